//! The library half of the `ferrobot` command line: the base benchmark (PyRobot's Table 1 in
//! [`base_trials`], the circle plots' runs in [`circle_tracking`], the odometry calibration in
//! [`odometry_calibration`]) and the PNG canvas it draws on ([`plot`]). The binary
//! (`src/main.rs`, one module per subcommand in `src/cmd/`) parses arguments and prints; these
//! modules do the work so that tests can call them.
#![warn(missing_docs)]

/// PyRobot's base trials (in `ferrobot-skills`, so that the Python package runs them too).
pub use ferrobot_skills::base_trials;
pub mod circle_tracking;
pub mod odometry_calibration;
pub mod plot;
