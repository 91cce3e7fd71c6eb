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

use heapless::{String, Vec};
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use crate::MAX_JOINTS;

/// A short name (joint, board, robot), at most 16 bytes of UTF-8.
pub type Name = String<16>;

/// A bit mask over joint indices: bit `i` selects joint `i` of the joint table.
pub type JointMask = u16;

/// The joint mask that selects every joint.
pub const ALL_JOINTS: JointMask = u16::MAX;

/// What a joint is, as far as the firmware cares.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum JointKind {
    /// An arm joint, revolute, angle in rad.
    Arm,
    /// A pan or tilt joint of a camera head, revolute, angle in rad.
    Head,
    /// The gripper motor, driven by the firmware's gripper state machine.
    Gripper,
}

/// The Dynamixel model that drives a joint. Decides units and which goal registers exist.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ServoModel {
    /// XM430-W350: current sensing and current control.
    Xm430W350,
    /// XL430-W250: no current control; address 126 reports load in 0.1 % of stall torque.
    Xl430W250,
}

/// Control mode of a joint.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum JointMode {
    /// Torque off; the joint is limp.
    Off,
    /// The servo's internal position PID tracks setpoints the firmware interpolates every tick.
    Position,
    /// The servo tracks a joint velocity (rad/s).
    Velocity,
    /// The firmware runs the joint PID with effort feed-forward and commands motor current.
    Current,
    /// Raw motor voltage as a fraction of the supply, in [−1, 1].
    Pwm,
}

/// Joint limits the firmware enforces whatever the host sends.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lowest joint position, rad.
    pub min: f32,
    /// Highest joint position, rad.
    pub max: f32,
    /// Largest joint speed, rad/s.
    pub velocity: f32,
    /// Largest joint effort, N·m.
    pub effort: f32,
}

/// Gains of the firmware's joint PID (current mode).
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq)]
pub struct PidGains {
    /// Proportional gain, N·m/rad.
    pub kp: f32,
    /// Integral gain, N·m/(rad·s).
    pub ki: f32,
    /// Derivative gain, N·m·s/rad.
    pub kd: f32,
    /// Bound on the integral term's contribution (anti-windup), N·m.
    pub i_limit: f32,
}

/// The servo's own control-table gains and motion profile, written at configuration.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServoGains {
    /// Position P gain (control table 84).
    pub pos_p: u16,
    /// Position I gain (control table 82).
    pub pos_i: u16,
    /// Position D gain (control table 80).
    pub pos_d: u16,
    /// Velocity P gain (control table 78).
    pub vel_p: u16,
    /// Velocity I gain (control table 76).
    pub vel_i: u16,
    /// Profile velocity (control table 112), 0.229 rpm units; 0 means none.
    pub profile_velocity: u32,
    /// Profile acceleration (control table 108), 214.577 rev/min² units; 0 means none.
    pub profile_acceleration: u32,
}

/// One row of the joint table: how a joint maps onto servos, and its limits and gains.
///
/// Servo angle (rad, 0 at tick 2048) = `sign · joint + offset`; a twin servo, when present,
/// is mirrored: its angle is the negated servo angle.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, PartialEq)]
pub struct JointConfig {
    /// Joint name as in the robot description.
    pub name: Name,
    /// What the joint is.
    pub kind: JointKind,
    /// Servo model.
    pub model: ServoModel,
    /// Dynamixel ID of the servo.
    pub servo_id: u8,
    /// Dynamixel ID of a mirrored twin servo sharing the load, if any.
    pub twin_id: Option<u8>,
    /// +1 or −1: direction of the servo relative to the joint.
    pub sign: i8,
    /// Servo angle at joint zero, rad.
    pub offset: f32,
    /// Limits enforced in the firmware.
    pub limits: JointLimits,
    /// Firmware joint PID (current mode).
    pub pid: PidGains,
    /// Position mode: gain (1/s) of the firmware's integrator that shifts the servo's goal
    /// until the measured position meets the reference (removes the sag a P-only servo loop
    /// leaves under gravity); it runs only while the joint holds a settled reference, and its
    /// correction is bounded to ±0.2 rad. 0 disables it.
    pub position_ki: f32,
    /// Servo-internal gains and profile.
    pub servo: ServoGains,
}

