//! ROS 2 on the wire, without ROS: what a ROS 2 tool reads from Ferrobot and writes to it.
//!
//! - [`cdr`]: the encoding of ROS 2 messages (XCDR1, little-endian).
//! - [`schemas`]: the message definitions Ferrobot speaks (ROS 2 Jazzy's, comments left out),
//!   as `.msg` text and as MCAP `ros2msg` schemas.
//! - [`encode`]: those messages written from the robot's values; [`decode`] reads them back.
//! - [`topics`]: the topics Ferrobot speaks, each with its name and type.
//! - [`robot`]: a robot's telemetry, camera frames and events as messages on those topics
//!   ([`events`] for the events).
//! - [`type_hash`]: each definition's RIHS01 type hash, as `rosidl` computes it.
//! - [`view`]: what a viewer draws besides the robot's streams: planned paths, maps, the
//!   simulated world's bodies.
//! - [`rmw_zenoh`]: the names rmw_zenoh gives topics, services and entities on zenoh (key
//!   expressions, liveliness tokens, QoS strings, GIDs) and the attachment on every sample.
//!
//! Sans-IO: bytes and strings in and out. The recorder writes MCAP with it; the bridge puts it
//! on zenoh. It sits on [`ferrobot`]'s types (telemetry, frames, events) and on nothing of its
//! backends.

pub mod cdr;
pub mod decode;
pub mod encode;
pub mod events;
pub mod rmw_zenoh;
pub mod robot;
pub mod schemas;
pub mod topics;
pub mod type_hash;
pub mod view;
