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

#[cfg(not(any(feature = "sim", feature = "serial")))]
compile_error!("ferrobot needs a backend: enable `sim` (the default) or `serial`");

pub mod arm;
mod arm_kinematics;
mod arm_parts;
pub mod arm_plan;
mod arm_plan_event;
mod arm_scene;
pub mod arm_teach;
pub mod backend;
pub mod base;
mod base_goals;
mod base_navigation;
mod base_state;
mod builder;
pub mod camera;
mod components;
mod connect;
pub mod error;
pub mod events;
mod frame;
pub mod frames;
mod goals;
pub mod gripper;
pub mod head;
mod hub;
mod joints_goal;
pub mod motion;
pub mod navigate;
pub mod planning;
pub mod robot;
mod sense;
mod sensing;
#[cfg(feature = "sim")]
pub mod shared_world;
#[cfg(feature = "sim")]
mod simulated;
pub mod slam;
mod slam_runner;
pub mod subscription;
#[cfg(feature = "sim")]
pub mod world_options;
/// Where to stand at a table (pure geometry, in `ferrobot-nav`).
pub use ferrobot_nav::stance;

pub use ferrobot_control::odometry_calibration;
pub use ferrobot_description as config;
pub use ferrobot_geometry::validate;
pub use ferrobot_kinematics as kinematics;
/// Navigation: maps on disk, the global planner on occupancy grids, obstacles.
pub use ferrobot_nav as nav;
/// A described robot made whole: its checks against the wire, the firmware and its chain, and
/// what derives from it (firmware profile, joint table, arm chain).
pub use ferrobot_profile as profile;

/// Base control and navigation, as one module of the API: references, LQR and ILQR
/// (`ferrobot-control`), and the navigation field and dynamic window (`ferrobot-nav`).
pub mod base_control {
    pub use ferrobot_control::trajectory::*;
    pub use ferrobot_nav::{Circle, Dwa, NavField, Obstacles, OccupancyGrid};
}

pub use arm::{MoveOptions, Orientation, Pose};
pub use backend::{Backend, LinkEvent};
pub use base::GoalOptions;
pub use builder::RobotBuilder;
pub use camera::{Camera, CameraDevice, Frame};
pub use config::RobotConfig;
pub use error::{Error, Result};
pub use ferrobot_perception as perception;
/// The firmware's reports as the API hands them on: faults ([`Robot::take_faults`]), their
/// kinds and flags, the gripper's state, telemetry ([`Robot::telemetry`]) and diagnostics.
pub use ferrobot_protocol::{fault_flags, Diagnostics, Fault, FaultKind, GripperState, Telemetry};
#[cfg(feature = "sim")]
pub use ferrobot_sim::scene;
pub use motion::Motion;
pub use robot::Robot;
#[cfg(feature = "sim")]
pub use shared_world::SharedWorld;
pub use slam::Source;
pub use subscription::{Bell, Subscription};
#[cfg(feature = "sim")]
pub use world_options::{mount_error_pose, MAX_CAMERA_MOUNT_ERROR};

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
