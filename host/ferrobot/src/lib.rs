//! # ferrobot
//!
//! A light, hardware-independent robotics API in the manner of PyRobot, without ROS: arms,
//! grippers, pan-tilt cameras and mobile bases, driven through the Ferrobot firmware core —
//! simulated in-process (the default, deterministic, faster than real time), in QEMU, or on a
//! real controller board, with the same program.
//!
//! ```no_run
//! use ferrobot::Robot;
//! let bot = Robot::new("locobot")?;                     // in-process simulator by default
//! bot.arm()?.set_joint_positions(&[0.0; 5])?;
//! bot.base()?.go_to_absolute([1.0, 1.0, 0.0])?;
//! # Ok::<(), ferrobot::Error>(())
//! ```
//!
//! Units are SI (m, rad, s, N·m); frames are right-handed; quaternions are `[x, y, z, w]`.
#![warn(missing_docs)]

pub mod arm;
pub mod arm_plan;
pub mod backend;
pub mod base;
pub mod camera;
pub mod error;
mod frames;
pub mod grasp;
pub mod gripper;
pub mod hand_eye;
pub mod head;
pub mod motion;
pub mod navigate;
pub mod planning;
pub mod push;
pub mod robot;
mod sense;
pub mod slam;
pub mod stance;

pub use ferrobot_control::odometry_calibration;
pub use ferrobot_description as config;
/// A described robot made whole: its checks against the wire, the firmware and its chain, and
/// what derives from it (firmware profile, joint table, arm chain).
pub use ferrobot_profile as profile;
pub use ferrobot_geometry::validate;
pub use ferrobot_kinematics as kinematics;
pub use ferrobot_nav as obstacles;
/// Navigation: maps on disk, the global planner on occupancy grids, obstacles.
pub use ferrobot_nav as nav;

/// Base control and navigation, as one module of the API: references, LQR and ILQR
/// (`ferrobot-control`), and the navigation field and dynamic window (`ferrobot-nav`).
pub mod base_control {
    pub use ferrobot_control::trajectory::*;
    pub use ferrobot_nav::{Circle, Dwa, NavField, Obstacles, OccupancyGrid};
}

pub use arm::{MoveOptions, Orientation, Pose};
pub use backend::{Backend, LinkEvent};
pub use base::GoalOptions;
pub use camera::{Camera, CameraDevice, Frame};
pub use config::RobotConfig;
pub use error::{Error, Result};
pub use ferrobot_perception as perception;
pub use ferrobot_protocol::GripperState;
pub use ferrobot_sim::scene;
pub use hand_eye::{HandEyeOptions, HandEyeReport};
pub use motion::Motion;
pub use push::{PushOptions, Pushed};
pub use robot::{Robot, RobotBuilder};
pub use slam::Source;

#[cfg(test)]
mod tests {
    /// The geometry layer's bounds are the wire protocol's, one fact in two crates that must
    /// not drift apart (the geometry crate is below the protocol's users and does not depend on
    /// it).
    #[test]
    fn the_geometry_layer_bounds_are_the_protocols() {
        use ferrobot_protocol::ranges;
        assert_eq!(
            crate::validate::BASE_SPEED_MAX,
            ranges::BASE_SPEED_MAX as f64
        );
        assert_eq!(crate::validate::BASE_TURN_MAX, ranges::BASE_TURN_MAX as f64);
        assert!(crate::validate::MAX_ANGLE <= ranges::JOINT_POSITION_MAX as f64);
    }
}
