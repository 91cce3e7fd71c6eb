//! What the host sends: [`HostMsg`], with the trajectory knots and gripper commands it
//! carries. Units SI, `f32`.

use heapless::Vec;
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use super::config::{ArmLink, JointConfig, JointLimits, JointMode, PidGains};
use super::JointMask;
use super::MAX_JOINTS;

/// Gripper commands.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum GripperCommand {
    /// Open fully (position mode, goal 2800 ticks on the LoCoBot).
    Open,
    /// Close until fully closed or an object is held.
    Close,
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
    /// Start of a session: the host's protocol version. Answered by
    /// [`DeviceMsg::Hello`](crate::DeviceMsg::Hello).
    Hello {
        /// The host's [`crate::PROTOCOL_VERSION`].
        protocol_version: u16,
        /// The host's [`crate::SCHEMA_HASH`].
        schema_hash: u32,
    },
    /// Ask for one row of the joint table. Answered by
    /// [`DeviceMsg::Joint`](crate::DeviceMsg::Joint).
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
    /// [`RejectReason::InvalidConfig`](crate::RejectReason::InvalidConfig) otherwise.
    SetPid {
        /// Joint index.
        joint: u8,
        /// Gains.
        gains: PidGains,
    },
    /// Set the limits of one joint, within [`crate::ranges::limits_ok`] and within the limits
    /// its row was configured with (at start or by [`HostMsg::ConfigureJoint`]): limits only
    /// narrow at run time ([`RejectReason::OutOfLimits`](crate::RejectReason::OutOfLimits)
    /// otherwise), the effort limit to no less than
    /// [`crate::ranges::EFFORT_NARROW_MIN_SHARE`] of its configured one, and only around where
    /// the joint is: limits it is measured outside of are refused with
    /// [`RejectReason::OutOfLimits`](crate::RejectReason::OutOfLimits) (they could not hold at
    /// once).
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
    /// be rebooted (else [`RejectReason::Busy`](crate::RejectReason::Busy)).
    RebootJoint {
        /// Joint index.
        joint: u8,
    },
    /// Ask for the link and bus counters. Answered by
    /// [`DeviceMsg::Diagnostics`](crate::DeviceMsg::Diagnostics).
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
    /// Link `index` of the arm's gravity model of `count` links, base first (the host derives
    /// it from the robot's description). Links arrive in order, every link within
    /// [`crate::ranges::arm_link_error`] and naming a distinct arm row of the joint table;
    /// anything else is refused with
    /// [`RejectReason::InvalidConfig`](crate::RejectReason::InvalidConfig) (or `NotFinite`,
    /// `UnknownJoint`) and the links so far dropped. A whole model is a candidate: it replaces
    /// the trusted one only once the joints' measured efforts bear it out
    /// ([`crate::FaultKind::ModelConfirmed`]); a trusted model is given up only when they
    /// contradict it ([`crate::FaultKind::ModelRefuted`]) or the joint table changes. `count`
    /// 0 drops the candidate.
    ArmLink {
        /// The link's place in the chain.
        index: u8,
        /// Links in the chain, at most [`crate::gravity::MAX_LINKS`].
        count: u8,
        /// The link.
        link: ArmLink,
    },
}

impl HostMsg {
    /// The message's name, as its variant is spelled (`"Waypoint"`, `"EmergencyStop"`): for
    /// logs and recordings.
    pub const fn kind(&self) -> &'static str {
        match self {
            HostMsg::Hello { .. } => "Hello",
            HostMsg::GetJoint { .. } => "GetJoint",
            HostMsg::ConfigureJoint { .. } => "ConfigureJoint",
            HostMsg::SetPid { .. } => "SetPid",
            HostMsg::SetLimits { .. } => "SetLimits",
            HostMsg::SetMode { .. } => "SetMode",
            HostMsg::Waypoint { .. } => "Waypoint",
            HostMsg::ClearQueue { .. } => "ClearQueue",
            HostMsg::JointCommand { .. } => "JointCommand",
            HostMsg::BaseVelocity { .. } => "BaseVelocity",
            HostMsg::ResetOdometry => "ResetOdometry",
            HostMsg::Gripper(_) => "Gripper",
            HostMsg::SetWatchdog { .. } => "SetWatchdog",
            HostMsg::Heartbeat => "Heartbeat",
            HostMsg::EmergencyStop => "EmergencyStop",
            HostMsg::Resume => "Resume",
            HostMsg::SetTelemetry { .. } => "SetTelemetry",
            HostMsg::SetLoopPeriod { .. } => "SetLoopPeriod",
            HostMsg::RebootJoint { .. } => "RebootJoint",
            HostMsg::GetDiagnostics => "GetDiagnostics",
            HostMsg::SetBaseGeometry { .. } => "SetBaseGeometry",
            HostMsg::ArmLink { .. } => "ArmLink",
        }
    }
}
