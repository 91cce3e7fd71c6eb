//! The in-process simulator backend: the protocol's host session
//! ([`ferrobot_protocol::session::HostSession`]) driving a lockstep simulator built from the
//! robot's configuration (servo chain, gravity from the URDF's link masses, base) in virtual
//! time: waiting for an answer runs the simulation.

use std::time::{Duration, Instant};

use ferrobot_protocol::session::{
    Answer, GetDiagnostics, GetJoint, Handshake, HostSession, Request, SessionError,
};
use ferrobot_protocol::{
    DeviceInfo, Diagnostics, Fault, HostMsg, JointConfig, Telemetry, MAX_WIRE,
};
use ferrobot_sim::arm::ArmJoint;
use ferrobot_sim::chain::ServoMount;
use ferrobot_sim::lockstep::KEEPALIVE_US;
use ferrobot_sim::robots::{BaseModel as SimBase, SimRobot};
use ferrobot_sim::LockstepSim;

use super::{acked, replied, Link};
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

/// How long (simulated) a command waits for its acknowledgement, µs.
const COMMAND_TIMEOUT_US: u64 = 100_000;
/// How long (simulated) a request, the handshake or the first telemetry may take, µs.
const REQUEST_TIMEOUT_US: u64 = 200_000;

/// The simulator backend.
pub struct SimLink {
    sim: LockstepSim,
    session: HostSession,
    info: DeviceInfo,
    realtime: Option<(Instant, u64)>,
    /// When the last heartbeat went out (simulated µs).
    last_keepalive: u64,
}

impl SimLink {
    /// Simulate the robot of `cfg` with plants seeded by `seed`.
    pub fn start(cfg: &RobotConfig, seed: u64, realtime: bool) -> Result<Self> {
        let sim = LockstepSim::with(sim_robot(cfg), cfg.firmware_profile(), seed);
        let mut link = SimLink {
            sim,
            session: HostSession::new(),
            info: super::placeholder_info(),
            realtime: None,
            last_keepalive: 0,
        };
        link.info = link.handshake()?;
        // Let the firmware configure its servos before the first command.
        let end = link.sim.now_us() + 2_000_000;
        loop {
            link.pump();
            let configured = link
                .session
                .telemetry()
                .is_some_and(|t| t.faults & ferrobot_protocol::fault_flags::CONFIGURING == 0);
            if configured {
                break;
            }
            if link.sim.now_us() >= end {
                return Err(Error::Timeout {
                    what: "servo configuration".into(),
                    after: Duration::from_secs(2),
                });
            }
            link.step(1000);
        }
        if realtime {
            link.realtime = Some((Instant::now(), link.sim.now_us()));
        }
        Ok(link)
    }

    fn handshake(&mut self) -> Result<DeviceInfo> {
        let mut buf = [0u8; MAX_WIRE];
        let n = self
            .session
            .hello(self.sim.now_us(), &mut buf)
            .map_err(|e| Error::Link(format!("hello: {e:?}")))?;
        self.sim.write_host(&buf[..n]);
        let end = self.sim.now_us() + REQUEST_TIMEOUT_US;
        loop {
            self.pump();
            match self.session.handshake() {
                Handshake::Accepted(info) => return Ok(info.clone()),
                Handshake::Refused(info) => {
                    return Err(Error::VersionMismatch {
                        host: ferrobot_protocol::PROTOCOL_VERSION,
                        host_schema: ferrobot_protocol::SCHEMA_HASH,
                        firmware: info.protocol_version,
                        firmware_schema: info.schema_hash,
                    })
                }
                Handshake::Waiting => {}
            }
            if self.sim.now_us() >= end {
                return Err(Error::Timeout {
                    what: "hello".into(),
                    after: Duration::from_micros(REQUEST_TIMEOUT_US),
                });
            }
            self.step(1000);
        }
    }

    /// A heartbeat every [`KEEPALIVE_US`] of simulated time, as a host's I/O thread sends
    /// when it is quiet, so that the firmware's watchdog stays fed.
    fn keep_alive(&mut self) {
        let now = self.sim.now_us();
        if now >= self.last_keepalive + KEEPALIVE_US {
            self.last_keepalive = now;
            let mut buf = [0u8; MAX_WIRE];
            if let Some(n) = self.session.heartbeat_due(now, 0, &mut buf) {
                self.sim.write_host(&buf[..n]);
            }
        }
    }

