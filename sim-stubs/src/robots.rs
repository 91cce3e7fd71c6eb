//! The simulated robots: which servos sit where, the arm's mass properties, and the base.
//! These describe the hardware as built (the firmware learns the same facts from its profile).

use ferrobot_protocol::dxl::units;
use ferrobot_protocol::ServoModel::{Xl430W250, Xm430W350};

use crate::arm::{locobot_arm, ArmJoint};
use crate::chain::ServoMount;

/// Which base a robot stands on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseModel {
    /// No base.
    None,
    /// Kobuki.
    Kobuki,
    /// Create 2.
    Create2,
}

/// A simulated robot.
#[derive(Debug, Clone)]
pub struct SimRobot {
    /// Name, as the firmware profiles use it.
    pub name: String,
    /// Servos.
    pub servos: Vec<ServoMount>,
    /// Arm chain for gravity.
    pub arm: Vec<ArmJoint>,
    /// Base.
    pub base: BaseModel,
    /// Servo-bus bit rate, bit/s.
    pub bus_baud: u32,
}

/// Names of the robots the simulator knows.
pub const ROBOTS: [&str; 2] = ["locobot", "locobot_lite"];

fn tick(t: i32) -> f64 {
    units::tick_to_rad(t) as f64
}

/// LoCoBot's servo chain: IDs 1-9 as in PyRobot's `dynamixels.yaml`; joint 2 drives 2 and its
/// mirrored twin 3; joints 3-5 sign-inverted; gripper between mechanical stops at 1650 and 3050
/// ticks, starting open at 2800; pan and tilt XL430s.
pub fn locobot_servos() -> Vec<ServoMount> {
    let arm = |id, model, j, gain: f64, share| ServoMount {
        id,
        model,
        arm_joint: Some(j),
        gain,
        share,
        stops: Some((-2.0, 2.0)),
        initial: 0.0,
    };
    vec![
        arm(1, Xm430W350, 0, 1.0, 1.0),
        arm(2, Xm430W350, 1, 1.0, 0.5),
        arm(3, Xm430W350, 1, -1.0, 0.5),
        arm(4, Xm430W350, 2, -1.0, 1.0),
        arm(5, Xm430W350, 3, -1.0, 1.0),
        arm(6, Xl430W250, 4, -1.0, 1.0),
        ServoMount {
            id: 7,
            model: Xl430W250,
            arm_joint: None,
            gain: 1.0,
            share: 1.0,
            stops: Some((tick(1650), tick(3050))),
            initial: tick(2800),
        },
        ServoMount {
            id: 8,
            model: Xl430W250,
            arm_joint: None,
            gain: 1.0,
            share: 1.0,
            stops: Some((-2.8, 2.7)),
            initial: 0.0,
        },
        ServoMount {
            id: 9,
            model: Xl430W250,
            arm_joint: None,
            gain: 1.0,
            share: 1.0,
            stops: Some((-1.5, 1.85)),
            initial: 0.0,
        },
    ]
}

/// A robot by name.
pub fn by_name(name: &str) -> Option<SimRobot> {
    let base = match name {
        "locobot" => BaseModel::Kobuki,
        "locobot_lite" => BaseModel::Create2,
        _ => return None,
    };
    Some(SimRobot {
        name: name.to_string(),
        servos: locobot_servos(),
        arm: locobot_arm(),
        base,
        bus_baud: 4_000_000,
    })
}
