//! The host ⇄ firmware message set.
//!
//! Units are SI throughout (m, rad, s, N·m, m/s, rad/s) and `f32` on the wire. Joint angles are
//! joint-space angles as the robot description defines them (sign and offset of the servo are
//! the firmware's business, from the joint table). The base frame is the odometry frame: x
//! forward at the last odometry reset, y left, z up, θ counter-clockwise.
//!
//! Every [`HostMsg`] is answered by [`DeviceMsg::Ack`] or [`DeviceMsg::Reject`] carrying the
//! sequence number of the frame it answers; [`HostMsg::Hello`], [`HostMsg::GetJoint`] and
//! [`HostMsg::GetDiagnostics`] are answered by their reply message instead.
//!
//! The types are split by what they describe: the joint table and robot configuration
//! (`config`), what the host sends (`host`), the telemetry frame (`telemetry`) and what
//! the firmware answers and reports (`device`); all are re-exported here.

use heapless::String;

// The bound of every joint list, for the message files.
use crate::MAX_JOINTS;

mod config;
mod device;
mod host;
mod telemetry;

pub use config::*;
pub use device::*;
pub use host::*;
pub use telemetry::*;

/// A short name (joint, board, robot), at most 16 bytes of UTF-8.
pub type Name = String<16>;

/// A bit mask over joint indices: bit `i` selects joint `i` of the joint table.
pub type JointMask = u16;

/// The joint mask that selects every joint.
pub const ALL_JOINTS: JointMask = u16::MAX;
