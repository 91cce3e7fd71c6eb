//! A simulated world several robots share (cargo feature `sim`): one scene, one physics
//! world, one clock ([`ferrobot_sim::shared`]). Robots join it with
//! [`RobotBuilder::shared_world`](crate::RobotBuilder::shared_world); each is a [`Robot`](crate::Robot) of
//! its own, driven by the same API, and what one does the others meet: its bumper stops
//! against them, their cameras see it.
//!
//! ```
//! # fn main() -> ferrobot::Result<()> {
//! let world = ferrobot::SharedWorld::new("empty")?;
//! let a = ferrobot::Robot::builder("locobot").shared_world(&world).start_pose([0.0, 0.0, 0.0]).build()?;
//! let b = ferrobot::Robot::builder("locobot").shared_world(&world).start_pose([2.0, 0.0, 3.14]).build()?;
//! a.base()?.set_vel(0.2, 0.0, 1.0)?; // B's time passes too
//! assert_eq!(world.robots(), 2);
//! assert!((a.time() - b.time()).abs() < 1e-9);
//! # Ok(())
//! # }
//! ```
//!
//! Time passes only while a robot waits (or, on [`Backend::Sim`](crate::Backend::Sim) with
//! `realtime`, paced to the wall clock): every robot's firmware and plants run together, and
//! each robot's host keeps its firmware's watchdog fed as its own I/O thread would.
//! [`Robot::simulator`](crate::Robot::simulator) is `None` for a robot in a shared world;
//! [`SharedWorld::simulator`] reaches every robot's.

use std::sync::{Arc, Weak};
use std::time::Duration;

use ferrobot_sim::scene::{Scene, SceneSource};
use ferrobot_sim::shared::SharedHosts;
use parking_lot::{Mutex, MutexGuard};

use crate::error::Result;
use crate::robot::Inner;

/// A simulated world several robots share (see the module documentation). Cloning it gives
/// another handle on the same world.
#[derive(Clone)]
pub struct SharedWorld {
    pub(crate) hosts: Arc<Mutex<SharedHosts>>,
    /// The robots built in it, to step each other's motions ([`SharedWorld::step_others`]).
    members: Arc<Mutex<Vec<Weak<Inner>>>>,
}

impl std::fmt::Debug for SharedWorld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let h = self.hosts.lock();
        f.debug_struct("SharedWorld")
            .field("scene", &h.sim.scene().name)
            .field("robots", &h.sim.robots())
            .field("time_us", &h.sim.now_us())
            .finish()
    }
}

impl SharedWorld {
    /// A world of a bundled scene (`empty`, `tabletop`, `apartment`, `shelf`, `clutter`) or
    /// a scene file, no robot in it yet.
    pub fn new(scene: &str) -> Result<SharedWorld> {
        Ok(SharedWorld::with_scene(Scene::load(
            &SceneSource::from_arg(scene),
        )?))
    }

    /// A world of a scene already loaded (and perhaps changed), no robot in it yet.
    pub fn with_scene(scene: Scene) -> SharedWorld {
        SharedWorld {
            hosts: Arc::new(Mutex::new(SharedHosts::new(Arc::new(scene)))),
            members: Arc::default(),
        }
    }

    /// The scene.
    pub fn scene(&self) -> Arc<Scene> {
        self.hosts.lock().sim.scene().clone()
    }

    /// The robots that joined, in the order they joined.
    pub fn robots(&self) -> usize {
        self.hosts.lock().sim.robots()
    }

    /// The world's time, s.
    pub fn time(&self) -> f64 {
        self.hosts.lock().sim.now_us() as f64 * 1e-6
    }

    /// The world's ground truth as robot `i` (in joining order) has it, the other robots in
    /// [`ferrobot_sim::lockstep::Truth::others`]; `None` for a robot that did not join.
    pub fn truth(&self, i: usize) -> Option<ferrobot_sim::lockstep::Truth> {
        self.hosts.lock().sim.truth(i)
    }

    /// The simulator itself (every robot's firmware and plants, the physics world), for
    /// fault injection. The guard holds the world: drop it before calling a robot in it.
    pub fn simulator(&self) -> MutexGuard<'_, SharedHosts> {
        self.hosts.lock()
    }

    /// A robot built in this world, from now on stepped by the others' waits.
    pub(crate) fn admit(&self, robot: &Arc<Inner>) {
        let mut m = self.members.lock();
        m.retain(|w| w.strong_count() > 0);
        m.push(Arc::downgrade(robot));
    }

    /// Step every robot's motions but `me`'s at the world's present instant, taking in what
    /// its firmware sent (its streams flow, its closed-loop goals send their next commands),
    /// as its own wait would, without letting time pass. A robot whose link another thread
    /// holds is left to that thread.
    pub(crate) fn step_others(&self, me: &Arc<Inner>) {
        let others: Vec<Arc<Inner>> = self
            .members
            .lock()
            .iter()
            .filter_map(Weak::upgrade)
            .filter(|r| !Arc::ptr_eq(r, me))
            .collect();
        for r in others {
            if let Some(mut io) = r.io.try_lock() {
                io.pump(&r.cfg, Duration::ZERO);
            }
        }
    }
}
