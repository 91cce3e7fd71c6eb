//! The lockstep simulator: the firmware core and the simulated [`Hardware`] (servo chain and
//! base, joined by timed serial lines) on one virtual clock.
//! Time advances from event to event (the firmware's deadlines, bytes arriving, base
//! feedback), so simulated seconds cost milliseconds. Everything is deterministic for a seed.
//!
//! The host side speaks real frames: [`LockstepSim::write_host`] and
//! [`LockstepSim::take_host_output`] carry the same bytes a serial port would; [`SimHost`]
//! drives them with the protocol's host session for tests, benches and hostile hosts.

use std::sync::Arc;

use nalgebra::Isometry3;

use crate::body::RobotBody;
use crate::scene::{Scene, SceneError};
use ferrobot_firmware::time::Instant;
use ferrobot_firmware::{config, Firmware, Link};
use ferrobot_protocol::session::{Answer, HostSession, Request, SessionError};
use ferrobot_protocol::{
    DeviceMsg, HostMsg, RejectReason, Telemetry, MAX_WIRE, PROTOCOL_VERSION, SCHEMA_HASH,
};

use crate::diff_drive::Pose;
use crate::hardware::Hardware;
use crate::robots;

mod demo;

pub use demo::demo;

/// Errors of the simulator.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum SimError {
    /// No robot of that name.
    UnknownRobot(String),
    /// A wait ran out of simulated time.
    Timeout(&'static str),
    /// The firmware rejected a command.
    Rejected(RejectReason),
}

impl std::fmt::Display for SimError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SimError::UnknownRobot(r) => {
                write!(
                    f,
                    "unknown robot {r:?}; the simulator knows {}",
                    robots::ROBOTS.join(", ")
                )
            }
            SimError::Timeout(what) => write!(f, "timed out waiting for {what}"),
            SimError::Rejected(r) => write!(f, "the firmware rejected the command: {r:?}"),
        }
    }
}

impl std::error::Error for SimError {}

/// Firmware and hardware on one virtual clock.
pub struct LockstepSim {
    now: u64,
    /// The firmware core.
    pub fw: Firmware,
    /// The plants and the lines between them and the firmware.
    pub hw: Hardware,
    host_in: Vec<u8>,
    host_out: Vec<u8>,
    /// Events processed (for benchmarks).
    pub events: u64,
    scene: Arc<Scene>,
    body: Option<Arc<RobotBody>>,
}

/// The simulated world's ground truth at one instant (the simulator's "motion capture").
#[derive(Debug, Clone, PartialEq)]
pub struct Truth {
    /// Simulated time, µs.
    pub time_us: u64,
    /// Pose of the robot's root link in the world.
    pub root: Isometry3<f64>,
    /// Value of every movable joint of the URDF tree ([`ferrobot_kinematics::LinkTree::joints`]
    /// order), rad or m.
    pub joints: Vec<f64>,
    /// Pose of every URDF link in the world ([`ferrobot_kinematics::LinkTree::links`] order).
    pub links: Vec<Isometry3<f64>>,
    /// Pose of every scene body in the world now ([`Scene::bodies`] order): the physics
    /// world's live poses.
    pub bodies: Vec<Isometry3<f64>>,
}

/// The ground truth of the plants `hw` at `now_us` in `scene`, for the robot's `body`: the
/// root from the base's true pose (or the scene's start pose without a base), the joints from
/// the servos' true angles.
pub fn truth_of(hw: &Hardware, now_us: u64, scene: &Scene, body: Option<&RobotBody>) -> Truth {
    let base = hw.robot_pose();
    let root = RobotBody::root_pose(base, scene.robot_height);
    let theta: Vec<f64> = hw.chain.servos.iter().map(|s| s.theta).collect();
    let (joints, links) = match body {
        Some(b) => {
            let q = b.joint_values(&theta);
            let links = b.link_poses(&root, &q);
            (q, links)
        }
        None => (Vec::new(), Vec::new()),
    };
    Truth {
        time_us: now_us,
        root,
        joints,
        links,
        bodies: hw
            .body_poses()
            .unwrap_or_else(|| scene.bodies.iter().map(|b| b.pose).collect()),
    }
}

impl LockstepSim {
    /// The simulated `robot` with plants seeded by `seed`.
    pub fn new(robot: &str, seed: u64) -> Result<Self, SimError> {
        let desc =
            robots::by_name(robot).ok_or_else(|| SimError::UnknownRobot(robot.to_string()))?;
        let profile =
            config::by_name(robot).ok_or_else(|| SimError::UnknownRobot(robot.to_string()))?;
        Ok(Self::with(desc, profile, seed))
    }

