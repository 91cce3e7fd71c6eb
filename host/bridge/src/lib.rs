//! A Ferrobot robot on [zenoh](https://zenoh.io), the network ROS 2 itself runs on with
//! rmw_zenoh (its Tier-1 middleware since Jazzy).
//!
//! - [`Server`]: a robot served as a ROS 2 node sees one: its joint states, transforms,
//!   odometry, camera and log on their ROS 2 topics, in CDR with ROS 2's type names and RIHS01
//!   hashes, announced by rmw_zenoh's liveliness tokens; `/cmd_vel` drives its base,
//!   `/goal_pose` and `/arm/joint_trajectory` set goals ([`inputs`]). Every
//!   ROS 2 tool on rmw_zenoh (`ros2 topic`, rviz2, rosbag2) is a peer, and nothing of ROS is
//!   installed here.
//! - [`remote`]: the remote backend: a served robot driven from another process or machine
//!   through the same API ([`remote::connect`]), with the server's watchdog on its clients.
//! - [`access`]: the zenoh session's configuration from where it listens and connects and with
//!   which credentials; a robot served beyond loopback needs them.
//!
//! The names and bytes come from [`ferrobot_ros2`] (sans-IO); this crate puts them on zenoh.

pub mod access;
pub mod error;
pub mod inputs;
pub mod node;
pub mod remote;
pub mod serve;

pub use access::{Access, Credentials};
pub use error::BridgeError;
pub use node::{RosNode, RosPublisher};
pub use serve::{Clock, ServeOptions, ServeStats, Server};
/// The zenoh this crate is built on, for programs that use its sessions too.
pub use zenoh;
