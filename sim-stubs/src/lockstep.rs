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
use ferrobot_protocol::{HostMsg, RejectReason};

use crate::diff_drive::Pose;
use crate::hardware::Hardware;
use crate::robots;

mod demo;
mod host;

pub use demo::demo;
pub use host::{HostEnd, HostSide, SimHost, INBOX_CAP, KEEPALIVE_US};

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
    /// The other robots in the same world ([`crate::shared`]), in the order they joined;
    /// empty for a robot alone.
    pub others: Vec<OtherRobot>,
}

/// Another robot in the same world, as a camera sees it: its body and where its links are.
#[derive(Debug, Clone)]
pub struct OtherRobot {
    /// Its body (links and shapes).
    pub body: Arc<RobotBody>,
    /// Pose of every one of its links in the world ([`ferrobot_kinematics::LinkTree::links`]
    /// order).
    pub links: Vec<Isometry3<f64>>,
}

impl PartialEq for OtherRobot {
    /// The same body (the same allocation) with its links at the same poses.
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.body, &other.body) && self.links == other.links
    }
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
        others: Vec::new(),
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
        Self::assemble_at(hw, desc, profile, scene, 0)
    }

    /// Firmware started at `now` (µs) over the plants `hw` (started then too).
    pub(crate) fn assemble_at(
        hw: Hardware,
        desc: robots::SimRobot,
        profile: config::RobotProfile,
        scene: Arc<Scene>,
        now: u64,
    ) -> Self {
        Self {
            now,
            fw: Firmware::new(profile, "sim", Instant::from_micros(now)),
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
            self.events_now();
            if self.now >= t_end {
                break;
            }
            self.now = self.next_event().max(self.now + 1).min(t_end);
            self.events += 1;
        }
        self.hw.chain.advance_to(self.now);
    }

    /// Everything due at the current time: host bytes to the firmware, its deadlines, bytes
    /// to and from the plants, the plants' own events.
    pub(crate) fn events_now(&mut self) {
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
    }

    /// Set the clock to `now_us` (µs), no earlier than it is: a floor that runs several
    /// robots on one clock moves them together.
    pub(crate) fn set_now(&mut self, now_us: u64) {
        self.now = self.now.max(now_us);
    }

    /// When anything next happens (µs): a firmware deadline or a plant's event.
    pub(crate) fn next_event(&self) -> u64 {
        let deadline = self.fw.next_deadline().as_micros();
        self.hw.next_event().map_or(deadline, |t| t.min(deadline))
    }

    /// Run for `dt_us` of simulated time.
    pub fn run_for(&mut self, dt_us: u64) {
        self.run_until(self.now + dt_us);
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
