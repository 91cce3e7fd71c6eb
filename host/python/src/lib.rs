//! `ferrobot._native`: Ferrobot's Rust API as a Python extension module, PyRobot's names and
//! signatures kept (the package `ferrobot` re-exports it; see `python/ferrobot/__init__.py`).
//!
//! Arrays are numpy (colour `(H, W, 3)` uint8, depth `(H, W)` float32 m, points `(N, 3)`
//! float64 m), handed over without copying; every Rust error is a `ferrobot.Error` subclass
//! named as its variant; blocking calls release the GIL and stop on Ctrl-C.

mod arm;
mod arm_plan;
mod base;
mod base_utils;
mod bench;
mod camera;
mod configs;
mod convert;
mod errors;
mod gripper;
mod motion;
mod options;
mod record;
mod robot;
mod skills;
mod world;

use pyo3::prelude::*;

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<robot::Robot>()?;
    m.add_class::<arm::Arm>()?;
    m.add_class::<arm_plan::Plan>()?;
    m.add_class::<gripper::Gripper>()?;
    m.add_class::<camera::Camera>()?;
    m.add_class::<base::Base>()?;
    m.add_class::<motion::Motion>()?;
    m.add_class::<record::Recorder>()?;
    m.add_class::<world::SharedWorld>()?;
    m.add_function(wrap_pyfunction!(record::export_lerobot, m)?)?;
    m.add_function(wrap_pyfunction!(skills::grasp, m)?)?;
    m.add_function(wrap_pyfunction!(skills::push, m)?)?;
    m.add_function(wrap_pyfunction!(skills::calibrate_camera, m)?)?;
    m.add_function(wrap_pyfunction!(skills::bench_base, m)?)?;
    m.add_function(wrap_pyfunction!(skills::robots, m)?)?;
    m.add_function(wrap_pyfunction!(skills::scenes, m)?)?;
    m.add_function(wrap_pyfunction!(base_utils::base_reference, m)?)?;
    m.add_function(wrap_pyfunction!(base_utils::circle_reference, m)?)?;
    m.add_function(wrap_pyfunction!(bench::rust_call_seconds, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
