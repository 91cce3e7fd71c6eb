//! The joint table: each `[[joint]]` as written (its servo, limit overrides, gains), and each
//! as resolved ([`Joint`]): its limits the URDF's, overridden per field, rad or m (rad/s,
//! N·m), in the `f32` of the firmware's joint table, so that what the host checks and what
//! the firmware enforces agree to the bit.

use serde::Deserialize;

/// Servo of a joint.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServoSection {
    /// Dynamixel ID.
    pub id: u8,
    /// `xm430-w350` or `xl430-w250`.
    pub model: String,
    /// +1 or −1.
    #[serde(default = "one")]
    pub sign: i8,
    /// Servo angle at joint zero, rad.
    #[serde(default)]
    pub offset: f64,
    /// Mirrored twin servo sharing the load.
    pub twin: Option<u8>,
}

fn one() -> i8 {
    1
}

/// Per-field overrides of the URDF's joint limits.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsOverride {
    /// Lower position limit, rad.
    pub min: Option<f64>,
    /// Upper position limit, rad.
    pub max: Option<f64>,
    /// Speed limit, rad/s.
    pub velocity: Option<f64>,
}

/// Joint PID of current mode.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PidSection {
    /// N·m/rad.
    pub kp: f64,
    /// N·m/(rad·s).
    pub ki: f64,
    /// N·m·s/rad.
    pub kd: f64,
    /// Integral bound, N·m.
    pub i_limit: f64,
}

/// Joint kind in the table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointRole {
    /// Arm joint.
    Arm,
    /// Pan or tilt.
    Head,
    /// Gripper motor.
    Gripper,
}

/// One `[[joint]]` of the firmware's joint table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSection {
    /// Joint name (a URDF joint, except for the gripper motor).
    pub name: String,
    /// Role.
    pub kind: JointRole,
    /// Servo.
    pub servo: ServoSection,
    /// Limit overrides.
    pub limits: Option<LimitsOverride>,
    /// Effort limit, N·m.
    pub effort_limit: f64,
    /// Current-mode PID; the model's default when absent.
    pub pid: Option<PidSection>,
    /// Position-mode goal-offset integrator gain, 1/s; the default when absent.
    pub position_ki: Option<f64>,
}

/// The servo models a joint may name (`xm430-w350`, `xl430-w250`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServoModel {
    /// ROBOTIS XM430-W350.
    Xm430W350,
    /// ROBOTIS XL430-W250.
    Xl430W250,
}

/// A joint's limits as the firmware's table holds them (`f32`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lower position limit, rad (m for a prismatic joint).
    pub min: f32,
    /// Upper position limit, rad (m).
    pub max: f32,
    /// Speed limit, rad/s (m/s).
    pub velocity: f32,
    /// Effort limit, N·m (N).
    pub effort: f32,
}

/// One entry of the joint table, resolved against the URDF.
#[derive(Debug, Clone)]
pub struct Joint {
    /// Joint name (a URDF joint, except for the gripper motor).
    pub name: String,
    /// Role.
    pub kind: JointRole,
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
    /// Limits (the URDF's, overridden per field), in the table's `f32`.
    pub limits: JointLimits,
    /// Lower and upper position limits as resolved, before the table's `f32`, rad or m: the
    /// limits of the arm's kinematic chain.
    pub bounds: (f64, f64),
    /// Current-mode PID; the servo model's default when absent.
    pub pid: Option<PidSection>,
    /// Position-mode goal-offset integrator gain, 1/s; the default when absent.
    pub position_ki: Option<f64>,
}
