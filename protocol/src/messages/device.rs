//! What the firmware sends besides telemetry: [`DeviceMsg`], the answers (the Hello's
//! [`DeviceInfo`], acknowledgements and rejections with their [`RejectReason`]), fault
//! reports and counters.

use heapless::{String, Vec};
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use super::config::{BaseKind, JointConfig, JointKind};
use super::telemetry::Telemetry;
use super::Name;
use super::MAX_JOINTS;

/// Why the firmware rejected a command.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum RejectReason {
    /// The host's protocol version or schema differs from the firmware's.
    VersionMismatch,
    /// A joint index beyond the joint table.
    UnknownJoint,
    /// The number of values does not match the number of selected joints.
    CountMismatch,
    /// A value is NaN or infinite.
    NotFinite,
    /// A target outside the joint's position limits.
    OutOfLimits,
    /// The setpoint queue has no room.
    QueueFull,
    /// An emergency stop is active.
    EmergencyStop,
    /// The command does not fit the joint's current mode.
    WrongMode,
    /// The hardware cannot do it (e.g. a mode a servo model lacks).
    Unsupported,
    /// The robot has no base.
    NoBase,
    /// The robot has no gripper.
    NoGripper,
    /// A joint is not off (joint-table changes need every joint off).
    Busy,
    /// A configuration value is invalid (sign not ±1, min > max, …).
    InvalidConfig,
    /// A base safety sensor (bumper, cliff, wheel drop) is active, or the base's feedback
    /// (which carries them) is lost.
    BaseSafety,
}

/// Description of the firmware, sent in answer to [`HostMsg::Hello`](crate::HostMsg::Hello).
#[derive(Serialize, Deserialize, Schema, Debug, Clone, PartialEq)]
pub struct DeviceInfo {
    /// The firmware's [`crate::PROTOCOL_VERSION`].
    pub protocol_version: u16,
    /// The firmware's [`crate::SCHEMA_HASH`].
    pub schema_hash: u32,
    /// Firmware version, major/minor/patch.
    pub firmware_version: [u8; 3],
    /// Board name (`sim`, `mps2-an386`, `opencr`, …).
    pub board: Name,
    /// Robot the joint table was built for.
    pub robot: Name,
    /// Kind of every joint, in joint-table order; its length is the joint count.
    pub joints: Vec<JointKind, MAX_JOINTS>,
    /// The base.
    pub base: BaseKind,
    /// Servo-loop period, µs.
    pub loop_period_us: u32,
    /// Whether the host's version and schema match; if not, every other command is rejected.
    pub accepted: bool,
    /// Whether the host watchdog had stopped the robot when this Hello arrived: the host had
    /// sent nothing for longer than the watchdog period (a link that was down), so the base
    /// was stopped and every joint held where it was. Any valid frame, this Hello too, ends
    /// that state; the joints go on holding until commanded. (Last, so that an older host
    /// still reads the fields before it and can report a schema mismatch.)
    pub watchdog_tripped: bool,
}

/// Kinds of fault reports.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FaultKind {
    /// A servo stopped answering; its joint is held and left out of the loop.
    ServoLost,
    /// A lost servo answers again.
    ServoRecovered,
    /// A servo reports hardware-error bits (`code`: Hardware Error Status, address 70).
    ServoHardware,
    /// A servo could not be configured.
    ServoConfig,
    /// The host watchdog expired: base stopped, arm held.
    Watchdog,
    /// Emergency stop engaged.
    EmergencyStop,
    /// A bumper was pressed (`code`: [`base_flags`](crate::base_flags) bits).
    Bumper,
    /// A cliff sensor fired (`code`: [`base_flags`](crate::base_flags) bits).
    Cliff,
    /// A wheel dropped (`code`: [`base_flags`](crate::base_flags) bits).
    WheelDrop,
    /// The base stopped sending feedback.
    BaseLost,
    /// The base answers again.
    BaseRecovered,
    /// A command was clamped to a joint limit.
    LimitClamped,
    /// The last gate before the servos found a goal that was not finite or outside the
    /// joint's limits; the joint holds where it is instead.
    UnsafeGoal,
    /// A joint in velocity, current or PWM mode left its speed or position limits (a weak
    /// servo loop, a load, a slow control loop): it was switched to position mode and holds
    /// where it comes to rest.
    LimitStop,
    /// A joint under control is more than [`crate::ranges::OUTSIDE_FAULT`] outside its
    /// position limits (`code`: how far, mrad): a load carried it there faster than its servos
    /// could brake (it fell while limp, or gravity outpulls its effort limit). The firmware
    /// brings it back; reported once, again only after it has come back inside.
    OutsideLimits,
    /// A gravity model the host sent is trusted (and replaces the one trusted before): every
    /// loaded joint of it, held still in position mode, was measured giving the effort the
    /// model gives it. Position mode then carries the modelled load, current mode adds it,
    /// and teach mode may be set; joints in teach mode go back to position mode.
    ModelConfirmed,
    /// The trusted gravity model is no longer trusted (`joint`: the one whose measured effort
    /// disagreed with it, held still in position mode; a payload, or a wrong model): it waits
    /// to be confirmed again. Joints in teach mode go back to position mode; the load
    /// correction takes over the load.
    ModelRefuted,
}

/// A fault report.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fault {
    /// What happened.
    pub kind: FaultKind,
    /// Joint index concerned, if any.
    pub joint: Option<u8>,
    /// Servo ID concerned, if any.
    pub servo_id: Option<u8>,
    /// Kind-specific code (hardware-error bits, sensor bits).
    pub code: u16,
    /// Firmware clock, µs.
    pub time_us: u64,
}

/// Link and bus counters.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Diagnostics {
    /// Host frames decoded and accepted.
    pub host_frames: u32,
    /// Host frames dropped: bad COBS, CRC, size or body.
    pub host_bad_frames: u32,
    /// Frames the firmware could not queue to the host (link congested).
    pub host_tx_dropped: u32,
    /// Dynamixel status packets received.
    pub servo_packets: u32,
    /// Dynamixel packets dropped for CRC, length or framing errors.
    pub servo_bad_packets: u32,
    /// Expected status packets that never came.
    pub servo_timeouts: u32,
    /// Status packets with the hardware-alert bit.
    pub servo_alerts: u32,
    /// Status packets that answered nothing awaited (late from an earlier transaction, or
    /// out of a sync read's order), dropped.
    pub servo_stale: u32,
    /// Base feedback packets received.
    pub base_packets: u32,
    /// Base packets dropped for checksum or framing errors.
    pub base_bad_packets: u32,
}

/// Messages from the firmware to the host.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum DeviceMsg {
    /// Answer to [`HostMsg::Hello`](crate::HostMsg::Hello).
    Hello(DeviceInfo),
    /// Answer to [`HostMsg::GetJoint`](crate::HostMsg::GetJoint).
    Joint {
        /// Joint index.
        index: u8,
        /// The row.
        config: JointConfig,
    },
    /// The command with this sequence number was accepted.
    Ack {
        /// Sequence number of the host frame.
        seq: u16,
    },
    /// The command with this sequence number was rejected.
    Reject {
        /// Sequence number of the host frame.
        seq: u16,
        /// Why.
        reason: RejectReason,
    },
    /// Periodic state.
    Telemetry(Telemetry),
    /// Something went wrong (or right again).
    Fault(Fault),
    /// Answer to [`HostMsg::GetDiagnostics`](crate::HostMsg::GetDiagnostics).
    Diagnostics(Diagnostics),
    /// Free-form log text.
    Log(String<64>),
}
