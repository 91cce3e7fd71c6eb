//! The Rust side of the Python overhead benchmark (`host/python/bench/overhead.py`): the same
//! calls as the Python API makes, timed in a loop in Rust, so that the benchmark measures what
//! the binding adds in one run.

use std::time::Instant;

use pyo3::prelude::*;

use crate::errors::{invalid, OrRaise};
use crate::robot::Robot;

/// Seconds per call of the Rust API's `call` on `robot`, over `n` calls (1 to 10^7):
/// `"get_joint_angles"`, `"pose_ee"` (`Arm::get_ee_pose`) or `"get_rgb_depth"`. Without the
/// GIL, as the Python calls run.
#[pyfunction]
pub fn rust_call_seconds(py: Python<'_>, robot: &Robot, call: &str, n: usize) -> PyResult<f64> {
    if !(1..=10_000_000).contains(&n) {
        return Err(invalid(py, "n", "1 to 10^7 calls", format!("{n}")));
    }
    let bot = &robot.robot;
    let run = |f: &dyn Fn() -> ferrobot::Result<()>| -> ferrobot::Result<f64> {
        let start = Instant::now();
        for _ in 0..n {
            f()?;
        }
        Ok(start.elapsed().as_secs_f64() / n as f64)
    };
    match call {
        "get_joint_angles" => {
            let arm = bot.arm().py()?;
            py.detach(|| run(&|| arm.get_joint_angles().map(drop))).py()
        }
        "pose_ee" => {
            let arm = bot.arm().py()?;
            py.detach(|| run(&|| arm.get_ee_pose().map(drop))).py()
        }
        "get_rgb_depth" => {
            let camera = bot.camera().py()?;
            py.detach(|| run(&|| camera.get_rgb_depth().map(drop))).py()
        }
        other => Err(invalid(
            py,
            "call",
            "\"get_joint_angles\", \"pose_ee\" or \"get_rgb_depth\"",
            format!("{other:?}"),
        )),
    }
}
