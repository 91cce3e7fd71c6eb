//! The simulated hardware around a firmware: the servo chain and the base, joined to the
//! microcontroller by timed serial lines (the servo bus at its bit rate, the base at
//! [`BASE_BAUD`]). Sans-IO and event-driven: the caller hands over what the firmware sent,
//! runs the plants from event to event, and takes what reaches the firmware.
//!
//! Two callers drive it: [`crate::LockstepSim`] with the firmware core in-process, and the
//! [`crate::conductor`] with the real firmware in QEMU behind pseudo-terminals. Both see the
//! same plants on the same wires.
//!
//! In a scene with bodies the hardware also owns the physics [`World`], stepped every
//! [`crate::world::STEP_US`] as one of the plants' events, on the base's 1 ms grid: at each
//! step the servo chain and the base are advanced to it (the base's bumper and wheels meeting
//! the world's colliders), then the world moves the robot's links to their state and steps.
//! Without bodies (the empty scene) there is no world and nothing more to do.

use ferrobot_firmware::Link;

use crate::bases::BasePlant;
use crate::chain::ServoChain;
use crate::diff_drive::Pose;
use crate::robots::{BaseModel, SimRobot};
use crate::scene::{Scene, SceneError};
use crate::serial_line::SerialLine;
use crate::world::{ContactError, RobotContact, RobotContactRecord, World};

/// Base serial line rate, bit/s.
pub const BASE_BAUD: u32 = ferrobot_protocol::kobuki::BAUD;

/// Servo chain, base and the four one-way lines between them and the firmware.
pub struct Hardware {
    /// The servo chain.
    pub chain: ServoChain,
    /// The base, if any.
    pub base: Option<BasePlant>,
    to_servo: SerialLine,
    from_servo: SerialLine,
    to_base: SerialLine,
    from_base: SerialLine,
    world: Option<World>,
    /// The base's pose when there is no base (a pedestal): x, y (m), heading (rad).
    fixed_pose: Pose,
}

impl Hardware {
    /// The wheel speeds (left, right, m/s) the base is commanded to, as its controller holds
    /// them; zeros without a base.
    pub fn wheel_command(&self) -> (f64, f64) {
        self.base
            .as_ref()
            .map(|b| b.drive.target)
            .unwrap_or((0.0, 0.0))
    }

    /// The plants of `desc`, seeded by `seed`.
    pub fn new(desc: &SimRobot, seed: u64) -> Self {
        let base = match desc.base {
            BaseModel::Kobuki => Some(BasePlant::kobuki(seed)),
            BaseModel::Create2 => Some(BasePlant::create2(seed)),
            BaseModel::None => None,
        };
        let mut chain = ServoChain::new(&desc.servos, &desc.arm, seed);
        for m in &desc.servos {
            if let Some(s) = chain.servo_mut(m.id) {
                s.set_baud_register(desc.bus_baud);
            }
        }
        Self {
            chain,
            base,
            to_servo: SerialLine::new(desc.bus_baud),
            from_servo: SerialLine::new(desc.bus_baud),
            to_base: SerialLine::new(BASE_BAUD),
            from_base: SerialLine::new(BASE_BAUD),
            world: None,
            fixed_pose: [0.0; 3],
        }
    }

    /// The plants of `desc`, seeded by `seed`, in `scene`: the base (or the robot's root) at
    /// the scene's start pose, and the physics world when the scene has bodies. Fails when a
    /// scene body overlaps the robot at the start, naming both.
    pub fn in_scene(desc: &SimRobot, seed: u64, scene: &Scene) -> Result<Self, SceneError> {
        let mut hw = Self::new(desc, seed);
        hw.place(scene.robot_pose);
        if !scene.bodies.is_empty() {
            let theta: Vec<f64> = hw.chain.servos.iter().map(|s| s.theta).collect();
            hw.world = Some(World::new(
                scene,
                desc.body.as_ref(),
                scene.robot_pose,
                &theta,
            )?);
        }
        Ok(hw)
    }

    /// The physics world, if the scene has bodies.
    pub fn world(&self) -> Option<&World> {
        self.world.as_ref()
    }

    /// Pose of every scene body now ([`Scene::bodies`] order): the world's, or `None` without
    /// one.
    pub fn body_poses(&self) -> Option<Vec<nalgebra::Isometry3<f64>>> {
        self.world.as_ref().map(World::body_poses)
    }

    /// Every (robot link, scene body) pair in contact now ([`World::robot_contacts`]); empty
    /// without a world (a scene with no bodies has nothing to touch).
    pub fn robot_contacts(&self) -> Vec<RobotContact> {
        self.world
            .as_ref()
            .map_or_else(Vec::new, World::robot_contacts)
    }

    /// Record the contacts of the robot's `links` (URDF names) from now on, at every world
    /// step ([`World::watch_robot_contacts`]). Without a world nothing is recorded (and the
    /// names are not checked).
    ///
    /// # Errors
    ///
    /// [`ContactError::UnknownLink`] when the robot has no link of a given name.
    pub fn watch_robot_contacts<S: AsRef<str>>(&mut self, links: &[S]) -> Result<(), ContactError> {
        match self.world.as_mut() {
            Some(w) => w.watch_robot_contacts(links),
            None => Ok(()),
        }
    }

    /// What the contact watch recorded since it started or was last taken, forgotten then
    /// ([`World::take_robot_contacts`]); empty without a world or a watch.
    pub fn take_robot_contacts(&mut self) -> Vec<RobotContactRecord> {
        self.world
            .as_mut()
            .map_or_else(Vec::new, World::take_robot_contacts)
    }

