//! The simulated robots, derived from the robot descriptions (`ferrobot-description`): which
//! servos sit where and where their mechanical stops are, the arm's mass properties from the
//! URDF, the base and the servo bus. The firmware's built-in profiles are tested equal to the
//! same descriptions, so the simulator, the plant servers, the HIL harness and a board agree.

use std::collections::BTreeMap;

use ferrobot_description::{BaseModel as DescBase, RobotConfig};
use ferrobot_protocol::dxl::units;
use ferrobot_protocol::JointKind;

use crate::arm::ArmJoint;
use crate::body::{JointServo, RobotBody};
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
    /// Arm chain for gravity (empty: no gravity load).
    pub arm: Vec<ArmJoint>,
    /// Base.
    pub base: BaseModel,
    /// Servo-bus bit rate, bit/s.
    pub bus_baud: u32,
    /// The body in the world (links, shapes, joints), when the URDF has one root.
    pub body: Option<std::sync::Arc<RobotBody>>,
}

/// Names of the robots the simulator knows: the bundled descriptions.
pub const ROBOTS: [&str; 3] = ferrobot_description::BUNDLED;

/// Mechanical stops of a joint's servo beyond its configured limits, rad.
pub const STOP_MARGIN: f64 = 0.1;

/// A bundled robot by name.
pub fn by_name(name: &str) -> Option<SimRobot> {
    ferrobot_profile::bundled(name)
        .ok()
        .map(|cfg| from_description(&cfg))
}

/// The arm's gravity model a host derives from bundled robot `name`'s description and sends
/// the firmware ([`ferrobot_profile::arm_model`]); empty for a robot that is not bundled or
/// has no arm.
pub fn arm_model(name: &str) -> Vec<ferrobot_protocol::ArmLink> {
    ferrobot_profile::bundled(name)
        .ok()
        .and_then(|cfg| ferrobot_profile::arm_model(&cfg))
        .unwrap_or_default()
}

/// The simulated robot a description describes: one servo per joint-table row (and its
/// mirrored twin), with mechanical stops [`STOP_MARGIN`] beyond the joint limits (the
/// gripper's at its `[gripper] stops`, starting open), the arm chain's links from the URDF
/// (unless `[sim] gravity = false`), the base and the bus rate.
pub fn from_description(cfg: &RobotConfig) -> SimRobot {
    let (arm, arm_index) = if cfg.sim_gravity {
        arm_chain(cfg)
    } else {
        (Vec::new(), BTreeMap::new())
    };
    let tick = |t: i32| units::tick_to_rad(t) as f64;
    let mut servos = Vec::new();
    let mut joint_servos = Vec::new();
    for j in &ferrobot_profile::joint_table(cfg) {
        // Servo angle = sign·q + offset (the twin: its negation).
        let s = j.sign as f64;
        let (a, b) = (
            s * (j.limits.min as f64 - STOP_MARGIN) + j.offset as f64,
            s * (j.limits.max as f64 + STOP_MARGIN) + j.offset as f64,
        );
        let (lo, hi) = (a.min(b), a.max(b));
        let gripper = cfg
            .gripper
            .as_ref()
            .filter(|_| j.kind == JointKind::Gripper);
        let (stops, initial) = match gripper {
            Some(g) => ((tick(g.stops[0]), tick(g.stops[1])), tick(g.open_tick)),
            None => ((lo, hi), j.offset as f64),
        };
        let arm_joint = arm_index.get(j.name.as_str()).copied();
        joint_servos.push(JointServo {
            joint: j.name.to_string(),
            servo: servos.len(),
            sign: s,
            offset: j.offset as f64,
        });
        servos.push(ServoMount {
            id: j.servo_id,
            model: j.model,
            arm_joint,
            gain: s,
            share: if j.twin_id.is_some() { 0.5 } else { 1.0 },
            stops: Some(stops),
            initial,
        });
        if let Some(t) = j.twin_id {
            servos.push(ServoMount {
                id: t,
                model: j.model,
                arm_joint,
                gain: -s,
                share: 0.5,
                stops: Some((-stops.1, -stops.0)),
                initial: -initial,
            });
        }
    }
    SimRobot {
        name: cfg.name.clone(),
        servos,
        arm,
        base: match cfg.base.as_ref().map(|b| b.kind) {
            Some(DescBase::Kobuki) => BaseModel::Kobuki,
            Some(DescBase::Create2) => BaseModel::Create2,
            None => BaseModel::None,
        },
        bus_baud: cfg.bus.baud,
        body: RobotBody::new(cfg, &joint_servos),
    }
}

/// The arm chain's joints with the mass and centre of mass of everything each carries up to
/// the next (the gravity model the host derives for the firmware,
/// [`ferrobot_profile::arm_links`]), and each arm joint's index in it.
fn arm_chain(cfg: &RobotConfig) -> (Vec<ArmJoint>, BTreeMap<String, usize>) {
    let links = ferrobot_profile::arm_links(cfg);
    let index = links
        .iter()
        .enumerate()
        .map(|(i, l)| (l.joint.clone(), i))
        .collect();
    let arm = links
        .iter()
        .map(|l| ArmJoint {
            origin: l.link.origin,
            rpy: l.link.rpy,
            axis: l.link.axis,
            mass: l.link.mass,
            com: l.link.com,
        })
        .collect();
    (arm, index)
}
