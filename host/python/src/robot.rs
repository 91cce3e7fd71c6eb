//! `ferrobot.Robot`: PyRobot's constructor and its components (`bot.arm`, `bot.gripper`,
//! `bot.camera`, `bot.base`), plus the robot-wide calls of the Rust API.

use pyo3::prelude::*;

use crate::convert::truthy;
use ferrobot::config::ConfigSource;
use pyo3::types::PyDict;

use crate::arm::Arm;
use crate::base::Base;
use crate::camera::Camera;
use crate::convert;
use crate::errors::OrRaise;
use crate::gripper::Gripper;
use crate::motion::blocking;
use crate::options;

/// A robot: PyRobot's `Robot`. Components the robot lacks, or that were turned off
/// (`use_arm=False`, ...), are `None`.
#[pyclass(frozen, module = "ferrobot._native")]
pub struct Robot {
    pub(crate) robot: ferrobot::Robot,
    /// The arm (`None` without one).
    #[pyo3(get)]
    arm: Option<Py<Arm>>,
    /// The gripper (`None` without one, or without the arm, as in PyRobot).
    #[pyo3(get)]
    gripper: Option<Py<Gripper>>,
    /// The RGB-D camera on its pan-tilt head (`None` without one).
    #[pyo3(get)]
    camera: Option<Py<Camera>>,
    /// The mobile base (`None` without one).
    #[pyo3(get)]
    base: Option<Py<Base>>,
    /// PyRobot's `configs` (`bot.configs.BASE.MAX_ABS_FWD_SPEED`, ...), from the description.
    #[pyo3(get)]
    configs: Py<PyAny>,
}

impl Robot {
    /// The Python objects of `robot`'s components.
    fn assemble(
        py: Python<'_>,
        robot: ferrobot::Robot,
        base_cfg: &Option<Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let configs = crate::configs::configs(py, &robot)?;
        let cfg = robot.config();
        let arm = match robot.arm() {
            Ok(a) => Some(Py::new(
                py,
                Arm::new(a, robot.clone(), configs.clone_ref(py)),
            )?),
            Err(_) => None,
        };
        let gripper = match robot.gripper() {
            Ok(g) if cfg.gripper.is_some() => Some(Py::new(py, Gripper::new(g, robot.clone()))?),
            _ => None,
        };
        let camera = match robot.camera() {
            Ok(c) => Some(Py::new(
                py,
                Camera::new(c, robot.head().ok(), robot.clone()),
            )?),
            Err(_) => None,
        };
        let base = match robot.base() {
            Ok(b) if cfg.base.is_some() => {
                Some(Py::new(py, Base::new(py, b, robot.clone(), base_cfg)?)?)
            }
            _ => None,
        };
        Ok(Robot {
            robot,
            arm,
            gripper,
            camera,
            base,
            configs,
        })
    }
}

/// The bundled description PyRobot's robot names load: `locobot_kobuki` is the LoCoBot.
fn bundled_name(name: &str) -> &str {
    match name {
        "locobot_kobuki" => "locobot",
        "locobot_create" => "locobot_lite",
        other => other,
    }
}