/// Which mobile base the firmware drives.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum BaseKind {
    /// No base.
    None,
    /// Yujin Kobuki (LoCoBot).
    Kobuki,
    /// iRobot Create 2 (LoCoBot-Lite).
    Create2,
}

/// Gripper commands.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum GripperCommand {
    /// Open fully (position mode, goal 2800 ticks on the LoCoBot).
    Open,
    /// Close until fully closed or an object is held.
    Close,
}

/// Gripper state as PyRobot reports it (its numeric codes in brackets), plus `Opening`.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum GripperState {
    /// Unknown, e.g. before the first command (−1).
    Unknown,
    /// Open (0).
    Open,
    /// Closing (1).
    Closing,
    /// Closed on an object (2).
    Holding,
    /// Fully closed, nothing held (3).
    Closed,
    /// Moving to the open position.
    Opening,
    /// The robot has no gripper.
    Absent,
}

/// One interpolation knot of a streamed joint trajectory.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq)]
pub struct JointPoint {
    /// Position, rad.
    pub position: f32,
    /// Velocity, rad/s.
    pub velocity: f32,
    /// Effort feed-forward, N·m (used in current mode).
    pub effort: f32,
}

impl JointPoint {
    /// A knot at rest at `position` (rad): zero velocity and effort.
    pub const fn at_rest(position: f32) -> Self {
        JointPoint {
            position,
            velocity: 0.0,
            effort: 0.0,
        }
    }
}

