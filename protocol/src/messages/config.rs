//! The joint table and the robot's configuration as the host sets it: what each joint is,
//! which servo drives it and how, its limits and gains; the base's kind. Angles in rad,
//! speeds in rad/s, efforts in N·m.

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use super::Name;

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
    /// Teach mode: the arm moves under a hand and stays where it is left. The servo's
    /// position loop holds the joint; the firmware takes what its measured effort gives
    /// beyond the trusted gravity model's load as a hand's torque, and moves the goal with it
    /// (within the joint's limits and speed limit). Refused
    /// ([`RejectReason::Unsupported`](crate::RejectReason::Unsupported)) for a joint outside
    /// a trusted gravity model ([`crate::HostMsg::ArmLink`]).
    Teach,
}

/// One link of an arm's gravity model as it crosses the wire (see [`crate::gravity::Link`]),
/// with the row of the joint table its joint is. Within [`crate::ranges::arm_link_error`].
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq)]
pub struct ArmLink {
    /// Joint-table row of the link's joint.
    pub joint: u8,
    /// Joint origin in the parent joint's frame, m.
    pub origin: [f32; 3],
    /// Fixed rotation of the joint's frame, roll-pitch-yaw (URDF convention), rad.
    pub rpy: [f32; 3],
    /// Joint axis in the joint's frame (unit vector).
    pub axis: [f32; 3],
    /// Mass carried by the joint up to the next one, kg.
    pub mass: f32,
    /// Centre of that mass in the joint's frame, m.
    pub com: [f32; 3],
}

impl ArmLink {
    /// The link as the gravity model takes it.
    pub const fn link(&self) -> crate::gravity::Link<f32> {
        crate::gravity::Link {
            origin: self.origin,
            rpy: self.rpy,
            axis: self.axis,
            mass: self.mass,
            com: self.com,
        }
    }
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
