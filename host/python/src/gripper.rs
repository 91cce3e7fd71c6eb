//! `bot.gripper`: PyRobot's gripper.

use ferrobot::GripperState;
use pyo3::prelude::*;

use crate::convert::truthy;

use crate::arm::finish;
use crate::errors::OrRaise;

/// The gripper: PyRobot's `Gripper`.
#[pyclass(frozen, module = "ferrobot._native")]
pub struct Gripper {
    gripper: ferrobot::gripper::Gripper,
    robot: ferrobot::Robot,
}

impl Gripper {
    /// The gripper of `robot`.
    pub fn new(gripper: ferrobot::gripper::Gripper, robot: ferrobot::Robot) -> Self {
        Gripper { gripper, robot }
    }
}

/// PyRobot's gripper state codes ([`GripperState::pyrobot_code`]).
pub fn state_code(s: GripperState) -> i32 {
    i32::from(s.pyrobot_code())
}

#[pymethods]
impl Gripper {
    /// Open the gripper; with `wait`, until it is open (True), else a `Motion`.
    #[pyo3(signature = (wait=true))]
    fn open(
        &self,
        py: Python<'_>,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let m = py.detach(|| self.gripper.open_async()).py()?;
        finish(py, &self.robot, "gripper opening", m, wait)
    }

    /// Close the gripper; with `wait`, until it holds something or is closed (True), else a
    /// `Motion`.
    #[pyo3(signature = (wait=true))]
    fn close(
        &self,
        py: Python<'_>,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let m = py.detach(|| self.gripper.close_async()).py()?;
        finish(py, &self.robot, "gripper closing", m, wait)
    }

    /// Open, close and open again (PyRobot's reset).
    #[pyo3(signature = (wait=true))]
    fn reset(&self, py: Python<'_>, #[pyo3(from_py_with = truthy)] wait: bool) -> PyResult<bool> {
        let _ = wait;
        let g = self.gripper.clone();
        crate::motion::blocking(py, &self.robot, move || g.reset())?;
        Ok(true)
    }

    /// PyRobot's state code: -1 unknown, 0 open, 1 closing, 2 holding an object, 3 fully
    /// closed, 4 opening.
    fn get_gripper_state(&self, py: Python<'_>) -> PyResult<i32> {
        Ok(state_code(py.detach(|| self.gripper.get_state()).py()?))
    }

    fn __repr__(&self) -> String {
        format!("<ferrobot.Gripper of {:?}>", self.robot.name())
    }
}
