//! Robots in one world on one clock: each robot's firmware core and plants (a
//! [`LockstepSim`] without a world of its own), one physics [`World`] holding every robot's
//! links and the scene's bodies, and each robot's host end ([`HostEnd`]). A robot's bumper
//! meets the other robots' links, its gripper takes what another pushed, and its camera sees
//! the others ([`Truth::others`]).
//!
//! Time passes for all robots together: a host that waits for its robot ([`Seat`], a
//! [`HostSide`]) lets every robot's time pass, and every host's heartbeats are fed on the
//! way, as each robot's own I/O thread would. Deterministic for the robots' seeds and the
//! order they join.

use std::ops::DerefMut;
use std::sync::Arc;

use ferrobot_firmware::config::RobotProfile;

use crate::diff_drive::Pose;
use crate::hardware::{step_world, Hardware};
use crate::lockstep::{HostEnd, HostSide, LockstepSim, OtherRobot, Truth, KEEPALIVE_US};
use crate::robots::SimRobot;
use crate::scene::{Scene, SceneError};
use crate::world::World;

/// Robots in one world on one clock (see the module documentation).
pub struct SharedSim {
    now: u64,
    scene: Arc<Scene>,
    world: World,
    stations: Vec<LockstepSim>,
}

impl SharedSim {
    /// The world of `scene`, no robot in it yet.
    pub fn new(scene: Arc<Scene>) -> SharedSim {
        SharedSim {
            now: 0,
            world: World::of_scene(&scene),
            scene,
            stations: Vec::new(),
        }
    }

    /// Place the robot `desc` (its firmware running `profile`, its plants seeded by `seed`)
    /// at `pose` (`[x, y, θ]` in the world, m and rad) now; its index. Its firmware and plants
    /// start at the current time. Fails, and places nothing, when a scene body or another
    /// robot overlaps it.
    pub fn join(
        &mut self,
        desc: SimRobot,
        profile: RobotProfile,
        seed: u64,
        pose: Pose,
    ) -> Result<usize, SceneError> {
        let mut hw = Hardware::new(&desc, seed);
        hw.place(pose);
        hw.start_at(self.world.time_us());
        let theta: Vec<f64> = hw.chain.servos.iter().map(|s| s.theta).collect();
        let i = self
            .world
            .add_robot(&self.scene, desc.body.as_ref(), pose, &theta)?;
        let sim = LockstepSim::assemble_at(hw, desc, profile, self.scene.clone(), self.now);
        self.stations.push(sim);
        Ok(i)
    }

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.now
    }

    /// The scene.
    pub fn scene(&self) -> &Arc<Scene> {
        &self.scene
    }

    /// The physics world.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The robots that joined.
    pub fn robots(&self) -> usize {
        self.stations.len()
    }

    /// Robot `i`'s firmware and plants (fault injection; its clock is the floor's).
    pub fn station_mut(&mut self, i: usize) -> Option<&mut LockstepSim> {
        self.stations.get_mut(i)
    }

    /// Robot `i`'s firmware and plants.
    pub fn station(&self, i: usize) -> Option<&LockstepSim> {
        self.stations.get(i)
    }

    /// The world's ground truth as robot `i` has it: its root, joints and links, the scene's
    /// bodies, and the other robots ([`Truth::others`]).
    pub fn truth(&self, i: usize) -> Option<Truth> {
        let s = self.stations.get(i)?;
        let mut t = s.truth();
        t.bodies = self.world.body_poses();
        t.others = self
            .stations
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .filter_map(|(_, o)| {
                let body = o.body()?.clone();
                let links = o.truth().links;
                Some(OtherRobot { body, links })
            })
            .collect();
        Some(t)
    }

    /// Run every robot until `t_end` (µs): at each instant something happens, the world's
    /// steps due (every robot's plants advanced to each), then each robot's events.
    pub fn run_until(&mut self, t_end: u64) {
        loop {
            if self.world.next_step() <= self.now {
                let mut plants: Vec<&mut Hardware> =
                    self.stations.iter_mut().map(|s| &mut s.hw).collect();
                step_world(&mut self.world, &mut plants, self.now);
            }
            for s in &mut self.stations {
                s.set_now(self.now);
                s.events_now();
            }
            if self.now >= t_end {
                break;
            }
            let next = self
                .stations
                .iter()
                .map(LockstepSim::next_event)
                .fold(self.world.next_step(), u64::min);
            self.now = next.max(self.now + 1).min(t_end);
        }
        for s in &mut self.stations {
            s.hw.chain.advance_to(self.now);
        }
    }

    /// Run every robot for `dt_us` (µs).
    pub fn run_for(&mut self, dt_us: u64) {
        self.run_until(self.now + dt_us);
    }
}

