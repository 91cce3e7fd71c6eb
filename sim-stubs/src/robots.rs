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

/// The arm chain's joints with the mass and centre of mass of each joint's child link, and
/// each arm joint's index in it. Fixed joints between two arm joints must be pure
/// translations (their offsets are summed). Everything distal to the last arm joint (the
/// gripper's fingers) rides on its link.
fn arm_chain(cfg: &RobotConfig) -> (Vec<ArmJoint>, BTreeMap<String, usize>) {
    let mut arm = Vec::new();
    let mut index = BTreeMap::new();
    let Some(a) = &cfg.arm else {
        return (arm, index);
    };
    let urdf = &cfg.urdf;
    let mut prev = a.base_frame.clone();
    for name in &a.joints {
        let Some(j) = urdf.joints.iter().find(|j| &j.name == name) else {
            break;
        };
        let mut origin = j.origin.xyz.0;
        let mut parent = j.parent.link.clone();
        while parent != prev {
            let Some(f) = urdf.joints.iter().find(|f| f.child.link == parent) else {
                break;
            };
            for (o, d) in origin.iter_mut().zip(f.origin.xyz.0) {
                *o += d;
            }
            parent = f.parent.link.clone();
        }
        let (mass, com) = urdf
            .links
            .iter()
            .find(|l| l.name == j.child.link)
            .map(|l| (l.inertial.mass.value, l.inertial.origin.xyz.0))
            .unwrap_or((0.0, [0.0; 3]));
        index.insert(name.clone(), arm.len());
        arm.push(ArmJoint {
            rpy: j.origin.rpy.0,
            origin,
            axis: j.axis.xyz.0,
            mass,
            com,
        });
        prev = j.child.link.clone();
    }
    if let (Some(last), Some(n)) = (arm.last_mut(), a.joints.last()) {
        let tip = urdf
            .joints
            .iter()
            .find(|j| &j.name == n)
            .map(|j| j.child.link.clone());
        for j in urdf
            .joints
            .iter()
            .filter(|j| Some(&j.parent.link) == tip.as_ref())
        {
            if let Some(l) = urdf.links.iter().find(|l| l.name == j.child.link) {
                let m = l.inertial.mass.value;
                let total = last.mass + m;
                if total > 0.0 {
                    for ((lc, o), c) in last
                        .com
                        .iter_mut()
                        .zip(j.origin.xyz.0)
                        .zip(l.inertial.origin.xyz.0)
                    {
                        *lc = (*lc * last.mass + (o + c) * m) / total;
                    }
                    last.mass = total;
                }
            }
        }
    }
    (arm, index)
}
