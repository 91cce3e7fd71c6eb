//! The gripper: open, close, state. The firmware's state machine does the work (closing in PWM
//! mode until fully closed or an object is held, as the LoCoBot driver does).

use std::time::Duration;

use ferrobot_protocol::{GripperCommand, GripperState, HostMsg};

use crate::backend::Link;
use crate::error::Result;
use crate::goals::{Claim, Goal, Step};
use crate::hub::Hub;
use crate::motion::Motion;
use crate::robot::Robot;

/// How long open and close may take.
pub const GRIPPER_TIMEOUT: Duration = Duration::from_secs(5);

/// The goal of the gripper's state machine reaching one of some states.
struct GripperGoal(&'static [GripperState]);

impl Goal for GripperGoal {
    fn claim(&self) -> Claim {
        Claim {
            gripper: true,
            ..Claim::default()
        }
    }

    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>> {
        self.0.contains(&s.telemetry.gripper).then_some(Ok(()))
    }

    /// The firmware's state machine finishes what it started.
    fn halt(&mut self, _link: &mut dyn Link) {}
}

/// The gripper of a [`Robot`]: a handle (clone of the robot's).
#[derive(Clone, Debug)]
pub struct Gripper {
    robot: Robot,
}

impl Gripper {
    pub(crate) fn new(robot: Robot) -> Self {
        Gripper { robot }
    }

    /// Send `cmd` and put the goal of reaching one of `want` under way.
    fn start(
        &self,
        cmd: GripperCommand,
        want: &'static [GripperState],
        what: &str,
    ) -> Result<Motion> {
        let claim = Claim {
            gripper: true,
            ..Claim::default()
        };
        self.robot.start_motion(claim, what, |io: &mut Hub| {
            io.link.command(&HostMsg::Gripper(cmd), what)?;
            Ok((
                Box::new(GripperGoal(want)) as Box<dyn Goal>,
                GRIPPER_TIMEOUT,
            ))
        })
    }

    /// Start opening.
    pub fn open_async(&self) -> Result<Motion> {
        self.start(GripperCommand::Open, &[GripperState::Open], "gripper open")
    }

    /// Start closing; it finishes fully closed or holding an object.
    pub fn close_async(&self) -> Result<Motion> {
        self.start(
            GripperCommand::Close,
            &[GripperState::Closed, GripperState::Holding],
            "gripper close",
        )
    }

    /// Open and wait until open.
    pub fn open(&self) -> Result<()> {
        self.open_async()?.wait()
    }

    /// Close and wait until fully closed or holding an object; returns which.
    pub fn close(&self) -> Result<GripperState> {
        self.close_async()?.wait()?;
        self.get_state()
    }

    /// Back to the open state (PyRobot's `reset`).
    pub fn reset(&self) -> Result<()> {
        self.open()
    }

    /// Current state: open, closing, holding an object, fully closed (or unknown/opening).
    pub fn get_state(&self) -> Result<GripperState> {
        Ok(self.robot.telemetry()?.gripper)
    }
}
