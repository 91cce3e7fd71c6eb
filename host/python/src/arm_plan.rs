//! `bot.arm`'s planning: plans made without moving (`make_plan_joint_positions`,
//! `make_plan_pose`) and run later, and the planning scene with the signatures of PyRobot's
//! `MoveitObjectHandler` (poses `[x, y, z, qx, qy, qz, qw]` or `[x, y, z, roll, pitch, yaw]`).

use ferrobot::arm::Orientation;
use ferrobot::arm_plan::ArmTrajectory;
use pyo3::prelude::*;

use crate::convert::truthy;
use pyo3::types::{PyDict, PyTuple};

use crate::arm::{finish, orientation, Arm};
use crate::convert::{self, array, vector};
use crate::errors::{invalid, OrRaise};

/// A planned arm motion, made without moving: its collision-free path and time-optimal
/// trajectory. Iterating gives the path's waypoints (rad), as PyRobot's plans did:
/// `for q in plan: bot.arm.set_joint_positions(q, plan=False)`; `bot.arm.execute_plan(plan)`
/// runs the trajectory itself.
#[pyclass(frozen, module = "ferrobot._native")]
pub struct Plan {
    pub(crate) plan: ArmTrajectory,
}

#[pymethods]
impl Plan {
    /// The joints' names, in the order of every configuration.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.plan.joints.clone()
    }

    /// The path's waypoints, rad: `(k, dof)`.
    #[getter]
    fn path<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let k = self.plan.path.len();
        let dof = self.plan.joints.len();
        convert::shaped(py, self.plan.path.concat(), &[k, dof])
    }

    /// The trajectory's duration, s.
    #[getter]
    fn duration(&self) -> f64 {
        self.plan.duration()
    }

    /// Time spent planning, s.
    #[getter]
    fn planning_time(&self) -> f64 {
        self.plan.planning_time.as_secs_f64()
    }

    /// The trajectory sampled every `dt` s: `(times (n,), positions (n, dof), velocities
    /// (n, dof))`.
    #[pyo3(signature = (dt=0.01))]
    fn sample<'py>(&self, py: Python<'py>, dt: f64) -> PyResult<Bound<'py, PyTuple>> {
        let max = ferrobot::validate::MAX_DURATION_S;
        if !(dt > 0.0 && dt <= max) {
            return Err(invalid(
                py,
                "dt",
                &format!("seconds in (0, {max}]"),
                format!("{dt}"),
            ));
        }
        let s = self.plan.trajectory.samples(dt);
        let dof = self.plan.joints.len();
        let times: Vec<f64> = s.iter().map(|p| p.time).collect();
        let q: Vec<f64> = s.iter().flat_map(|p| p.position.iter().copied()).collect();
        let qd: Vec<f64> = s.iter().flat_map(|p| p.velocity.iter().copied()).collect();
        PyTuple::new(
            py,
            [
                convert::vec1(py, times),
                convert::shaped(py, q, &[s.len(), dof])?,
                convert::shaped(py, qd, &[s.len(), dof])?,
            ],
        )
    }

    fn __len__(&self) -> usize {
        self.plan.path.len()
    }

    fn __getitem__<'py>(&self, py: Python<'py>, i: isize) -> PyResult<Bound<'py, PyAny>> {
        let n = self.plan.path.len() as isize;
        let j = if i < 0 { i + n } else { i };
        if !(0..n).contains(&j) {
            return Err(pyo3::exceptions::PyIndexError::new_err(format!(
                "waypoint {i} of a path of {n}"
            )));
        }
        Ok(convert::vec1(py, self.plan.path[j as usize].clone()))
    }

    fn __repr__(&self) -> String {
        format!(
            "<ferrobot.Plan of {} waypoints, {:.2} s>",
            self.plan.path.len(),
            self.plan.duration()
        )
    }
}