/// Messages from the host to the firmware.
///
/// Not `#[non_exhaustive]`: the firmware matches it exhaustively, so a message added here
/// without a handler there fails to compile.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, PartialEq)]
pub enum HostMsg {
    /// Start of a session: the host's protocol version. Answered by [`DeviceMsg::Hello`].
    Hello {
        /// The host's [`crate::PROTOCOL_VERSION`].
        protocol_version: u16,
        /// The host's [`crate::SCHEMA_HASH`].
        schema_hash: u32,
    },
    /// Ask for one row of the joint table. Answered by [`DeviceMsg::Joint`].
    GetJoint {
        /// Joint index.
        index: u8,
    },
    /// Replace or append (index = joint count) one row of the joint table. Only while every
    /// joint is off; the servos are reconfigured.
    ConfigureJoint {
        /// Joint index.
        index: u8,
        /// The new row.
        config: JointConfig,
    },
    /// Set the firmware PID gains of one joint, within [`crate::ranges::gains_ok`] and within
    /// what its servos can use ([`crate::ranges::gains_beyond_servo`]);
    /// [`RejectReason::InvalidConfig`] otherwise.
    SetPid {
        /// Joint index.
        joint: u8,
        /// Gains.
        gains: PidGains,
    },
    /// Set the limits of one joint, within [`crate::ranges::limits_ok`] and within the limits
    /// its row was configured with (at start or by [`HostMsg::ConfigureJoint`]): limits only
    /// narrow at run time ([`RejectReason::OutOfLimits`] otherwise), the effort limit to no
    /// less than [`crate::ranges::EFFORT_NARROW_MIN_SHARE`] of its configured one, and only
    /// around where the joint is: limits it is measured outside of are refused with
    /// [`RejectReason::OutOfLimits`] (they could not hold at once).
    SetLimits {
        /// Joint index.
        joint: u8,
        /// Limits.
        limits: JointLimits,
    },
    /// Switch the selected joints to a control mode. Clears their setpoint queues and holds
    /// them where they are.
    SetMode {
        /// Selected joints.
        joints: JointMask,
        /// New mode.
        mode: JointMode,
    },
    /// Queue one trajectory knot for the selected joints (position and current mode). The
    /// knot is reached `duration_us` after the previous queued knot, or after now when the
    /// queue is empty; the firmware interpolates with cubic Hermite splines between knots.
    /// Knots are checked by [`crate::ranges::point_error`].
    Waypoint {
        /// Selected joints; `points` holds one entry per set bit, lowest bit first.
        joints: JointMask,
        /// Time from the previous knot, µs.
        duration_us: u32,
        /// Knots, one per selected joint.
        points: Vec<JointPoint, MAX_JOINTS>,
    },
    /// Drop the queued knots of the selected joints and hold their current references.
    ClearQueue {
        /// Selected joints.
        joints: JointMask,
    },
    /// Direct command of the selected joints: velocity (rad/s, at most
    /// [`crate::ranges::JOINT_SPEED_MAX`]) in velocity mode, effort (N·m, at most
    /// [`crate::ranges::JOINT_EFFORT_MAX`]; PID bypassed until the next waypoint) in current
    /// mode, PWM fraction in [−1, 1] in PWM mode. The firmware still keeps every joint within
    /// its limits, braking ahead of a position limit and at the velocity limit.
    JointCommand {
        /// Selected joints; `values` holds one entry per set bit, lowest bit first.
        joints: JointMask,
        /// Values.
        values: Vec<f32, MAX_JOINTS>,
    },
    /// Base velocity in the base frame: forward `v` (m/s, at most
    /// [`crate::ranges::BASE_SPEED_MAX`]) and yaw rate `w` (rad/s, at most
    /// [`crate::ranges::BASE_TURN_MAX`]), held for `duration_ms` and then brought to zero; the
    /// firmware scales it to the base's top wheel speed.
    BaseVelocity {
        /// Forward speed, m/s.
        v: f32,
        /// Yaw rate, rad/s.
        w: f32,
        /// How long the command holds, ms.
        duration_ms: u16,
    },
    /// Reset the odometry pose to zero.
    ResetOdometry,
    /// Gripper command.
    Gripper(GripperCommand),
    /// Host watchdog period, ms, within `1..=`[`crate::ranges::WATCHDOG_MAX_MS`]: the watchdog
    /// cannot be switched off or set longer. When no valid frame arrives within it the base
    /// stops and the arm holds. It runs from the first accepted Hello on, in every session
    /// state.
    SetWatchdog {
        /// Period, ms.
        period_ms: u16,
    },
    /// Keeps the watchdog fed when the host has nothing else to say.
    Heartbeat,
    /// Emergency stop: base stopped, arm held, motion commands rejected until [`HostMsg::Resume`].
    /// Accepted in every session state (before a Hello, after a refused one) and always
    /// acknowledged. Joints in current or PWM mode are switched to position mode to be held
    /// (a torque would let a load carry them on); after `Resume` they stay there until the
    /// host sets their mode again.
    EmergencyStop,
    /// Leave the emergency stop.
    Resume,
    /// Telemetry period, ms; 0 stops telemetry.
    SetTelemetry {
        /// Period, ms.
        period_ms: u16,
    },
    /// Servo-loop period, µs, within [`crate::ranges::LOOP_PERIOD_MIN_US`]
    /// ..= [`crate::ranges::LOOP_PERIOD_MAX_US`].
    SetLoopPeriod {
        /// Period, µs.
        period_us: u32,
    },
    /// Reboot a joint's servo(s) to clear a hardware error, then reconfigure them. A rebooting
    /// servo is limp, so only a joint that is off or whose servo reports a hardware error may
    /// be rebooted (else [`RejectReason::Busy`]).
    RebootJoint {
        /// Joint index.
        joint: u8,
    },
    /// Ask for the link and bus counters. Answered by [`DeviceMsg::Diagnostics`].
    GetDiagnostics,
    /// Calibrated odometry geometry (from an odometry calibration against external
    /// measurements): the effective left and right wheel radii and wheel separation, m, each
    /// within 10 % of the base's nominal value. Only the odometry uses it; velocity commands
    /// are converted with the base's nominal geometry, as its own controller does.
    SetBaseGeometry {
        /// Effective left wheel radius, m.
        left_radius: f32,
        /// Effective right wheel radius, m.
        right_radius: f32,
        /// Effective wheel separation, m.
        track: f32,
    },
}

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

/// Description of the firmware, sent in answer to [`HostMsg::Hello`].
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

/// Measured state of one joint.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Default)]
pub struct JointState {
    /// Position, rad.
    pub position: f32,
    /// Velocity, rad/s.
    pub velocity: f32,
    /// Effort, N·m (twin servos summed).
    pub effort: f32,
}

/// Wheel-odometry estimate of the base in the odometry frame.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Default)]
pub struct Odometry {
    /// Position x, m.
    pub x: f32,
    /// Position y, m.
    pub y: f32,
    /// Heading, rad, in (−π, π].
    pub theta: f32,
    /// Forward speed, m/s.
    pub v: f32,
    /// Yaw rate, rad/s.
    pub w: f32,
}

