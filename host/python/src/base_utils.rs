//! PyRobot's base trajectory utilities (`pyrobot.locobot.base_control_utils`), on Ferrobot's
//! references (`ferrobot_control::trajectory::Reference`): what PyRobot's programs build the
//! states of `track_trajectory` with.

use ferrobot::base_control::{Limits, Reference};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::convert::{array, shaped};
use crate::errors::{invalid, OrRaise};

fn reference_tuple(py: Python<'_>, r: Reference) -> PyResult<Bound<'_, PyTuple>> {
    let (n, m) = (r.states.len(), r.controls.len());
    PyTuple::new(
        py,
        [
            shaped(py, r.states.concat(), &[n, 3])?,
            shaped(py, r.controls.concat(), &[m, 2])?,
        ],
    )
}

/// A reference from `start_pos` to `goal_pos` (`[x, y, theta]`), sampled every `dt` s under
/// `max_v` (m/s) and `max_w` (rad/s): `init_type` `"sharp"` (turn, drive, turn; backwards
/// when the goal lies behind) or `"smooth"` (a Bézier curve). Returns `(states (n + 1, 3),
/// controls (n, 2))`.
#[pyfunction]
pub fn base_reference<'py>(
    py: Python<'py>,
    init_type: &str,
    start_pos: &Bound<'_, PyAny>,
    goal_pos: &Bound<'_, PyAny>,
    dt: f64,
    max_v: f64,
    max_w: f64,
) -> PyResult<Bound<'py, PyTuple>> {
    let start = array::<3>(start_pos, "start_pos")?;
    let goal = array::<3>(goal_pos, "goal_pos")?;
    let lim = Limits {
        v: max_v,
        w: max_w,
        ..Limits::TRACKING
    };
    let r = match init_type {
        "sharp" => Reference::sharp(start, goal, &lim, dt),
        "smooth" => Reference::smooth(start, goal, &lim, dt, ferrobot::base::SMOOTH_ARM),
        other => {
            return Err(invalid(
                py,
                "init_type",
                "\"sharp\" or \"smooth\"",
                format!("{other:?}"),
            ))
        }
    };
    let r = r.map_err(ferrobot::Error::from).py()?;
    reference_tuple(py, r)
}

/// A circle from `start_pos` at speed `v` (m/s) and radius `r` (m; turning left), through
/// `angle` rad, sampled every `dt` s: `(states (n + 1, 3), controls (n, 2))`.
#[pyfunction]
pub fn circle_reference<'py>(
    py: Python<'py>,
    start_pos: &Bound<'_, PyAny>,
    dt: f64,
    r: f64,
    v: f64,
    angle: f64,
) -> PyResult<Bound<'py, PyTuple>> {
    let start = array::<3>(start_pos, "start_pos")?;
    if !(r.is_finite() && r != 0.0 && angle.is_finite() && v.is_finite() && v != 0.0) {
        return Err(invalid(
            py,
            "r, v, angle",
            "finite numbers, r and v not 0",
            format!("r={r}, v={v}, angle={angle}"),
        ));
    }
    let w = v / r;
    let duration = (angle / w).abs();
    let reference = Reference::circle(start, v, w, duration, dt)
        .map_err(ferrobot::Error::from)
        .py()?;
    reference_tuple(py, reference)
}
