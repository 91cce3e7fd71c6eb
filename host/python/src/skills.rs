//! Ferrobot's skills and catalogues from Python: grasping, pushing and hand-eye calibration on
//! a robot (`ferrobot-skills`), and the bundled robots and scenes.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::OrRaise;
use crate::motion::run_blocking;
use crate::robot::Robot;

/// Pick an object off the table in front of the robot: look (head tilt `head_tilt` rad),
/// segment the table's objects, choose a top-down grasp, plan to its pregrasp, grasp and lift.
/// Returns a dict: `position` (m, base_link), `yaw` (rad), `width` (m), `objects` seen,
/// `skipped` (better grasps out of reach), `gripper_state` (PyRobot's code).
#[pyfunction]
#[pyo3(signature = (robot, head_tilt=0.8, attempts=5))]
pub fn grasp(
    py: Python<'_>,
    robot: &Robot,
    head_tilt: f64,
    attempts: usize,
) -> PyResult<Py<PyAny>> {
    let bot = robot.robot.clone();
    let opts = ferrobot_skills::grasp::GraspOptions {
        head_tilt,
        attempts,
        ..Default::default()
    };
    let g = run_blocking(py, &robot.robot, move || {
        ferrobot_skills::grasp::pick(&bot, &opts).py()
    })?;
    let d = PyDict::new(py);
    let p = g.grasp.position;
    d.set_item("position", vec![p.x, p.y, p.z])?;
    d.set_item("yaw", g.grasp.yaw)?;
    d.set_item("width", g.grasp.width)?;
    d.set_item("objects", g.objects)?;
    d.set_item("skipped", g.skipped)?;
    d.set_item("gripper_state", crate::gripper::state_code(g.state))?;
    Ok(d.into_any().unbind())
}

/// Push an object on the table: look, segment, choose the push that moves the object most
/// towards the table's free middle, and push it with the closed gripper. Returns a dict:
/// `objects` seen, `target` (the object's index), `lift` (m), `roll` (rad), `base_move`
/// (`[forward, left]` m, when the base moved to reach), `side` of the table.
#[pyfunction]
#[pyo3(signature = (robot, attempts=None))]
pub fn push(py: Python<'_>, robot: &Robot, attempts: Option<usize>) -> PyResult<Py<PyAny>> {
    let bot = robot.robot.clone();
    let mut opts = ferrobot_skills::push::PushOptions::default();
    if let Some(a) = attempts {
        opts.attempts = a;
    }
    let p = run_blocking(py, &robot.robot, move || {
        ferrobot_skills::push::push_object(&bot, &opts).py()
    })?;
    let d = PyDict::new(py);
    d.set_item("objects", p.objects.len())?;
    d.set_item("target", p.plan.target)?;
    d.set_item("lift", p.lift)?;
    d.set_item("roll", p.roll)?;
    d.set_item("base_move", p.base_move.to_vec())?;
    d.set_item("side", format!("{:?}", p.side).to_lowercase())?;
    Ok(d.into_any().unbind())
}

/// Hand-eye calibration: the arm shows the gripper's marker to the camera from several poses,
/// and the camera's mount is fitted to the marker's corners. Returns a dict: `calibration`
/// (the mount: `parent`, `child`, `xyz` m, `quaternion` `[x, y, z, w]`, ...), `captured`,
/// `seen`, `used` (images), `rms_px` (reprojection error), `missed` (why, per image), from
/// `poses` arm poses (1-6) times a `grid` x `grid` head grid (1-5). With
/// `save`, the calibration is written there (TOML), for `Robot(..., overrides=...)` or
/// `ferrobot`'s `--camera-calibration`.
#[pyfunction]
#[pyo3(signature = (robot, save=None, poses=6, grid=3))]
pub fn calibrate_camera(
    py: Python<'_>,
    robot: &Robot,
    save: Option<std::path::PathBuf>,
    poses: usize,
    grid: usize,
) -> PyResult<Py<PyAny>> {
    let bot = robot.robot.clone();
    let r = run_blocking(py, &robot.robot, move || {
        let opts = ferrobot_skills::HandEyeOptions::with_counts(poses, grid).py()?;
        ferrobot_skills::hand_eye::calibrate_camera(&bot, &opts).py()
    })?;
    if let Some(path) = save {
        r.calibration
            .save(&path)
            .map_err(|e| crate::errors::to_py(py, ferrobot::Error::Io(e)))?;
    }
    let d = PyDict::new(py);
    d.set_item("calibration", to_python(py, &r.calibration)?)?;
    d.set_item("captured", r.captured)?;
    d.set_item("seen", r.seen)?;
    d.set_item("used", r.used)?;
    d.set_item("rms_px", r.rms_px)?;
    d.set_item("missed", r.missed)?;
    Ok(d.into_any().unbind())
}

/// PyRobot's base benchmark (its Table 1), as `ferrobot bench base` runs it: every controller
/// drives to the paper's relative targets from rest, `trials` times each (1 to 100, trial k
/// seeded `seed + k`) on a fresh simulated `robot`; errors against the simulator's ground
/// truth and the odometry. Returns `{"rows": [...], "markdown": table}`, each row a dict of
/// `controller`, `category`, `reference`, `translation_mm` and `rotation_deg` (mean, std),
/// `successes` (of trials). Ctrl-C stops between trials.
#[pyfunction]
#[pyo3(signature = (robot="locobot", trials=5, seed=1))]
pub fn bench_base(py: Python<'_>, robot: &str, trials: usize, seed: u64) -> PyResult<Py<PyAny>> {
    use ferrobot_skills::base_trials::{jobs, markdown, run_trial, summarize, MAX_TRIALS};
    ferrobot::validate::count("trials", trials, 1..=MAX_TRIALS)
        .map_err(ferrobot::Error::from)
        .py()?;
    let mut done = Vec::new();
    for (c, cat, target, sd) in jobs(trials, seed) {
        let opts = ferrobot::GoalOptions::default();
        done.push(
            py.detach(|| run_trial(robot, c, cat, target, opts, sd, None))
                .py()?,
        );
        py.check_signals()?;
    }
    let rows = summarize(&done);
    let json: Vec<_> = rows.iter().map(|r| r.json()).collect();
    let d = PyDict::new(py);
    d.set_item("rows", to_python(py, &json)?)?;
    d.set_item("markdown", markdown(robot, trials, seed, &rows))?;
    Ok(d.into_any().unbind())
}

/// A value of the Rust API as Python's dicts and lists: the same fields and names as the
/// command line's `--json` gives, through its serde form.
fn to_python<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// The bundled robots' names.
#[pyfunction]
pub fn robots() -> Vec<&'static str> {
    ferrobot::config::BUNDLED.to_vec()
}

/// The bundled scenes' names.
#[pyfunction]
pub fn scenes() -> Vec<&'static str> {
    ferrobot::scene::BUNDLED.to_vec()
}