    /// A simulator for an explicit description and firmware profile.
    pub fn with(desc: robots::SimRobot, profile: config::RobotProfile, seed: u64) -> Self {
        Self::assemble(
            Hardware::new(&desc, seed),
            desc,
            profile,
            Arc::new(Scene::empty()),
        )
    }

    /// A simulator for an explicit description and firmware profile in `scene`, the robot at
    /// the scene's start pose, the scene's bodies in the physics world ([`crate::world`]).
    /// Fails with [`SceneError::Overlap`] when a scene body overlaps the robot at the start.
    pub fn with_scene(
        desc: robots::SimRobot,
        profile: config::RobotProfile,
        seed: u64,
        scene: Arc<Scene>,
    ) -> Result<Self, SceneError> {
        let hw = Hardware::in_scene(&desc, seed, &scene)?;
        Ok(Self::assemble(hw, desc, profile, scene))
    }

    fn assemble(
        hw: Hardware,
        desc: robots::SimRobot,
        profile: config::RobotProfile,
        scene: Arc<Scene>,
    ) -> Self {
        Self {
            now: 0,
            fw: Firmware::new(profile, "sim", Instant::ZERO),
            hw,
            host_in: Vec::new(),
            host_out: Vec::new(),
            events: 0,
            scene,
            body: desc.body.clone(),
        }
    }

    /// The scene.
    pub fn scene(&self) -> &Arc<Scene> {
        &self.scene
    }

    /// The robot's body (links and shapes), when its URDF has one.
    pub fn body(&self) -> Option<&Arc<RobotBody>> {
        self.body.as_ref()
    }

    /// The world's ground truth now: the robot's root, joints and links, and the scene's
    /// bodies.
    pub fn truth(&self) -> Truth {
        truth_of(&self.hw, self.now, &self.scene, self.body.as_deref())
    }

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.now
    }

    /// Bytes from the host, delivered to the firmware at the current simulated time.
    pub fn write_host(&mut self, bytes: &[u8]) {
        self.host_in.extend_from_slice(bytes);
    }

    /// Bytes the firmware has sent to the host.
    pub fn take_host_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.host_out)
    }

    /// Put extra bytes on the line from the servo bus or the base to the firmware, as line
    /// noise would (fault injection).
    pub fn inject_to_firmware(&mut self, link: Link, bytes: &[u8]) {
        match link {
            Link::Host => self.host_in.extend_from_slice(bytes),
            _ => self.hw.inject_to_firmware(link, self.now, bytes),
        }
    }

    /// Ground-truth pose of the base (world frame), if there is a base.
    pub fn base_truth(&self) -> Option<Pose> {
        self.hw.base_truth()
    }

    /// Fault injection, a kidnapped robot: carries the base to `pose` (`[x, y, θ]` in the
    /// world, m and rad) without turning its wheels, so its odometry does not see the move.
    /// False (and nothing moves) without a base or for a pose that is not finite.
    pub fn carry_base(&mut self, pose: Pose) -> bool {
        match self.hw.base.as_mut() {
            Some(b) if pose.iter().all(|x| x.is_finite()) => {
                b.drive.truth = pose;
                true
            }
            _ => false,
        }
    }

    fn flush(&mut self) {
        for link in [Link::Servo, Link::Base] {
            let n = self.fw.pending(link).len();
            if n > 0 {
                self.hw.from_firmware(link, self.now, self.fw.pending(link));
                self.fw.consume(link, n);
            }
        }
        let n = self.fw.pending(Link::Host).len();
        if n > 0 {
            self.host_out.extend_from_slice(self.fw.pending(Link::Host));
            self.fw.consume(Link::Host, n);
        }
    }

    /// Run until simulated time `t_end` (µs).
    pub fn run_until(&mut self, t_end: u64) {
        loop {
            // The plants' clock (µs) as the firmware's.
            let now = Instant::from_micros(self.now);
            if !self.host_in.is_empty() {
                let bytes = std::mem::take(&mut self.host_in);
                self.fw.on_host_bytes(now, &bytes);
            }
            if self.fw.next_deadline() <= now {
                self.fw.poll(now);
            }
            self.flush();
            // Deliveries due now.
            self.hw.step(self.now);
            if let Some(b) = self.hw.to_firmware(Link::Servo, self.now) {
                self.fw.on_servo_bytes(now, &b);
            }
            if let Some(b) = self.hw.to_firmware(Link::Base, self.now) {
                self.fw.on_base_bytes(now, &b);
            }
            if self.fw.next_deadline() <= now {
                self.fw.poll(now);
            }
            self.flush();
            if self.now >= t_end {
                break;
            }
            let deadline = self.fw.next_deadline().as_micros();
            let next = self.hw.next_event().map_or(deadline, |t| t.min(deadline));
            self.now = next.max(self.now + 1).min(t_end);
            self.events += 1;
        }
        self.hw.chain.advance_to(self.now);
    }

    /// Run for `dt_us` of simulated time.
    pub fn run_for(&mut self, dt_us: u64) {
        self.run_until(self.now + dt_us);
    }
}