    /// Advance the simulation by `dt_us`, feeding the watchdog on the way.
    fn step(&mut self, dt_us: u64) {
        let end = self.sim.now_us() + dt_us;
        while self.sim.now_us() < end {
            self.keep_alive();
            let chunk = KEEPALIVE_US.min(end - self.sim.now_us());
            self.sim.run_for(chunk);
        }
    }

    /// Hand what the firmware sent to the session.
    fn pump(&mut self) {
        let bytes = self.sim.take_host_output();
        self.session.on_bytes(&bytes);
    }

    /// Run in 1 ms steps until the answer to `seq` comes, for at most `timeout_us`.
    fn answer(&mut self, seq: u16, timeout_us: u64, what: &str) -> Result<Answer> {
        let end = self.sim.now_us() + timeout_us;
        loop {
            self.pump();
            if let Some(a) = self.session.take_answer(seq) {
                return Ok(a);
            }
            if self.sim.now_us() >= end {
                self.session.forget(seq);
                return Err(Error::Timeout {
                    what: what.to_string(),
                    after: Duration::from_micros(timeout_us),
                });
            }
            self.step(1000);
        }
    }

    /// Encode with `encode` (a command or a request), send it, and wait for its answer for at
    /// most `timeout_us`.
    fn exchange(
        &mut self,
        what: &str,
        timeout_us: u64,
        encode: impl FnOnce(
            &mut HostSession,
            u64,
            &mut [u8],
        ) -> std::result::Result<(u16, usize), SessionError>,
    ) -> Result<Answer> {
        let mut buf = [0u8; MAX_WIRE];
        let (seq, n) = encode(&mut self.session, self.sim.now_us(), &mut buf)
            .map_err(|e| Error::Link(format!("{what}: {e:?}")))?;
        self.sim.write_host(&buf[..n]);
        self.answer(seq, timeout_us, what)
    }

    /// A typed request and its reply.
    fn request<R: Request>(&mut self, r: &R, what: &str) -> Result<R::Reply> {
        let a = self.exchange(what, REQUEST_TIMEOUT_US, |s, now, out| {
            s.request(r, now, out)
        })?;
        replied::<R>(what, a)
    }
}

impl Link for SimLink {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }

    fn command(&mut self, msg: &HostMsg, what: &str) -> Result<()> {
        let a = self.exchange(what, COMMAND_TIMEOUT_US, |s, now, out| {
            s.command(msg, now, out)
        })?;
        acked(what, a)
    }

    fn joint_config(&mut self, index: u8) -> Result<JointConfig> {
        self.request(&GetJoint(index), "joint configuration")
    }

    fn diagnostics(&mut self) -> Result<Diagnostics> {
        self.request(&GetDiagnostics, "diagnostics")
    }

    fn telemetry(&mut self) -> Result<Telemetry> {
        let end = self.sim.now_us() + REQUEST_TIMEOUT_US;
        loop {
            self.pump();
            if let Some(t) = self.session.telemetry() {
                return Ok(t.clone());
            }
            if self.sim.now_us() >= end {
                return Err(Error::Link("no telemetry".into()));
            }
            self.step(1000);
        }
    }

    fn wait(&mut self, dt: Duration) {
        self.step(dt.as_micros() as u64);
        self.pump();
        if let Some((wall0, sim0)) = self.realtime {
            let due = Duration::from_micros(self.sim.now_us() - sim0);
            if let Some(rest) = due.checked_sub(wall0.elapsed()) {
                std::thread::sleep(rest);
            }
        }
    }

    fn now(&self) -> Duration {
        Duration::from_micros(self.sim.now_us())
    }

    fn take_faults(&mut self) -> Vec<Fault> {
        self.pump();
        std::iter::from_fn(|| self.session.take_fault()).collect()
    }

    fn simulator(&mut self) -> Option<&mut LockstepSim> {
        Some(&mut self.sim)
    }
}
