//! The in-process simulator backend: a [`SimSession`] (the protocol's host session in virtual
//! time) on a lockstep simulator built from the robot's configuration (servo chain, gravity
//! from the URDF's link masses, base): waiting for an answer runs the simulation.

use std::time::{Duration, Instant};

use ferrobot_protocol::session::{GetDiagnostics, GetJoint};
use ferrobot_protocol::{DeviceInfo, Diagnostics, Fault, HostMsg, JointConfig, Telemetry};
use ferrobot_sim::arm::ArmJoint;
use ferrobot_sim::chain::ServoMount;
use ferrobot_sim::robots::{BaseModel as SimBase, SimRobot};
use ferrobot_sim::{LockstepSim, SimError, SimSession};

use super::{rejection, Link};
use crate::config::{BaseModel, RobotConfig};
use crate::error::{Error, Result};

/// The simulated robot a configuration describes.
pub fn sim_robot(cfg: &RobotConfig) -> SimRobot {
    // Gravity from the arm chain's links (mass and centre of mass of each joint's child link).
    let mut arm = Vec::new();
    let mut arm_index = std::collections::BTreeMap::new();
    if let (Some(a), true) = (&cfg.arm, cfg.sim_gravity) {
        let mut prev = a.base_frame.clone();
        for name in &a.joints {
            let Some(j) = cfg.urdf.joints.iter().find(|j| &j.name == name) else {
                break;
            };
            // Fixed joints between the previous arm joint and this one must be trivial for the
            // simple gravity model; otherwise gravity is left out.
            let mut origin = j.origin.xyz.0;
            let mut parent = j.parent.link.clone();
            while parent != prev {
                let Some(f) = cfg.urdf.joints.iter().find(|f| f.child.link == parent) else {
                    break;
                };
                origin = [
                    origin[0] + f.origin.xyz[0],
                    origin[1] + f.origin.xyz[1],
                    origin[2] + f.origin.xyz[2],
                ];
                parent = f.parent.link.clone();
            }
            let child = cfg.urdf.links.iter().find(|l| l.name == j.child.link);
            let (mass, com) = child
                .map(|l| (l.inertial.mass.value, l.inertial.origin.xyz.0))
                .unwrap_or((0.0, [0.0; 3]));
            arm_index.insert(name.clone(), arm.len());
            arm.push(ArmJoint {
                rpy: j.origin.rpy.0,
                origin,
                axis: j.axis.xyz.0,
                mass,
                com,
            });
            prev = j.child.link.clone();
        }
        // Everything distal to the last arm joint rides on its link: add the gripper's fingers.
        if let (Some(last), Some(n)) = (arm.last_mut(), a.joints.last()) {
            let tip = cfg
                .urdf
                .joints
                .iter()
                .find(|j| &j.name == n)
                .map(|j| j.child.link.clone());
            for j in cfg
                .urdf
                .joints
                .iter()
                .filter(|j| Some(&j.parent.link) == tip.as_ref())
            {
                if let Some(l) = cfg.urdf.links.iter().find(|l| l.name == j.child.link) {
                    let m = l.inertial.mass.value;
                    let c = [
                        j.origin.xyz[0] + l.inertial.origin.xyz[0],
                        j.origin.xyz[1] + l.inertial.origin.xyz[1],
                        j.origin.xyz[2] + l.inertial.origin.xyz[2],
                    ];
                    let total = last.mass + m;
                    if total > 0.0 {
                        for (lc, ck) in last.com.iter_mut().zip(c) {
                            *lc = (*lc * last.mass + ck * m) / total;
                        }
                        last.mass = total;
                    }
                }
            }
        }
    }
    let mut servos = Vec::new();
    for j in &cfg.joints {
        // Servo angle = sign·q + offset (the twin: its negation); mechanical stops 0.1 rad
        // beyond the joint limits.
        let s = j.sign as f64;
        let margin = 0.1;
        let (a, b) = (
            s * (j.limits.min as f64 - margin) + j.offset as f64,
            s * (j.limits.max as f64 + margin) + j.offset as f64,
        );
        let (lo, hi) = (a.min(b), a.max(b));
        let arm_joint = arm_index.get(j.name.as_str()).copied();
        let twin_share = if j.twin_id.is_some() { 0.5 } else { 1.0 };
        let gripper = j.kind == ferrobot_protocol::JointKind::Gripper;
        let initial = if gripper {
            ferrobot_protocol::dxl::units::tick_to_rad(2800) as f64
        } else {
            j.offset as f64
        };
        servos.push(ServoMount {
            id: j.servo_id,
            model: j.model,
            arm_joint,
            gain: s,
            share: twin_share,
            stops: if gripper {
                Some((
                    ferrobot_protocol::dxl::units::tick_to_rad(1650) as f64,
                    ferrobot_protocol::dxl::units::tick_to_rad(3050) as f64,
                ))
            } else {
                Some((lo, hi))
            },
            initial,
        });
        if let Some(t) = j.twin_id {
            servos.push(ServoMount {
                id: t,
                model: j.model,
                arm_joint,
                gain: -s,
                share: 0.5,
                stops: Some((-hi, -lo)),
                initial: -initial,
            });
        }
    }
    SimRobot {
        name: cfg.name.clone(),
        servos,
        arm,
        base: match cfg.base.as_ref().map(|b| b.kind) {
            Some(BaseModel::Kobuki) => SimBase::Kobuki,
            Some(BaseModel::Create2) => SimBase::Create2,
            None => SimBase::None,
        },
        bus_baud: 4_000_000,
    }
}