/// A [`SharedSim`] with each robot's host end: what the API's links share.
pub struct SharedHosts {
    /// The robots and their world.
    pub sim: SharedSim,
    ends: Vec<HostEnd>,
}

impl SharedHosts {
    /// The world of `scene`, no robot in it yet.
    pub fn new(scene: Arc<Scene>) -> SharedHosts {
        SharedHosts {
            sim: SharedSim::new(scene),
            ends: Vec::new(),
        }
    }

    /// Place a robot ([`SharedSim::join`]) with a host end opened now; its index. No
    /// handshake yet (its [`Seat`]'s [`HostSide::handshake`]).
    pub fn join(
        &mut self,
        desc: SimRobot,
        profile: RobotProfile,
        seed: u64,
        pose: Pose,
    ) -> Result<usize, SceneError> {
        let i = self.sim.join(desc, profile, seed, pose)?;
        self.ends.push(HostEnd::opened_at(self.sim.now_us()));
        Ok(i)
    }

    /// Robot `i`'s host, if it joined.
    pub fn seat(&mut self, i: usize) -> Option<Seat<&mut SharedHosts>> {
        Seat::new(self, i)
    }

    /// Run every robot for `dt_us`, every host's heartbeats fed, what each firmware sent
    /// routed to its host.
    pub fn step(&mut self, dt_us: u64) {
        let end = self.sim.now_us() + dt_us;
        while self.sim.now_us() < end {
            let now = self.sim.now_us();
            for (i, e) in self.ends.iter_mut().enumerate() {
                if let Some(b) = e.heartbeat(now) {
                    if let Some(s) = self.sim.station_mut(i) {
                        s.write_host(&b);
                    }
                }
            }
            let chunk = if self.ends.iter().any(|e| e.keepalive) {
                KEEPALIVE_US.min(end - now)
            } else {
                end - now
            };
            self.sim.run_for(chunk);
            self.pump();
        }
    }

    /// Route what each firmware sent to its host.
    pub fn pump(&mut self) {
        for (i, e) in self.ends.iter_mut().enumerate() {
            if let Some(s) = self.sim.station_mut(i) {
                e.absorb(&s.take_host_output());
            }
        }
    }
}

/// Robot `i`'s host among the others ([`SharedHosts::seat`], or [`Seat::new`] through a
/// lock's guard): its waits pass every robot's time.
pub struct Seat<H> {
    hosts: H,
    i: usize,
}

impl<H: DerefMut<Target = SharedHosts>> Seat<H> {
    /// Robot `i`'s host on `hosts`, if it joined.
    pub fn new(hosts: H, i: usize) -> Option<Seat<H>> {
        (i < hosts.ends.len()).then_some(Seat { hosts, i })
    }

    /// The robots and their world.
    pub fn hosts(&mut self) -> &mut SharedHosts {
        &mut self.hosts
    }

    /// Which robot this is.
    pub fn index(&self) -> usize {
        self.i
    }
}

impl<H: DerefMut<Target = SharedHosts>> HostSide for Seat<H> {
    fn end(&mut self) -> &mut HostEnd {
        // In range: checked when the seat was made, and robots never leave.
        &mut self.hosts.ends[self.i]
    }

    fn now_us(&self) -> u64 {
        self.hosts.sim.now_us()
    }

    fn write_host(&mut self, bytes: &[u8]) {
        if let Some(s) = self.hosts.sim.station_mut(self.i) {
            s.write_host(bytes);
        }
    }

    fn step(&mut self, dt_us: u64) {
        self.hosts.step(dt_us);
    }

    fn pump(&mut self) {
        self.hosts.pump();
    }
}