/// A pose as PyRobot's `MoveitObjectHandler` takes it: 7 numbers `[x, y, z, qx, qy, qz, qw]`
/// or 6 `[x, y, z, roll, pitch, yaw]` (`R = Rz(yaw) Ry(pitch) Rx(roll)`).
fn object_pose(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<([f64; 3], Orientation)> {
    let v = vector(obj, what, None)?;
    match v.len() {
        7 => Ok((
            [v[0], v[1], v[2]],
            Orientation::Quaternion([v[3], v[4], v[5], v[6]]),
        )),
        6 => Ok((
            [v[0], v[1], v[2]],
            Orientation::YawPitchRoll([v[5], v[4], v[3]]),
        )),
        n => Err(invalid(
            obj.py(),
            what,
            "[x, y, z, qx, qy, qz, qw] or [x, y, z, roll, pitch, yaw]",
            format!("{n} numbers"),
        )),
    }
}

#[pymethods]
impl Arm {
    /// Plan a collision-free, time-optimal motion from the joints now to `positions` (rad)
    /// without moving: a `Plan`.
    #[pyo3(signature = (positions, **kwargs))]
    fn make_plan_joint_positions(
        &self,
        py: Python<'_>,
        positions: &Bound<'_, PyAny>,
        #[allow(unused_variables)] kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Plan> {
        let q = vector(positions, "positions", None)?;
        let plan = py.detach(|| self.arm.make_plan_joint_positions(&q)).py()?;
        Ok(Plan { plan })
    }

    /// Plan to a pose (`position` m, `orientation` as `set_ee_pose` takes it) without moving:
    /// a `Plan`.
    #[pyo3(signature = (position, orientation, wait=true, numerical=true, **kwargs))]
    fn make_plan_pose(
        &self,
        py: Python<'_>,
        position: &Bound<'_, PyAny>,
        orientation: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = truthy)] wait: bool,
        #[pyo3(from_py_with = truthy)] numerical: bool,
        #[allow(unused_variables)] kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Plan> {
        let _ = (wait, numerical);
        let p = array::<3>(position, "position")?;
        let o = self::orientation(orientation, "orientation")?;
        let plan = py.detach(|| self.arm.make_plan_pose(p, o)).py()?;
        Ok(Plan { plan })
    }

    /// Run a `Plan` (refused as `StalePlan` when the arm has moved away from its start or
    /// the scene has changed across it). True when done, or a `Motion` with `wait=False`.
    #[pyo3(signature = (plan, wait=true))]
    fn execute_plan(
        &self,
        py: Python<'_>,
        plan: &Plan,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let m = py.detach(|| self.arm.execute(&plan.plan)).py()?;
        finish(py, &self.robot, "planned arm motion", m, wait)
    }

    /// Add a box `id_name` of `size` (m) at `pose` (the box's centre, in the arm's base
    /// frame) to the planning scene.
    #[pyo3(signature = (id_name, pose, size, frame=None))]
    fn add_world_object(
        &self,
        py: Python<'_>,
        id_name: &str,
        pose: &Bound<'_, PyAny>,
        size: &Bound<'_, PyAny>,
        frame: Option<&str>,
    ) -> PyResult<()> {
        self.check_frame(py, frame)?;
        let (p, o) = object_pose(pose, "pose")?;
        let s = array::<3>(size, "size")?;
        py.detach(|| self.arm.add_world_object(id_name, p, o, s))
            .py()
    }

    /// A table: the box `"table"` (`add_world_object("table", pose, size)`).
    fn add_table(
        &self,
        py: Python<'_>,
        pose: &Bound<'_, PyAny>,
        size: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        self.add_world_object(py, "table", pose, size, None)
    }

    /// Remove object `id_name` from the planning scene.
    fn remove_world_object(&self, py: Python<'_>, id_name: &str) -> PyResult<()> {
        py.detach(|| self.arm.remove_world_object(id_name)).py()
    }

    /// Attach a box `id_name` of `size` (m) to the end effector `link_name` at `pose` (in
    /// the end effector's frame): it moves with the gripper and may touch it.
    fn attach_arm_object(
        &self,
        py: Python<'_>,
        link_name: &str,
        id_name: &str,
        pose: &Bound<'_, PyAny>,
        size: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        self.check_link(py, link_name)?;
        let (p, o) = object_pose(pose, "pose")?;
        let s = array::<3>(size, "size")?;
        py.detach(|| self.arm.attach_arm_object(id_name, p, o, s))
            .py()
    }

    /// Detach object `id_name` from the end effector `link_name`; it is removed from the
    /// scene too when `remove_from_world`, else left where it is.
    #[pyo3(signature = (link_name, id_name, remove_from_world=true))]
    fn detach_arm_object(
        &self,
        py: Python<'_>,
        link_name: &str,
        id_name: &str,
        #[pyo3(from_py_with = truthy)] remove_from_world: bool,
    ) -> PyResult<()> {
        self.check_link(py, link_name)?;
        if remove_from_world {
            py.detach(|| self.arm.detach_arm_object(id_name)).py()
        } else {
            py.detach(|| self.arm.release_arm_object(id_name)).py()
        }
    }

    /// Remove every object from the planning scene.
    fn remove_all_objects(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| self.arm.remove_all_objects()).py()
    }

    /// Add the simulated scene's objects to the planning scene; returns how many.
    fn add_scene_objects(&self, py: Python<'_>) -> PyResult<usize> {
        py.detach(|| self.arm.add_scene_objects()).py()
    }

    /// Whether the arm, at its measured joints, touches the planning scene or itself.
    fn get_collision_state(&self, py: Python<'_>) -> PyResult<bool> {
        Ok(py.detach(|| self.arm.get_collision_state()).py()?.is_some())
    }

    /// The contact `get_collision_state` found: `(body, body)`, or `None`.
    fn get_collision_contact(&self, py: Python<'_>) -> PyResult<Option<(String, String)>> {
        let c = py.detach(|| self.arm.get_collision_state()).py()?;
        Ok(c.map(|c| (c.a, c.b)))
    }
}

impl Arm {
    /// A planning-scene pose's frame: the arm's base frame (PyRobot's ROS names may have a
    /// leading `/`).
    fn check_frame(&self, py: Python<'_>, frame: Option<&str>) -> PyResult<()> {
        let Some(f) = frame else { return Ok(()) };
        let what = "planning-scene poses are in the arm's base frame";
        self.expect_frame(py, f.trim_start_matches('/'), self.base_frame(), what)
    }

    /// An attached object's link: the end effector.
    fn check_link(&self, py: Python<'_>, link: &str) -> PyResult<()> {
        let what = "objects are attached to the end effector";
        self.expect_frame(py, link.trim_start_matches('/'), self.ee_frame(), what)
    }
}