/// The simulator backend: the lockstep simulator driven by [`SimSession`], the protocol's host
/// session in virtual time.
pub struct SimLink {
    session: SimSession,
    info: DeviceInfo,
    realtime: Option<(Instant, u64)>,
}

/// The API's error for a simulator session's, naming `what` was asked.
fn sim_err(what: &str, e: SimError) -> Error {
    match e {
        SimError::Rejected(r) => rejection(what, r),
        SimError::Timeout(waited) => Error::Timeout {
            what: format!("{what} ({waited})"),
            after: Duration::from_millis(200),
        },
        other => Error::Link(other.to_string()),
    }
}

impl SimLink {
    /// Simulate the robot of `cfg` with plants seeded by `seed`.
    pub fn start(cfg: &RobotConfig, seed: u64, realtime: bool) -> Result<Self> {
        let sim = LockstepSim::with(sim_robot(cfg), cfg.firmware_profile(), seed);
        let mut session = SimSession::new(sim);
        let info = session.handshake().map_err(|e| sim_err("hello", e))?;
        let mut link = SimLink {
            session,
            info,
            realtime: None,
        };
        // Let the firmware configure its servos before the first command.
        link.session
            .wait_telemetry(2_000_000, |t| {
                t.faults & ferrobot_protocol::fault_flags::CONFIGURING == 0
            })
            .map_err(|e| sim_err("servo configuration", e))?;
        if realtime {
            link.realtime = Some((Instant::now(), link.session.sim.now_us()));
        }
        Ok(link)
    }
}

impl Link for SimLink {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }

    fn command(&mut self, msg: &HostMsg, what: &str) -> Result<()> {
        self.session.command(msg).map_err(|e| sim_err(what, e))
    }

    fn joint_config(&mut self, index: u8) -> Result<JointConfig> {
        self.session
            .request(&GetJoint(index))
            .map_err(|e| sim_err("joint configuration", e))
    }

    fn diagnostics(&mut self) -> Result<Diagnostics> {
        self.session
            .request(&GetDiagnostics)
            .map_err(|e| sim_err("diagnostics", e))
    }

    fn telemetry(&mut self) -> Result<Telemetry> {
        self.session
            .wait_telemetry(200_000, |_| true)
            .map_err(|_| Error::Link("no telemetry".into()))
    }

    fn wait(&mut self, dt: Duration) {
        self.session.run_for(dt.as_micros() as u64);
        if let Some((wall0, sim0)) = self.realtime {
            let due = Duration::from_micros(self.session.sim.now_us() - sim0);
            if let Some(rest) = due.checked_sub(wall0.elapsed()) {
                std::thread::sleep(rest);
            }
        }
    }

    fn now(&self) -> Duration {
        Duration::from_micros(self.session.sim.now_us())
    }

    fn take_faults(&mut self) -> Vec<Fault> {
        self.session.take_faults()
    }

    fn simulator(&mut self) -> Option<&mut LockstepSim> {
        Some(&mut self.session.sim)
    }
}