#[pymethods]
impl Robot {
    /// PyRobot's constructor, on the in-process simulator unless `backend` says otherwise.
    ///
    /// `robot_name`: `"locobot"` (also `"locobot_kobuki"`), `"locobot_lite"` or `"sawyer"`;
    /// or any name with `config_file` (a TOML description beside its URDF). PyRobot's
    /// dictionaries take the keys PyRobot's LoCoBot classes take (`base_config`:
    /// `base_controller` `"ilqr"`, `"proportional"`, `"movebase"`, and `base_planner`;
    /// `arm_config`: `use_moveit`, `moveit_planner`, `planning_time`, `control_mode`).
    /// Ferrobot's keywords: `scene` (a bundled scene's name or a scene file), `backend`
    /// (`"sim"`, `"serial:PATH"`, `"emulated"`, `"direct"` for the host-run firmware on the
    /// robot's own cables, `"direct:servo=PATH,base=PATH,camera=SOCKET"` with its devices
    /// named, `"direct-emulated"`, `"remote:tcp/HOST:PORT[,namespace=NS][,credentials=FILE]"`
    /// for a robot served on zenoh by another process or machine (`ferrobot serve`); when
    /// absent, the environment's `FERROBOT_BACKEND`, else
    /// `"sim"`: an unchanged program runs on the robot), `seed` (the simulator's noise), `realtime`
    /// (pace simulated time to the wall clock), `start_pose` (`[x, y, theta]` in the scene),
    /// `depth_noise`, `slam` (start SLAM at the start pose), `overrides` (dotted keys of the
    /// description, e.g. `{"arm.joint_tolerance": 0.01}`), and for hand-eye calibration in
    /// the simulator `calibration_marker` (draw the gripper's marker) and
    /// `camera_mount_error` (`[dx, dy, dz, droll, dpitch, dyaw]`, m and rad: the simulated
    /// camera sits that far off its URDF pose, which the host keeps believing), and `world` (a
    /// `SharedWorld` to join, with other robots, at `start_pose`, instead of `scene`).
    #[new]
    #[pyo3(signature = (
        robot_name, use_arm=true, use_base=true, use_camera=true, use_gripper=true,
        arm_config=None, base_config=None, camera_config=None, gripper_config=None,
        common_config=None, *, scene=None, backend=None, seed=1, realtime=false,
        config_file=None, start_pose=None, depth_noise=true, slam=false, overrides=None,
        calibration_marker=false, camera_mount_error=None, world=None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        robot_name: &str,
        #[pyo3(from_py_with = truthy)] use_arm: bool,
        #[pyo3(from_py_with = truthy)] use_base: bool,
        #[pyo3(from_py_with = truthy)] use_camera: bool,
        #[pyo3(from_py_with = truthy)] use_gripper: bool,
        arm_config: Option<&Bound<'_, PyDict>>,
        base_config: Option<&Bound<'_, PyDict>>,
        camera_config: Option<&Bound<'_, PyDict>>,
        gripper_config: Option<&Bound<'_, PyDict>>,
        common_config: Option<&Bound<'_, PyDict>>,
        scene: Option<String>,
        backend: Option<String>,
        seed: u64,
        #[pyo3(from_py_with = truthy)] realtime: bool,
        config_file: Option<std::path::PathBuf>,
        start_pose: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = truthy)] depth_noise: bool,
        #[pyo3(from_py_with = truthy)] slam: bool,
        overrides: Option<&Bound<'_, PyDict>>,
        #[pyo3(from_py_with = truthy)] calibration_marker: bool,
        camera_mount_error: Option<&Bound<'_, PyAny>>,
        world: Option<PyRef<'_, crate::world::SharedWorld>>,
    ) -> PyResult<Self> {
        let base_cfg = options::checked(base_config, "base_config", &options::BASE_KEYS)?;
        options::checked(arm_config, "arm_config", &options::ARM_KEYS)?;
        options::checked(camera_config, "camera_config", &[])?;
        options::checked(gripper_config, "gripper_config", &options::GRIPPER_KEYS)?;
        let common = options::checked(common_config, "common_config", &options::COMMON_KEYS)?;
        let source = match config_file {
            Some(path) => ConfigSource::File(path),
            None => ConfigSource::Bundled(bundled_name(robot_name).into()),
        };
        let mut builder = match &source {
            ConfigSource::File(path) => ferrobot::Robot::builder_from_config(path),
            ConfigSource::Bundled(name) => ferrobot::Robot::builder(name),
        };
        builder = builder
            .use_arm(use_arm)
            .use_base(use_base)
            .use_camera(use_camera)
            .use_gripper(use_gripper && use_arm)
            .depth_noise(depth_noise);
        let spec = options::backend_spec(py, backend)?;
        builder =
            options::with_backend(py, builder, &spec, bundled_name(robot_name), seed, realtime)?;
        let scene = scene
            .or(options::string(&common, "scene")?)
            .or(options::string(&common, "scene_path")?);
        match (scene, &world) {
            (Some(_), Some(_)) => {
                return Err(ferrobot::Error::Usage(
                    "scene and world: a robot joining a shared world is in its scene".into(),
                ))
                .py()
            }
            (Some(s), None) => builder = builder.scene(&s),
            (None, Some(w)) => builder = builder.shared_world(&w.world),
            (None, None) => {}
        }
        if let Some(p) = start_pose {
            builder = builder.start_pose(convert::array::<3>(p, "start_pose")?);
        }
        if let Some(e) = camera_mount_error {
            builder = builder.camera_mount_error(convert::array::<6>(e, "camera_mount_error")?);
        }
        builder = builder.calibration_marker(calibration_marker);
        builder = options::base_controller(py, builder, &base_cfg)?;
        builder = options::pyrobot_ik_tolerances(builder, &source);
        builder = options::apply_overrides(builder, overrides)?;
        let robot = py.detach(move || builder.build()).py()?;
        if slam {
            let r = robot.clone();
            blocking(py, &robot, move || r.start_slam([0.0; 3], None))?;
        }
        Robot::assemble(py, robot, &base_cfg)
    }

    /// The robot's name.
    #[getter]
    fn name(&self) -> String {
        self.robot.name().to_string()
    }

    /// The backend's clock, s (simulated time on the simulator).
    fn time(&self) -> f64 {
        self.robot.time()
    }

    /// Let `seconds` pass (simulated time on the simulator), the motions under way going on.
    fn wait(&self, py: Python<'_>, seconds: f64) -> PyResult<()> {
        let r = self.robot.clone();
        blocking(py, &self.robot, move || r.wait(seconds))
    }

    /// Emergency stop: the base stops, the arm holds, motion is refused until `resume()`.
    fn emergency_stop(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| self.robot.emergency_stop()).py()
    }

    /// Leave the emergency stop.
    fn resume(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| self.robot.resume()).py()
    }

    /// Stop every motion under way where it is (what Ctrl-C does); nothing latches.
    fn cancel_motions(&self, py: Python<'_>) {
        py.detach(|| self.robot.cancel_motions())
    }

    /// The faults the firmware reported since the last call: a list of dicts
    /// (`kind`, `joint` index or `None`, `servo_id`, `code`, `time` s on the firmware's
    /// clock).
    fn take_faults(&self, py: Python<'_>) -> PyResult<Vec<Py<PyAny>>> {
        self.robot
            .take_faults()
            .into_iter()
            .map(|f| {
                let d = PyDict::new(py);
                d.set_item("kind", format!("{:?}", f.kind))?;
                d.set_item("joint", f.joint)?;
                d.set_item("servo_id", f.servo_id)?;
                d.set_item("code", f.code)?;
                d.set_item("time", f.time_us as f64 * 1e-6)?;
                Ok(d.into_any().unbind())
            })
            .collect()
    }

    /// The firmware's latest report: a dict of `time` (s, the firmware's clock),
    /// `joint_names` (the joint table's order), `positions` (rad or m), `velocities`,
    /// `efforts` (N m or N), `odometry` (`[x, y, theta]`), `base_velocity` (`[v, w]`, m/s and
    /// rad/s), `gripper` (PyRobot's state code) and `fault_flags`.
    fn telemetry<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = py.detach(|| self.robot.telemetry()).py()?;
        let d = PyDict::new(py);
        d.set_item("time", t.time_us as f64 * 1e-6)?;
        let names: Vec<&str> = self
            .robot
            .config()
            .joints
            .iter()
            .map(|j| j.name.as_str())
            .collect();
        d.set_item("joint_names", names)?;
        let q = t.joints.iter().map(|j| j.position as f64).collect();
        let qd = t.joints.iter().map(|j| j.velocity as f64).collect();
        let tau = t.joints.iter().map(|j| j.effort as f64).collect();
        d.set_item("positions", convert::vec1(py, q))?;
        d.set_item("velocities", convert::vec1(py, qd))?;
        d.set_item("efforts", convert::vec1(py, tau))?;
        let o = t.odometry;
        d.set_item("odometry", vec![o.x as f64, o.y as f64, o.theta as f64])?;
        d.set_item("base_velocity", vec![o.v as f64, o.w as f64])?;
        d.set_item("gripper", crate::gripper::state_code(t.gripper))?;
        d.set_item("fault_flags", t.faults)?;
        Ok(d)
    }

    /// Pose of URDF frame `src` in frame `dst` now: `(trans (3,), rot (3, 3), T (4, 4))`.
    fn get_link_transform<'py>(
        &self,
        py: Python<'py>,
        src: &str,
        dst: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let t = py.detach(|| self.robot.link_transform(src, dst)).py()?;
        crate::camera::transform_tuple(py, &t)
    }

    /// Start SLAM with the robot at `start` (`[x, y, theta]` in the map frame; default the
    /// origin): `bot.base.get_state("vslam")` then reads its pose.
    #[pyo3(signature = (start=None))]
    fn start_slam(&self, py: Python<'_>, start: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let start = match start {
            Some(s) => convert::array::<3>(s, "start")?,
            None => [0.0; 3],
        };
        let r = self.robot.clone();
        blocking(py, &self.robot, move || r.start_slam(start, None))
    }

    /// Stop SLAM; True when it was running.
    fn stop_slam(&self, py: Python<'_>) -> bool {
        py.detach(|| self.robot.stop_slam()).is_some()
    }

    /// SLAM's 3-D map as a point cloud on a `voxel` grid (m): `(points (N, 3), colours (N, 3)
    /// uint8)` in the map frame.
    #[pyo3(signature = (voxel=0.02))]
    fn slam_map_3d<'py>(&self, py: Python<'py>, voxel: f64) -> PyResult<Bound<'py, PyAny>> {
        let cloud = py.detach(|| self.robot.slam_map_3d(voxel)).py()?;
        crate::camera::cloud_tuple(py, cloud)
    }

    /// SLAM's occupancy grid: `(grid (H, W) uint8: 0 free, 100 occupied, 255 unknown,
    /// resolution m/cell, origin [x, y] m)`, or `None` before SLAM has one.
    fn slam_occupancy_map<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let map = py.detach(|| self.robot.slam_occupancy_map()).py()?;
        map.map(|m| crate::camera::occupancy_tuple(py, m))
            .transpose()
    }

    fn __repr__(&self) -> String {
        format!("<ferrobot.Robot {:?}>", self.robot.name())
    }
}
