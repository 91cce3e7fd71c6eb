//! PyRobot's `configs` (`bot.configs.ARM.EE_FRAME`, `bot.configs.BASE.MAX_ABS_FWD_SPEED`,
//! ...), read from the robot's description: the keys PyRobot's programs and tests read, with
//! PyRobot's names.

use pyo3::prelude::*;
use pyo3::types::PyDict;

/// PyRobot's base control rate, Hz: the sample period of the trajectories its programs make
/// for `track_trajectory` (`dt = 1 / BASE_CONTROL_RATE`).
pub const BASE_CONTROL_RATE: f64 = 10.0;

/// `configs` as `ferrobot.configs.CfgNode`s (attribute access, as PyRobot's yacs nodes).
pub fn configs(py: Python<'_>, robot: &ferrobot::Robot) -> PyResult<Py<PyAny>> {
    let cfg = robot.config();
    let root = PyDict::new(py);
    root.set_item("ROBOT", &cfg.name)?;
    root.set_item("HAS_ARM", cfg.arm.is_some())?;
    root.set_item("HAS_BASE", cfg.base.is_some())?;
    root.set_item("HAS_CAMERA", cfg.camera.is_some())?;
    root.set_item("HAS_GRIPPER", cfg.gripper.is_some())?;
    let bounds = |name: &str| cfg.joints.iter().find(|j| j.name == name).map(|j| j.bounds);
    if let Some(a) = &cfg.arm {
        let arm = PyDict::new(py);
        arm.set_item("ARM_BASE_FRAME", &a.base_frame)?;
        arm.set_item("EE_FRAME", &a.ee_frame)?;
        arm.set_item("JOINT_NAMES", &a.joints)?;
        arm.set_item("HOME", &a.home)?;
        arm.set_item("IK_POSITION_TOLERANCE", a.ik_position_tolerance)?;
        arm.set_item("IK_ORIENTATION_TOLERANCE", a.ik_orientation_tolerance)?;
        arm.set_item("MAX_JOINT_ERROR", a.joint_tolerance)?;
        root.set_item("ARM", arm)?;
    }
    if let Some(b) = &cfg.base {
        let base = PyDict::new(py);
        base.set_item("BASE_TYPE", format!("{:?}", b.kind).to_lowercase())?;
        base.set_item(
            "BASE_CONTROLLER",
            format!("{:?}", b.controller).to_lowercase(),
        )?;
        base.set_item("BASE_CONTROL_RATE", BASE_CONTROL_RATE)?;
        // PyRobot's speed limits are those its trajectories are made and tracked under.
        let lim = robot.base().map(|b| b.tracking_limits()).ok();
        base.set_item("MAX_ABS_FWD_SPEED", lim.map_or(b.max_linear, |l| l.v))?;
        base.set_item("MAX_ABS_TURN_SPEED", lim.map_or(b.max_angular, |l| l.w))?;
        base.set_item("TRANSLATION_TRESHOLD", b.translation_tolerance)?;
        if let Some(c) = &cfg.camera {
            let vslam = PyDict::new(py);
            vslam.set_item("VSLAM_BASE_FRAME", "base_link")?;
            vslam.set_item("RGB_CAMERA_CENTER_FRAME", &c.frame)?;
            vslam.set_item("DEPTH_MIN", c.depth_min)?;
            vslam.set_item("DEPTH_MAX", c.depth_max)?;
            base.set_item("VSLAM", vslam)?;
        }
        root.set_item("BASE", base)?;
    }
    if let Some(c) = &cfg.camera {
        let cam = PyDict::new(py);
        if let Some((lo, hi)) = bounds(&c.pan_joint) {
            cam.set_item("MIN_PAN", lo)?;
            cam.set_item("MAX_PAN", hi)?;
        }
        if let Some((lo, hi)) = bounds(&c.tilt_joint) {
            cam.set_item("MIN_TILT", lo)?;
            cam.set_item("MAX_TILT", hi)?;
        }
        cam.set_item("RESET_PAN", 0.0)?;
        cam.set_item("RESET_TILT", 0.0)?;
        cam.set_item("DEPTH_MAP_FACTOR", 1.0)?;
        cam.set_item("WIDTH", c.width)?;
        cam.set_item("HEIGHT", c.height)?;
        root.set_item("CAMERA", cam)?;
    }
    let node = py.import("ferrobot.configs")?.getattr("CfgNode")?;
    Ok(node.call1((root,))?.unbind())
}