    /// Stop the contact watch; what it recorded and was not yet taken
    /// ([`World::unwatch_robot_contacts`]).
    pub fn unwatch_robot_contacts(&mut self) -> Vec<RobotContactRecord> {
        self.world
            .as_mut()
            .map_or_else(Vec::new, World::unwatch_robot_contacts)
    }

    /// Step the world (with the chain and the base advanced in step with it) through `now`.
    fn run_world(&mut self, now: u64) {
        let Some(mut w) = self.world.take() else {
            return;
        };
        step_world(&mut w, &mut [self], now);
        self.world = Some(w);
    }

    /// Start the plants' clocks at `t_us` (µs) instead of zero, before anything ran: a robot
    /// that joins a world whose time has already passed ([`crate::shared`]).
    pub fn start_at(&mut self, t_us: u64) {
        self.chain.start_at(t_us);
        if let Some(b) = self.base.as_mut() {
            b.start_at(t_us);
        }
    }

    /// Move the robot, by its plants alone, to `pose` (`[x, y, θ]` in the world, m and rad):
    /// the base's true pose, or the pedestal's.
    pub fn place(&mut self, pose: Pose) {
        self.fixed_pose = pose;
        if let Some(b) = self.base.as_mut() {
            b.drive.truth = pose;
        }
    }

    /// Bytes the firmware sent on `link` at `t_us` (µs); they reach the plant when the line
    /// has clocked them out. Host bytes are not the hardware's and are ignored.
    pub fn from_firmware(&mut self, link: Link, t_us: u64, bytes: &[u8]) {
        if bytes.is_empty() {
            return;
        }
        match link {
            Link::Servo => {
                self.to_servo.send(t_us, bytes.to_vec());
            }
            Link::Base => {
                self.to_base.send(t_us, bytes.to_vec());
            }
            Link::Host => {}
        }
    }

    /// Put extra bytes on the line from the servo bus or the base to the firmware at `t_us`,
    /// as line noise would (fault injection).
    pub fn inject_to_firmware(&mut self, link: Link, t_us: u64, bytes: &[u8]) {
        match link {
            Link::Servo => {
                self.from_servo.send(t_us, bytes.to_vec());
            }
            Link::Base => {
                self.from_base.send(t_us, bytes.to_vec());
            }
            Link::Host => {}
        }
    }

    /// Run the plants' events at exactly `now` (µs): bytes that reach the servos and the base,
    /// the base's physics and feedback. Call at every event time in order (see
    /// [`Hardware::next_event`]).
    pub fn step(&mut self, now: u64) {
        self.run_world(now);
        if let Some(b) = self.to_servo.take_arrived(now) {
            for r in self.chain.on_bytes(now, &b) {
                self.from_servo.send(now + r.delay_us, r.bytes);
            }
        }
        if let Some(base) = self.base.as_mut() {
            if let Some(b) = self.to_base.take_arrived(now) {
                base.on_bytes(now, &b);
            }
            base.advance_to(now);
            let out = base.take_output();
            if !out.is_empty() {
                self.from_base.send(now, out);
            }
        }
    }

    /// Bytes that have reached the firmware on `link` by `now` (µs).
    pub fn to_firmware(&mut self, link: Link, now: u64) -> Option<Vec<u8>> {
        match link {
            Link::Servo => self.from_servo.take_arrived(now),
            Link::Base => self.from_base.take_arrived(now),
            Link::Host => None,
        }
    }

    /// The next time anything happens on a line or in the base (µs), if anything will.
    pub fn next_event(&self) -> Option<u64> {
        [
            self.to_servo.next_arrival(),
            self.from_servo.next_arrival(),
            self.to_base.next_arrival(),
            self.from_base.next_arrival(),
            self.base.as_ref().map(|b| b.next_event()),
            self.world.as_ref().map(World::next_step),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// Bytes carried so far on each line: to and from the servo bus, to and from the base.
    pub fn line_bytes(&self) -> [u64; 4] {
        [
            self.to_servo.bytes,
            self.from_servo.bytes,
            self.to_base.bytes,
            self.from_base.bytes,
        ]
    }

    /// Ground-truth pose of the base (world frame), if there is a base.
    pub fn base_truth(&self) -> Option<Pose> {
        self.base.as_ref().map(|b| b.drive.truth)
    }

    /// Pose of the robot on the floor: the base's ground truth, or the scene's start pose for
    /// a robot without a base.
    pub fn robot_pose(&self) -> Pose {
        self.base_truth().unwrap_or(self.fixed_pose)
    }
}

/// Step `world` through `now` (µs), each step with every robot's plants (`plants`, in the
/// world's robot order) advanced to it first: the servo chain, and the base among the world
/// around it (its bumper meeting the scene and the other robots).
pub fn step_world(world: &mut World, plants: &mut [&mut Hardware], now: u64) {
    while world.next_step() <= now {
        let t = world.next_step();
        let mut poses = Vec::with_capacity(plants.len());
        for (i, hw) in plants.iter_mut().enumerate() {
            hw.chain.advance_to(t);
            poses.push(match hw.base.as_mut() {
                Some(b) => {
                    b.advance_among(t, Some(&world.around(i)));
                    b.drive.truth
                }
                None => hw.fixed_pose,
            });
        }
        let mut robots: Vec<(Pose, &mut crate::chain::ServoChain)> = poses
            .into_iter()
            .zip(plants.iter_mut().map(|h| &mut h.chain))
            .collect();
        world.step_robots(&mut robots);
    }
}
