//! `bot.arm`: PyRobot's arm (joint and end-effector control, kinematics). The planning scene
//! and plans are in `arm_plan.rs`.

use ferrobot::arm::{MoveOptions, Orientation, Pose};
use pyo3::prelude::*;

use crate::convert::truthy;
use pyo3::types::PyTuple;

use crate::convert::{self, array, column3, mat3, vector};
use crate::errors::{invalid, OrRaise};
use crate::motion::{blocking, Motion};

/// The arm: PyRobot's `Arm`, names and signatures kept. Angles rad, lengths m, poses in the
/// arm's base frame (`configs.ARM.ARM_BASE_FRAME`), quaternions `[x, y, z, w]`.
#[pyclass(frozen, module = "ferrobot._native")]
pub struct Arm {
    pub(crate) arm: ferrobot::arm::Arm,
    pub(crate) robot: ferrobot::Robot,
    /// PyRobot's `configs` (the robot's).
    #[pyo3(get)]
    configs: Py<PyAny>,
}

impl Arm {
    /// The arm of `robot`.
    pub fn new(arm: ferrobot::arm::Arm, robot: ferrobot::Robot, configs: Py<PyAny>) -> Self {
        Arm {
            arm,
            robot,
            configs,
        }
    }

    fn robot(&self) -> &ferrobot::Robot {
        &self.robot
    }

    /// The end effector's URDF frame (`configs.ARM.EE_FRAME`).
    pub(crate) fn ee_frame(&self) -> &str {
        self.robot.config().arm.as_ref().map_or("", |a| &a.ee_frame)
    }

    /// The arm's base frame (`configs.ARM.ARM_BASE_FRAME`).
    pub(crate) fn base_frame(&self) -> &str {
        self.robot
            .config()
            .arm
            .as_ref()
            .map_or("", |a| &a.base_frame)
    }

    /// `Usage` unless `given` is `expected`, the frame `what` must be.
    pub(crate) fn expect_frame(
        &self,
        py: Python<'_>,
        given: &str,
        expected: &str,
        what: &str,
    ) -> PyResult<()> {
        if given == expected {
            return Ok(());
        }
        Err(crate::errors::to_py(
            py,
            ferrobot::Error::Usage(format!("{what} {expected:?}, not {given:?}")),
        ))
    }

    fn joints(&self, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
        vector(obj, what, None)
    }

    /// Runs a joint move to `q`: blocking (True) or a [`Motion`].
    fn start(&self, py: Python<'_>, q: Vec<f64>, plan: bool, wait: bool) -> PyResult<Py<PyAny>> {
        let opts = MoveOptions {
            plan,
            ..MoveOptions::default()
        };
        let arm = self.arm.clone();
        let motion = py.detach(move || arm.move_joints(&q, opts)).py()?;
        finish(py, self.robot(), "arm motion", motion, wait)
    }
}

/// A started motion, waited on (`True`) or handed back (`wait=False`).
pub fn finish(
    py: Python<'_>,
    robot: &ferrobot::Robot,
    what: &str,
    motion: ferrobot::Motion,
    wait: bool,
) -> PyResult<Py<PyAny>> {
    let m = Py::new(py, Motion::new(robot, what, motion))?;
    if wait {
        m.get().wait_blocking(py)?;
        Ok(true.into_pyobject(py)?.to_owned().into_any().unbind())
    } else {
        Ok(m.into_any())
    }
}

/// An orientation as PyRobot takes it: a 3x3 rotation matrix (9 numbers), Euler angles
/// `[yaw, pitch, roll]` (3; `R = Rz(yaw) Ry(pitch) Rx(roll)`), or a quaternion `[x, y, z, w]` (4).
pub fn orientation(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Orientation> {
    let n = convert::numbers(obj, what)?;
    let d = n.data;
    let long = n.shape.iter().filter(|&&s| s != 1).count();
    match d.len() {
        9 if n.shape == [3, 3] || long == 1 => Ok(Orientation::Matrix([
            [d[0], d[1], d[2]],
            [d[3], d[4], d[5]],
            [d[6], d[7], d[8]],
        ])),
        3 if long <= 1 => Ok(Orientation::YawPitchRoll([d[0], d[1], d[2]])),
        4 if long <= 1 => Ok(Orientation::Quaternion([d[0], d[1], d[2], d[3]])),
        _ => Err(invalid(
            obj.py(),
            what,
            "a 3x3 rotation matrix, [yaw, pitch, roll] or a quaternion [x, y, z, w]",
            format!("{} numbers of shape {:?}", d.len(), n.shape),
        )),
    }
}

/// A pose as PyRobot returns it: `(trans (3, 1), rot (3, 3), quat (4,) [x, y, z, w])`, the
/// quaternion with `w >= 0`.
pub fn pose_tuple<'py>(py: Python<'py>, p: &Pose) -> PyResult<Bound<'py, PyTuple>> {
    let mut q = p.quaternion;
    if q[3] < 0.0 {
        q = q.map(|c| -c);
    }
    PyTuple::new(
        py,
        [
            column3(py, p.position)?,
            mat3(py, p.rotation)?,
            convert::vec1(py, q.to_vec()),
        ],
    )
}