/// Messages a [`SimHost`] keeps for callers to wait for, at most.
pub const INBOX_CAP: usize = 1024;

/// A host talking frames to a [`LockstepSim`]: the protocol's host session
/// ([`HostSession`], the one the API's links drive too) in lockstep with the simulator, plus
/// raw access for tests and hostile hosts (send any message, see every message the session
/// did not route).
pub struct SimHost {
    /// The simulator.
    pub sim: LockstepSim,
    /// The host session.
    pub session: HostSession,
    /// Messages received that answered nothing pending (hellos, faults, logs, answers to
    /// [`SimHost::send`]), oldest first, at most [`INBOX_CAP`].
    pub inbox: Vec<DeviceMsg>,
    /// The newest telemetry.
    pub telemetry: Option<Telemetry>,
    /// Send a heartbeat every [`KEEPALIVE_US`] of simulated time, as a host's I/O thread does,
    /// so the firmware's watchdog stays fed (on by default).
    pub keepalive: bool,
    last_keepalive: u64,
}

/// Heartbeat period of a [`SimHost`] with keepalive on, µs.
pub const KEEPALIVE_US: u64 = 100_000;

impl SimHost {
    /// Start `robot` with `seed` and perform the handshake.
    pub fn start(robot: &str, seed: u64) -> Result<Self, SimError> {
        let mut s = Self::new(LockstepSim::new(robot, seed)?);
        s.handshake()?;
        Ok(s)
    }

    /// Wrap a simulator without a handshake.
    pub fn new(sim: LockstepSim) -> Self {
        Self {
            sim,
            session: HostSession::new(),
            inbox: Vec::new(),
            telemetry: None,
            keepalive: true,
            last_keepalive: 0,
        }
    }

