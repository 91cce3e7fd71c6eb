//! A live view of a robot in [Foxglove](https://foxglove.dev) or
//! [Lichtblick](https://github.com/Lichtblick-Suite/lichtblick), through their "Foxglove
//! WebSocket" connection (`ws://HOST:PORT`): the robot's URDF, transforms, joint states,
//! odometry, camera and log, as the ROS 2 messages the recorder writes and the zenoh bridge
//! publishes ([`ferrobot_ros2::robot`]), so the viewers' ROS 2 panels (3D with the URDF, image,
//! plot) show them with no Ferrobot code.
//!
//! Why Foxglove's protocol rather than rerun's SDK: the messages are already ROS 2's, CDR with
//! `ros2msg` schemas, which Foxglove and Lichtblick decode as they are (a recording opens the
//! same way); the server is a small WebSocket shell over them, where rerun would need each
//! message re-expressed in its own archetypes and its SDK (several hundred crates) built in CI.
//!
//! - [`protocol`]: the protocol's messages, sans-IO.
//! - [`hub`]: channels, latched messages and clients' subscriptions, sans-IO.
//! - [`ViewServer`]: the shell: a listener, a thread per viewer, the robot's feeds.

pub mod hub;
pub mod protocol;
pub mod server;

pub use server::{ViewError, ViewOptions, ViewServer};