#[pymethods]
impl Arm {
    /// The arm's joint names, base to tip.
    #[getter]
    fn arm_joint_names(&self) -> Vec<String> {
        self.arm.joint_names()
    }

    /// The number of the arm's joints.
    #[getter]
    fn arm_dof(&self) -> usize {
        self.arm.dof()
    }

    /// Move to the home configuration (`configs.ARM.HOME`; zeros on the LoCoBot). PyRobot's
    /// `plan=False` default kept. True when arrived.
    #[pyo3(signature = (plan=false, wait=true))]
    fn go_home(
        &self,
        py: Python<'_>,
        #[pyo3(from_py_with = truthy)] plan: bool,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let home = self.robot().config().arm.as_ref().map(|a| a.home.clone());
        let home = home.unwrap_or_else(|| vec![0.0; self.arm.dof()]);
        self.start(py, home, plan, wait)
    }

    /// Fold the arm in (the description's stow pose), planned: before a long drive.
    fn stow(&self, py: Python<'_>) -> PyResult<bool> {
        let arm = self.arm.clone();
        blocking(py, self.robot(), move || arm.stow())?;
        Ok(true)
    }

    /// Move the arm out of the camera's view (the description's look pose), planned.
    fn clear_view(&self, py: Python<'_>) -> PyResult<bool> {
        let arm = self.arm.clone();
        blocking(py, self.robot(), move || arm.clear_view())?;
        Ok(true)
    }

