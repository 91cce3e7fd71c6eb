//! Navigation for mobile bases in the odometry frame (m): obstacles and occupancy grids behind
//! one clearance query ([`obstacles`]), the navigation field and the dynamic window approach
//! ([`field`]).
#![warn(missing_docs)]

pub mod error;
pub mod field;
pub mod obstacles;

pub use error::{Error, Result};
pub use field::{Dwa, NavField};
pub use obstacles::{Circle, Obstacles, OccupancyGrid};
