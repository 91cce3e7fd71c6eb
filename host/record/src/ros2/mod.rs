//! ROS 2 messages: their definitions ([`schemas`]) and their CDR encoding from the robot's
//! values ([`encode`]).

pub mod encode;
pub mod schemas;
