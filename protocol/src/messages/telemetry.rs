//! The telemetry frame the firmware sends every telemetry period: joint states, gripper
//! state, odometry in the odometry frame, wheel data, base and fault flags, loop timing.
//! Units SI, `f32`.

use heapless::Vec;
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use super::MAX_JOINTS;

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

impl GripperState {
    /// PyRobot's code of the state: -1 unknown, 0 open, 1 closing, 2 holding an object, 3
    /// fully closed; Ferrobot adds 4 opening (and -1 for a robot without a gripper).
    pub const fn pyrobot_code(self) -> i8 {
        match self {
            GripperState::Open => 0,
            GripperState::Closing => 1,
            GripperState::Holding => 2,
            GripperState::Closed => 3,
            GripperState::Opening => 4,
            GripperState::Unknown | GripperState::Absent => -1,
        }
    }
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
    /// Not a fault: the firmware trusts the arm's gravity model (the host sent it and the
    /// arm, held still, has borne it out).
    pub const ARM_MODEL: u16 = 1 << 8;
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