/// Raw wheel data.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Default)]
pub struct WheelData {
    /// Left wheel angle accumulated since start, rad.
    pub left: f32,
    /// Right wheel angle accumulated since start, rad.
    pub right: f32,
    /// Left wheel speed, rad/s.
    pub left_rate: f32,
    /// Right wheel speed, rad/s.
    pub right_rate: f32,
}

/// Base safety-sensor bits of [`Telemetry::base_flags`].
pub mod base_flags {
    /// Left bumper pressed.
    pub const BUMPER_LEFT: u16 = 1 << 0;
    /// Centre bumper pressed.
    pub const BUMPER_CENTER: u16 = 1 << 1;
    /// Right bumper pressed.
    pub const BUMPER_RIGHT: u16 = 1 << 2;
    /// Left cliff sensor.
    pub const CLIFF_LEFT: u16 = 1 << 3;
    /// Centre (front) cliff sensor.
    pub const CLIFF_CENTER: u16 = 1 << 4;
    /// Right cliff sensor.
    pub const CLIFF_RIGHT: u16 = 1 << 5;
    /// Left wheel dropped.
    pub const WHEEL_DROP_LEFT: u16 = 1 << 6;
    /// Right wheel dropped.
    pub const WHEEL_DROP_RIGHT: u16 = 1 << 7;
    /// Any bumper.
    pub const ANY_BUMPER: u16 = BUMPER_LEFT | BUMPER_CENTER | BUMPER_RIGHT;
    /// Any cliff sensor.
    pub const ANY_CLIFF: u16 = CLIFF_LEFT | CLIFF_CENTER | CLIFF_RIGHT;
    /// Any wheel drop.
    pub const ANY_WHEEL_DROP: u16 = WHEEL_DROP_LEFT | WHEEL_DROP_RIGHT;
}

/// Fault bits of [`Telemetry::faults`]; each stays set while the condition lasts.
pub mod fault_flags {
    /// Emergency stop active.
    pub const ESTOP: u16 = 1 << 0;
    /// The host watchdog has expired.
    pub const WATCHDOG: u16 = 1 << 1;
    /// At least one servo does not answer.
    pub const SERVO_LOST: u16 = 1 << 2;
    /// At least one servo reports a hardware error.
    pub const SERVO_HARDWARE: u16 = 1 << 3;
    /// The base sends no feedback.
    pub const BASE_LOST: u16 = 1 << 4;
    /// A base safety sensor is active.
    pub const BASE_SAFETY: u16 = 1 << 5;
    /// The servo loop overran its period since the last telemetry.
    pub const OVERRUN: u16 = 1 << 6;
    /// Servos are still being configured.
    pub const CONFIGURING: u16 = 1 << 7;
}

/// Servo-loop timing.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LoopStats {
    /// Servo-loop ticks since start.
    pub ticks: u32,
    /// Longest tick (sync read sent until goals written), µs.
    pub worst_tick_us: u32,
    /// Ticks that did not finish within the loop period.
    pub overruns: u32,
}

/// One telemetry frame, sent every telemetry period.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, PartialEq)]
pub struct Telemetry {
    /// Firmware clock, µs since start.
    pub time_us: u64,
    /// Joint states in joint-table order.
    pub joints: Vec<JointState, MAX_JOINTS>,
    /// Setpoints still queued, summed over joints.
    pub queued: u8,
    /// Gripper state.
    pub gripper: GripperState,
    /// Odometry.
    pub odometry: Odometry,
    /// Wheels.
    pub wheels: WheelData,
    /// [`base_flags`] bits.
    pub base_flags: u16,
    /// [`fault_flags`] bits.
    pub faults: u16,
    /// Servo-loop timing.
    pub loop_stats: LoopStats,
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
    /// A bumper was pressed (`code`: [`base_flags`] bits).
    Bumper,
    /// A cliff sensor fired (`code`: [`base_flags`] bits).
    Cliff,
    /// A wheel dropped (`code`: [`base_flags`] bits).
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
    /// Answer to [`HostMsg::Hello`].
    Hello(DeviceInfo),
    /// Answer to [`HostMsg::GetJoint`].
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
    /// Answer to [`HostMsg::GetDiagnostics`].
    Diagnostics(Diagnostics),
    /// Free-form log text.
    Log(String<64>),
}
