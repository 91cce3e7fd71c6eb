//! Base control on a unicycle model ([`trajectory`]: references under limits, time-varying
//! LQR, iterative LQR; [`laws`]: the proportional law, LQR tracking and the finisher) and odometry calibration ([`odometry_calibration`]). The laws take
//! poses `[x, y, θ]` (m, m, rad) and controls `[v, ω]` (m/s, rad/s), never wire types.
#![warn(missing_docs)]

pub mod error;
pub mod laws;
pub mod odometry_calibration;
pub mod trajectory;

pub use error::{Error, Result};
pub use ferrobot_geometry::wrap;
