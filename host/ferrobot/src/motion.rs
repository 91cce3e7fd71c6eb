//! [`Motion`], the owned handle to a goal under way (poll, wait, cancel). Every blocking call
//! of the API is its non-blocking form followed by [`Motion::wait`].
//!
//! A motion does not borrow the robot: it holds a clone of the [`Robot`] handle and the number
//! of its goal. Whoever lets time pass (any motion's `poll` or `wait`, [`Robot::wait`]) steps
//! every goal under way, so the arm, the gripper, the head and the base move at the same time,
//! whichever of them a program waits on.

use crate::error::Result;
pub use crate::goals::{
    ARRIVAL_SPEED, FAULT_QUEUE, LINK_EVENT_QUEUE, POLL, STALL_GRACE, STALL_LAG, STALL_PROGRESS,
    STALL_TIME,
};
use crate::robot::Robot;

/// A motion under way: an owned handle to poll, wait on or cancel. It does not borrow the
/// robot; other motions (of other components) and other threads go on meanwhile. Dropping it
/// lets the motion run on, unobserved.
#[must_use = "a dropped motion runs on unobserved: wait on it, poll it or cancel it"]
pub struct Motion {
    robot: Robot,
    id: u64,
    result: Option<Result<()>>,
    /// The result has been handed out or the goal cancelled: nothing to detach on drop.
    done: bool,
}

impl std::fmt::Debug for Motion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Motion")
            .field("id", &self.id)
            .field("result", &self.result)
            .finish()
    }
}

impl Motion {
    pub(crate) fn new(robot: Robot, id: u64) -> Self {
        Motion {
            robot,
            id,
            result: None,
            done: false,
        }
    }

    /// Whether it has finished (successfully or not), as of the last time anyone let time
    /// pass.
    pub fn is_finished(&self) -> bool {
        self.result.is_some() || !self.robot.lock_hub().goals.is_running(self.id)
    }

    /// Let [`POLL`] pass (stepping every motion under way) and check; `Some(result)` once
    /// finished. A motion that has already finished returns at once.
    pub fn poll(&mut self) -> Option<&Result<()>> {
        if self.result.is_none() && !self.done {
            let cfg = self.robot.cfg();
            let mut io = self.robot.lock_hub();
            self.result = io.goals.take(self.id);
            if self.result.is_none() {
                io.pump(cfg, POLL);
                self.result = io.goals.take(self.id);
            }
            // Hand the link to a thread that is waiting for it; a simulator paced to the wall
            // clock waits for it without the lock.
            let rest = io.link.pace();
            parking_lot::MutexGuard::unlock_fair(io);
            self.robot.step_neighbours();
            if !rest.is_zero() {
                std::thread::sleep(rest);
            }
        }
        self.result.as_ref()
    }

    /// Block until finished; the result says why it ended.
    pub fn wait(mut self) -> Result<()> {
        // Check first: a motion may be finished before any time passes.
        if self.result.is_none() {
            let cfg = self.robot.cfg();
            let mut io = self.robot.lock_hub();
            io.step(cfg);
            self.result = io.goals.take(self.id);
        }
        loop {
            if let Some(r) = self.result.take() {
                self.done = true;
                return r;
            }
            self.poll();
        }
    }

    /// Stop the motion where it is: joints hold, the base stops. The other motions under way
    /// run on.
    pub fn cancel(mut self) -> Result<()> {
        self.robot.lock_hub().cancel(self.id);
        self.done = true;
        Ok(())
    }
}

impl Drop for Motion {
    fn drop(&mut self) {
        if !self.done && self.result.is_none() {
            self.robot.lock_hub().goals.detach(self.id);
        }
    }
}
