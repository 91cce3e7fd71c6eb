//! # ferrobot
//!
//! A light, hardware-independent robotics API in the manner of PyRobot, without ROS: arms,
//! grippers, pan-tilt cameras and mobile bases, driven through the Ferrobot firmware core —
//! simulated in-process (the default, deterministic, faster than real time), in QEMU, or on a
//! real controller board, with the same program.
//!
//! ```no_run
//! use ferrobot::Robot;
//! let mut bot = Robot::new("locobot")?;                 // in-process simulator by default
//! bot.arm()?.set_joint_positions(&[0.0; 5])?;
//! bot.base()?.go_to_absolute([1.0, 1.0, 0.0])?;
//! # Ok::<(), ferrobot::Error>(())
//! ```
//!
//! Units are SI (m, rad, s, N·m); frames are right-handed; quaternions are `[x, y, z, w]`.
#![warn(missing_docs)]

pub mod arm;
pub mod backend;
pub mod base;
pub mod base_control;
pub mod config;
pub mod error;
pub mod gripper;
pub mod kinematics;
pub mod motion;
pub mod obstacles;
pub mod odometry_calibration;
pub mod pan_tilt;
pub mod robot;
pub mod validate;

pub use arm::{MoveOptions, Orientation, Pose};
pub use backend::Backend;
pub use base::GoalOptions;
pub use config::RobotConfig;
pub use error::{Error, Result};
pub use ferrobot_protocol::GripperState;
pub use motion::Motion;
pub use robot::{Robot, RobotBuilder};
