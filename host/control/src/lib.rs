//! Base control on a unicycle model ([`trajectory`]: references under limits, time-varying
//! LQR, iterative LQR) and odometry calibration ([`odometry_calibration`]). The laws take
//! poses `[x, y, θ]` (m, m, rad) and controls `[v, ω]` (m/s, rad/s), never wire types.
#![warn(missing_docs)]

pub mod error;
pub mod odometry_calibration;
pub mod trajectory;

pub use error::{Error, Result};
pub use ferrobot_geometry::wrap;
