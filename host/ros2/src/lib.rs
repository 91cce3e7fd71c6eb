//! ROS 2 on the wire, without ROS: what a ROS 2 tool reads from Ferrobot and writes to it.
//!
//! - [`cdr`]: the encoding of ROS 2 messages (XCDR1, little-endian).
//! - [`schemas`]: the message definitions Ferrobot speaks (ROS 2 Jazzy's, comments left out),
//!   as `.msg` text and as MCAP `ros2msg` schemas.
//! - [`encode`]: those messages written from the robot's values.
//! - [`type_hash`]: each definition's RIHS01 type hash, as `rosidl` computes it.
//! - [`rmw_zenoh`]: the names rmw_zenoh gives topics, services and entities on zenoh (key
//!   expressions, liveliness tokens, QoS strings, GIDs) and the attachment on every sample.
//!
//! Sans-IO: bytes and strings in and out. The recorder writes MCAP with it; the bridge puts it
//! on zenoh.

pub mod cdr;
pub mod encode;
pub mod rmw_zenoh;
pub mod schemas;
pub mod type_hash;
