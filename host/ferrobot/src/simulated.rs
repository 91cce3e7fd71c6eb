//! What only a simulated robot has (cargo feature `sim`): the world it was built in, the
//! simulator's ground truth, and the simulator itself, through the sim backend's extension
//! ([`crate::backend::world`]).

use std::sync::Arc;

use ferrobot_sim::lockstep::Truth;
use ferrobot_sim::scene::Scene;
use ferrobot_sim::LockstepSim;
use parking_lot::{MappedMutexGuard, MutexGuard};

use crate::backend::world::{simulator_of, truth_of};
use crate::error::Result;
use crate::robot::Robot;

impl Robot {
    /// The world the robot was built in (a bundled or file scene; `empty` unless
    /// [`crate::RobotBuilder::scene`] named one), with its start pose.
    pub fn scene(&self) -> Arc<Scene> {
        self.inner.scene.clone()
    }

    /// The simulated world's ground truth now (the servos' true angles, the base's true pose,
    /// every scene body's pose in the world), on the simulator and on the emulated board; an
    /// error on hardware, which has none.
    pub fn truth(&self) -> Result<Truth> {
        truth_of(self.lock_hub().link.as_mut())
            .ok_or_else(|| self.missing("ground truth (a simulated world)"))
    }

    /// The simulator behind this robot, when it is simulated (ground truth, fault injection).
    /// The guard holds the robot's link: drop it before calling the robot again (from this
    /// thread or waiting on another).
    pub fn simulator(&self) -> Option<MappedMutexGuard<'_, LockstepSim>> {
        MutexGuard::try_map(self.lock_hub(), |io| simulator_of(io.link.as_mut())).ok()
    }
}