    /// Move to joint `positions` (rad): planned around the planning scene when `plan`, else
    /// straight to them. `wait=True` returns True on arrival (an error otherwise);
    /// `wait=False` returns a `Motion`.
    #[pyo3(signature = (positions, plan=true, wait=true, **kwargs))]
    fn set_joint_positions(
        &self,
        py: Python<'_>,
        positions: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = truthy)] plan: bool,
        #[pyo3(from_py_with = truthy)] wait: bool,
        #[allow(unused_variables)] kwargs: Option<&Bound<'_, pyo3::types::PyDict>>,
    ) -> PyResult<Py<PyAny>> {
        let q = self.joints(positions, "positions")?;
        self.start(py, q, plan, wait)
    }

    /// Command joint velocities (rad/s); held until the next command.
    #[pyo3(signature = (velocities, **kwargs))]
    fn set_joint_velocities(
        &self,
        py: Python<'_>,
        velocities: &Bound<'_, PyAny>,
        #[allow(unused_variables)] kwargs: Option<&Bound<'_, pyo3::types::PyDict>>,
    ) -> PyResult<bool> {
        let v = self.joints(velocities, "velocities")?;
        py.detach(|| self.arm.set_joint_velocities(&v)).py()?;
        Ok(true)
    }

    /// Command joint torques (N m); held until the next command.
    #[pyo3(signature = (torques, **kwargs))]
    fn set_joint_torques(
        &self,
        py: Python<'_>,
        torques: &Bound<'_, PyAny>,
        #[allow(unused_variables)] kwargs: Option<&Bound<'_, pyo3::types::PyDict>>,
    ) -> PyResult<bool> {
        let t = self.joints(torques, "torques")?;
        py.detach(|| self.arm.set_joint_torques(&t)).py()?;
        Ok(true)
    }

    /// Teach mode on or off: on, the arm moves under a hand and stays where it is left (its
    /// limits held as ever); off, it holds where it is. Waits up to two seconds for the
    /// firmware to trust the arm's gravity model.
    fn set_teach_mode(&self, py: Python<'_>, on: bool) -> PyResult<bool> {
        py.detach(|| self.arm.set_teach_mode(on)).py()?;
        Ok(true)
    }

    /// Joint angles now, rad, shape `(dof,)`.
    fn get_joint_angles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let q = py.detach(|| self.arm.get_joint_angles()).py()?;
        Ok(convert::vec1(py, q))
    }

    /// Joint velocities now, rad/s, shape `(dof,)`.
    fn get_joint_velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = py.detach(|| self.arm.get_joint_velocities()).py()?;
        Ok(convert::vec1(py, v))
    }

    /// Joint torques now, N m, shape `(dof,)`.
    fn get_joint_torques<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let t = py.detach(|| self.arm.get_joint_torques()).py()?;
        Ok(convert::vec1(py, t))
    }

    /// One joint's angle, rad.
    fn get_joint_angle(&self, py: Python<'_>, joint: &str) -> PyResult<f64> {
        py.detach(|| self.arm.get_joint_angle(joint)).py()
    }

    /// One joint's velocity, rad/s.
    fn get_joint_velocity(&self, py: Python<'_>, joint: &str) -> PyResult<f64> {
        py.detach(|| self.arm.get_joint_velocity(joint)).py()
    }

    /// One joint's torque, N m.
    fn get_joint_torque(&self, py: Python<'_>, joint: &str) -> PyResult<f64> {
        py.detach(|| self.arm.get_joint_torque(joint)).py()
    }

    /// The end effector's pose in the arm's base frame: `(trans (3, 1), rot (3, 3), quat)`.
    #[getter]
    fn pose_ee<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let p = py.detach(|| self.arm.get_ee_pose()).py()?;
        pose_tuple(py, &p)
    }

    /// The end effector's pose in `base_frame` (a URDF frame): `(trans (3, 1), rot (3, 3),
    /// quat)`.
    #[pyo3(signature = (base_frame=None))]
    fn get_ee_pose<'py>(
        &self,
        py: Python<'py>,
        base_frame: Option<&str>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let ee = self.ee_frame();
        let p = match base_frame {
            None => py.detach(|| self.arm.get_ee_pose()).py()?,
            Some(f) => Pose::from(py.detach(|| self.robot().link_transform(ee, f)).py()?),
        };
        pose_tuple(py, &p)
    }

    /// Pose of `dest_frame` in `src_frame`: `(trans (3, 1), rot (3, 3), quat)`.
    fn get_transform<'py>(
        &self,
        py: Python<'py>,
        src_frame: &str,
        dest_frame: &str,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let t = py
            .detach(|| self.robot().link_transform(dest_frame, src_frame))
            .py()?;
        pose_tuple(py, &Pose::from(t))
    }

    /// Move the end effector to `position` (m) with `orientation` (3x3, `[yaw, pitch, roll]`
    /// or `[x, y, z, w]`): the collision-free IK solution nearest the joints, then a joint
    /// move (planned when `plan`). `numerical` is accepted for PyRobot's programs; the IK is
    /// the description's (numerical, or closed-form on 5-DOF arms).
    #[pyo3(signature = (position, orientation, plan=true, wait=true, numerical=true, **kwargs))]
    #[allow(clippy::too_many_arguments)]
    fn set_ee_pose(
        &self,
        py: Python<'_>,
        position: &Bound<'_, PyAny>,
        orientation: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = truthy)] plan: bool,
        #[pyo3(from_py_with = truthy)] wait: bool,
        #[pyo3(from_py_with = truthy)] numerical: bool,
        #[allow(unused_variables)] kwargs: Option<&Bound<'_, pyo3::types::PyDict>>,
    ) -> PyResult<Py<PyAny>> {
        let _ = numerical;
        let p = array::<3>(position, "position")?;
        let o = self::orientation(orientation, "orientation")?;
        let opts = MoveOptions {
            plan,
            ..MoveOptions::default()
        };
        let arm = self.arm.clone();
        let motion = py.detach(move || arm.move_to_pose(p, o, opts)).py()?;
        finish(py, self.robot(), "end-effector motion", motion, wait)
    }

    /// 5-DOF arms: move the end effector to `position` (m) with gripper `pitch` (rad below
    /// horizontal; pi/2 points down) and `roll` (rad; the current roll when `None`).
    #[pyo3(signature = (position, pitch, roll=None, plan=true, wait=true, numerical=true, **kwargs))]
    #[allow(clippy::too_many_arguments)]
    fn set_ee_pose_pitch_roll(
        &self,
        py: Python<'_>,
        position: &Bound<'_, PyAny>,
        pitch: f64,
        roll: Option<f64>,
        #[pyo3(from_py_with = truthy)] plan: bool,
        #[pyo3(from_py_with = truthy)] wait: bool,
        #[pyo3(from_py_with = truthy)] numerical: bool,
        #[allow(unused_variables)] kwargs: Option<&Bound<'_, pyo3::types::PyDict>>,
    ) -> PyResult<Py<PyAny>> {
        let _ = numerical;
        let p = array::<3>(position, "position")?;
        let arm = self.arm.clone();
        let q = py
            .detach(move || arm.compute_ik_pitch_roll(p, pitch, roll, None))
            .py()?;
        self.start(py, q, plan, wait)
    }

    /// Move the end effector along a straight line by `displacement` (m, base frame), its
    /// orientation kept, through IK solutions every `eef_step` m; the line is checked for
    /// collisions and joint jumps first when `plan`. True when done.
    #[pyo3(signature = (displacement, eef_step=0.005, numerical=true, plan=true, **kwargs))]
    fn move_ee_xyz(
        &self,
        py: Python<'_>,
        displacement: &Bound<'_, PyAny>,
        eef_step: f64,
        #[pyo3(from_py_with = truthy)] numerical: bool,
        #[pyo3(from_py_with = truthy)] plan: bool,
        #[allow(unused_variables)] kwargs: Option<&Bound<'_, pyo3::types::PyDict>>,
    ) -> PyResult<bool> {
        let _ = numerical;
        let d = array::<3>(displacement, "displacement")?;
        let arm = self.arm.clone();
        blocking(py, self.robot(), move || {
            arm.move_ee_xyz_with(d, eef_step, plan)
        })?;
        Ok(true)
    }

    /// Pose of `des_frame` (a link of the arm's chain) at `joint_positions`, in the arm's
    /// base frame: `(pos (3, 1), rot (3, 3))`.
    fn compute_fk_position<'py>(
        &self,
        py: Python<'py>,
        joint_positions: &Bound<'_, PyAny>,
        des_frame: &str,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let q = self.joints(joint_positions, "joint_positions")?;
        let p = py
            .detach(|| self.arm.compute_fk_position(&q, des_frame))
            .py()?;
        PyTuple::new(py, [column3(py, p.position)?, mat3(py, p.rotation)?])
    }

    /// The end effector's twist `[vx, vy, vz, wx, wy, wz]` (m/s, rad/s, base frame) at
    /// `joint_positions` moving at `joint_velocities`. `des_frame` must be the end effector's.
    fn compute_fk_velocity<'py>(
        &self,
        py: Python<'py>,
        joint_positions: &Bound<'_, PyAny>,
        joint_velocities: &Bound<'_, PyAny>,
        des_frame: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let q = self.joints(joint_positions, "joint_positions")?;
        let qd = self.joints(joint_velocities, "joint_velocities")?;
        let twist_of = "compute_fk_velocity gives the end effector's twist: des_frame must be";
        self.expect_frame(py, des_frame, self.ee_frame(), twist_of)?;
        let v = py.detach(|| self.arm.compute_fk_velocity(&q, &qd)).py()?;
        Ok(convert::vec1(py, v.to_vec()))
    }

    /// Joint angles (rad, `(dof,)`) that put the end effector at `position` with
    /// `orientation`, nearest `qinit` (default: the joints now). Raises `Unreachable` when
    /// none does (PyRobot returned `None`).
    #[pyo3(signature = (position, orientation, qinit=None, numerical=true))]
    fn compute_ik<'py>(
        &self,
        py: Python<'py>,
        position: &Bound<'_, PyAny>,
        orientation: &Bound<'_, PyAny>,
        qinit: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = truthy)] numerical: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let _ = numerical;
        let p = array::<3>(position, "position")?;
        let o = self::orientation(orientation, "orientation")?;
        let seed = qinit.map(|s| self.joints(s, "qinit")).transpose()?;
        let q = py
            .detach(|| self.arm.compute_ik(p, o, seed.as_deref()))
            .py()?;
        Ok(convert::vec1(py, q))
    }

    /// The geometric Jacobian at `joint_angles`: `(6, dof)`, rows `[vx, vy, vz, wx, wy, wz]`
    /// in the base frame, at the end effector's origin.
    fn get_jacobian<'py>(
        &self,
        py: Python<'py>,
        joint_angles: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let q = self.joints(joint_angles, "joint_angles")?;
        let j = py.detach(|| self.arm.get_jacobian(&q)).py()?;
        // Row-major: the transpose's column-major storage.
        let (rows, cols) = j.shape();
        convert::shaped(py, j.transpose().as_slice().to_vec(), &[rows, cols])
    }

    fn __repr__(&self) -> String {
        format!("<ferrobot.Arm of {:?}>", self.robot().name())
    }
}
