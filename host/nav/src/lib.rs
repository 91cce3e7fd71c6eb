//! Navigation for mobile bases in the odometry frame (m): obstacles and occupancy grids behind
//! one clearance query ([`obstacles`]), maps on disk in ROS map_server's format ([`map_file`]),
//! a global planner on the grid ([`global`]), the navigator that reaches a goal on a map with
//! live obstacles, re-planning and recovery ([`navigator`]), the navigation field and the
//! dynamic window approach ([`field`]), frontiers for exploration ([`frontier`]).
#![warn(missing_docs)]

pub mod depth_scan;
pub mod error;
pub mod field;
pub mod frontier;
pub mod global;
pub mod live;
pub mod map_file;
pub mod navigator;
pub mod obstacles;
pub mod stance;

pub use error::{Error, Result};
pub use field::{Dwa, NavField};
pub use frontier::{frontiers, Frontier, FrontierSettings};
pub use global::{GlobalPath, GlobalPlanner, GridAStar};
pub use live::LiveObstacles;
pub use map_file::{Cell, MapImage};
pub use navigator::{NavCommand, NavSettings, Navigator, Scan};
pub use obstacles::{
    grid_line, neighbours, Circle, Obstacles, OccupancyGrid, NEIGHBOURS_4, NEIGHBOURS_8,
};
