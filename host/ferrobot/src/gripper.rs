//! The gripper: open, close, state. The firmware's state machine does the work (closing in PWM
//! mode until fully closed or an object is held, as the LoCoBot driver does).

use std::time::Duration;

use ferrobot_protocol::{GripperCommand, GripperState, HostMsg};

use crate::error::Result;
use crate::motion::{Goal, Motion};
use crate::robot::Robot;

/// How long open and close may take.
pub const GRIPPER_TIMEOUT: Duration = Duration::from_secs(5);

/// The gripper of a [`Robot`].
pub struct Gripper<'r> {
    robot: &'r mut Robot,
}

impl<'r> Gripper<'r> {
    pub(crate) fn new(robot: &'r mut Robot) -> Self {
        Gripper { robot }
    }

    /// Start opening.
    pub fn open_async(&mut self) -> Result<Motion<'_>> {
        self.robot
            .link
            .command(&HostMsg::Gripper(GripperCommand::Open), "gripper open")?;
        Ok(Motion::new(
            self.robot,
            Goal::Gripper(&[GripperState::Open]),
            "gripper open",
            GRIPPER_TIMEOUT,
        ))
    }

    /// Start closing; it finishes fully closed or holding an object.
    pub fn close_async(&mut self) -> Result<Motion<'_>> {
        self.robot
            .link
            .command(&HostMsg::Gripper(GripperCommand::Close), "gripper close")?;
        Ok(Motion::new(
            self.robot,
            Goal::Gripper(&[GripperState::Closed, GripperState::Holding]),
            "gripper close",
            GRIPPER_TIMEOUT,
        ))
    }

    /// Open and wait until open.
    pub fn open(&mut self) -> Result<()> {
        self.open_async()?.wait()
    }

    /// Close and wait until fully closed or holding an object; returns which.
    pub fn close(&mut self) -> Result<GripperState> {
        self.close_async()?.wait()?;
        self.get_state()
    }

    /// Back to the open state (PyRobot's `reset`).
    pub fn reset(&mut self) -> Result<()> {
        self.open()
    }

    /// Current state: open, closing, holding an object, fully closed (or unknown/opening).
    pub fn get_state(&mut self) -> Result<GripperState> {
        Ok(self.robot.link.telemetry()?.gripper)
    }
}
