//! Recording a robot: its streams into [MCAP](https://mcap.dev) files with ROS 2 message
//! schemas and CDR payloads, which Foxglove, Lichtblick, rosbag2 and rosbags open without
//! Ferrobot.
//!
//! - [`Recorder`]: start it on a [`ferrobot::Robot`], let the robot work, finish it. Every
//!   topic it writes is in [`topics`]: joint states, odometry, every link's transform, the
//!   gripper's state, the commands sent, faults and emergency stops, camera colour, depth and
//!   intrinsics, SLAM's pose and the robot's URDF.
//! - [`bag::Bag`]: the writer itself, fed items, for any `Write + Seek`.
//! - [`replay`]: a recording fed back as commands to a robot, or as sensor input (SLAM
//!   offline); [`reader`] and [`decode`] read it.
//! - [`lerobot`]: recordings exported as a LeRobot dataset (v3.0), one episode each.
//! - [`cdr`] and [`ros2`]: the messages' encoding and definitions ([`ferrobot_ros2`]).

pub mod bag;
pub mod error;
pub mod lerobot;
pub mod reader;
pub mod recorder;
pub mod replay;

pub use error::RecordError;
pub use ferrobot_ros2 as ros2;
pub use ferrobot_ros2::{cdr, decode, events, topics};
pub use recorder::{RecordOptions, RecordStats, Recorder};