    /// Send the handshake and wait for the firmware's answer.
    pub fn handshake(&mut self) -> Result<ferrobot_protocol::DeviceInfo, SimError> {
        self.send(&HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH,
        });
        let m = self.wait_msg(200_000, |m| matches!(m, DeviceMsg::Hello(_)))?;
        match m {
            DeviceMsg::Hello(info) => Ok(info),
            _ => Err(SimError::Timeout("hello")),
        }
    }

    /// Send raw bytes to the firmware (garbage, corrupted frames).
    pub fn send_raw(&mut self, bytes: &[u8]) {
        self.sim.write_host(bytes);
    }

    /// Send any message without waiting for its answer (which arrives in the inbox); returns
    /// its sequence number.
    pub fn send(&mut self, msg: &HostMsg) -> u16 {
        let mut buf = [0u8; MAX_WIRE];
        match self.session.send_unrouted(msg, self.sim.now_us(), &mut buf) {
            Ok((seq, n)) => {
                self.sim.write_host(&buf[..n]);
                seq
            }
            Err(_) => 0,
        }
    }

    fn keep_alive(&mut self) {
        if self.keepalive && self.sim.now_us() >= self.last_keepalive + KEEPALIVE_US {
            self.last_keepalive = self.sim.now_us();
            let mut buf = [0u8; MAX_WIRE];
            if let Some(n) = self.session.heartbeat_due(self.sim.now_us(), 0, &mut buf) {
                self.sim.write_host(&buf[..n]);
            }
        }
    }

    /// Advance the simulation by up to `dt_us`, feeding the watchdog on the way.
    fn step(&mut self, dt_us: u64) {
        let end = self.sim.now_us() + dt_us;
        while self.sim.now_us() < end {
            self.keep_alive();
            let chunk = if self.keepalive {
                KEEPALIVE_US.min(end - self.sim.now_us())
            } else {
                end - self.sim.now_us()
            };
            self.sim.run_for(chunk);
        }
    }

    fn pump(&mut self) {
        let bytes = self.sim.take_host_output();
        let inbox = &mut self.inbox;
        self.session.on_bytes_with(&bytes, |m| {
            // Bounded: messages nobody waits for are dropped oldest first.
            if inbox.len() >= INBOX_CAP {
                inbox.remove(0);
            }
            inbox.push(m.clone());
        });
        // Faults are kept in the inbox, in order with the other messages.
        while self.session.take_fault().is_some() {}
        if let Some(t) = self.session.telemetry() {
            if self.telemetry.as_ref() != Some(t) {
                self.telemetry = Some(t.clone());
            }
        }
    }

    /// Run the simulation for `dt_us`, collecting messages.
    pub fn run_for(&mut self, dt_us: u64) {
        self.step(dt_us);
        self.pump();
    }

    /// Run in 1 ms steps until `ready` has an answer (checked after each pump), or
    /// `timeout_us` of simulated time pass (a timeout naming `what`).
    fn run_until<T>(
        &mut self,
        timeout_us: u64,
        what: &'static str,
        mut ready: impl FnMut(&mut Self) -> Option<T>,
    ) -> Result<T, SimError> {
        let end = self.sim.now_us() + timeout_us;
        loop {
            self.pump();
            if let Some(r) = ready(self) {
                return Ok(r);
            }
            if self.sim.now_us() >= end {
                return Err(SimError::Timeout(what));
            }
            self.step(1000);
        }
    }

    /// Run in 1 ms steps until a received message satisfies `pred` (it is removed from the
    /// inbox and returned) or `timeout_us` of simulated time pass.
    pub fn wait_msg(
        &mut self,
        timeout_us: u64,
        pred: impl Fn(&DeviceMsg) -> bool,
    ) -> Result<DeviceMsg, SimError> {
        self.run_until(timeout_us, "a message", |s| {
            let i = s.inbox.iter().position(&pred)?;
            Some(s.inbox.remove(i))
        })
    }

    /// Encode with `encode` (a command or a request), send it and wait (1 ms steps, at most
    /// `timeout_us`) for its answer, routed by the session.
    fn exchange(
        &mut self,
        timeout_us: u64,
        encode: impl FnOnce(&mut HostSession, u64, &mut [u8]) -> Result<(u16, usize), SessionError>,
    ) -> Result<Answer, SimError> {
        let mut buf = [0u8; MAX_WIRE];
        let (seq, n) = encode(&mut self.session, self.sim.now_us(), &mut buf)
            .map_err(|_| SimError::Rejected(RejectReason::Unsupported))?;
        self.sim.write_host(&buf[..n]);
        let r = self.run_until(timeout_us, "a message", |s| s.session.take_answer(seq));
        if r.is_err() {
            self.session.forget(seq);
        }
        match r? {
            Answer::Rejected(reason) => Err(SimError::Rejected(reason)),
            a => Ok(a),
        }
    }

    /// Send a command and wait for its acknowledgement (routed by the session).
    pub fn command(&mut self, msg: &HostMsg) -> Result<(), SimError> {
        self.exchange(100_000, |s, now, out| s.command(msg, now, out))
            .map(|_| ())
    }

    /// Send a typed request and wait for its reply (routed by the session).
    pub fn request<R: Request>(&mut self, r: &R) -> Result<R::Reply, SimError> {
        let a = self.exchange(200_000, |s, now, out| s.request(r, now, out))?;
        R::reply(a).ok_or(SimError::Timeout("a reply of the right kind"))
    }

    /// Run in 1 ms steps until the newest telemetry satisfies `pred`, or time out.
    pub fn wait_telemetry(
        &mut self,
        timeout_us: u64,
        pred: impl Fn(&Telemetry) -> bool,
    ) -> Result<Telemetry, SimError> {
        self.run_until(timeout_us, "telemetry", |s| {
            s.telemetry.as_ref().filter(|t| pred(t)).cloned()
        })
    }

    /// Take every fault received so far.
    pub fn take_faults(&mut self) -> Vec<ferrobot_protocol::Fault> {
        self.pump();
        let mut out = Vec::new();
        self.inbox.retain(|m| match m {
            DeviceMsg::Fault(x) => {
                out.push(*x);
                false
            }
            _ => true,
        });
        out
    }
}

/// The scenario the benchmarks and profiles run: the LoCoBot, configured, its arm on a slow
/// 30 s move and its base driving a 2 m circle, so that every bus and every plant is busy.
pub fn locobot_busy(seed: u64) -> Result<SimHost, SimError> {
    use ferrobot_protocol::JointPoint;
    let mut s = SimHost::start("locobot", seed)?;
    s.wait_telemetry(2_000_000, |t| {
        t.faults & ferrobot_protocol::fault_flags::CONFIGURING == 0
    })?;
    let points = [0.6f32, 0.4, -0.4, 0.3, 0.5]
        .iter()
        .map(|&p| JointPoint::at_rest(p))
        .collect();
    s.command(&HostMsg::Waypoint {
        joints: 0b1_1111,
        duration_us: 30_000_000,
        points,
    })?;
    s.command(&HostMsg::BaseVelocity {
        v: 0.2,
        w: 0.1,
        duration_ms: 30_000,
    })?;
    Ok(s)
}
