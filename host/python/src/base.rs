//! `bot.base`: PyRobot's mobile base (position goals, velocities, trajectories, state), and
//! exploration.

use ferrobot::base_control::Reference;
use ferrobot::config::BaseController;
use ferrobot::{GoalOptions, Source};
use parking_lot::Mutex;
use pyo3::prelude::*;

use crate::convert::truthy;
use pyo3::types::PyDict;

use crate::arm::finish;
use crate::configs::BASE_CONTROL_RATE;
use crate::convert::{array, rows};
use crate::errors::{invalid, OrRaise};
use crate::options;

/// The mobile base: PyRobot's `LoCoBotBase`. Poses `[x, y, theta]` (m, m, rad) in the
/// odometry frame (where the base started), or in SLAM's map.
#[pyclass(frozen, module = "ferrobot._native")]
pub struct Base {
    base: ferrobot::base::Base,
    robot: ferrobot::Robot,
    /// The controller of position goals; the description's when `None`.
    controller: Mutex<Option<BaseController>>,
}

/// PyRobot's `base_planner`: `"none"` or `"movebase"` (planning on a map is `use_map`).
fn check_planner(py: Python<'_>, name: &str) -> PyResult<()> {
    match name {
        "none" | "movebase" => Ok(()),
        _ => Err(invalid(
            py,
            "base_planner",
            "\"none\" or \"movebase\"",
            format!("{name:?}"),
        )),
    }
}

impl Base {
    /// The base of `robot`, with PyRobot's `base_config`'s `base_planner` checked (its
    /// `base_controller` is the description's `base.controller`, set when the robot is built).
    pub fn new(
        py: Python<'_>,
        base: ferrobot::base::Base,
        robot: ferrobot::Robot,
        cfg: &Option<Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        if let Some(p) = options::string(cfg, "base_planner")? {
            check_planner(py, &p)?;
        }
        Ok(Base {
            base,
            robot,
            controller: Mutex::new(None),
        })
    }

    fn goal(
        &self,
        py: Python<'_>,
        xyt: &Bound<'_, PyAny>,
        relative: bool,
        opts: GoalOptions,
        wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let g = array::<3>(xyt, "xyt_position")?;
        let base = self.base.clone();
        let m = py
            .detach(move || {
                if relative {
                    base.go_to_relative_with(g, opts)
                } else {
                    base.go_to_absolute_with(g, opts)
                }
            })
            .py()?;
        finish(py, &self.robot, "base motion", m, wait)
    }

    fn options(&self, use_map: bool, close_loop: bool, smooth: bool) -> GoalOptions {
        GoalOptions {
            controller: *self.controller.lock(),
            smooth,
            close_loop,
            use_map,
            ..GoalOptions::default()
        }
    }
}

/// Controls `[v, w]` that take a unicycle from each state to the next in `dt` s.
fn controls_between(states: &[[f64; 3]], dt: f64) -> Vec<[f64; 2]> {
    states
        .windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let forward = dx * a[2].cos() + dy * a[2].sin();
            let dist = dx.hypot(dy).copysign(forward);
            let turn = (b[2] - a[2] + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            [dist / dt, turn / dt]
        })
        .collect()
}

#[pymethods]
impl Base {
    /// Drive to `xyt_position` `[x, y, theta]` relative to the base now (x forward, y left).
    /// `use_map` plans on SLAM's map (SLAM must be running); `close_loop` and `smooth` choose
    /// how the LQR controllers track. True on arrival, a `Motion` with `wait=False`.
    #[pyo3(signature = (xyt_position, use_map=false, close_loop=true, smooth=false, wait=true))]
    fn go_to_relative(
        &self,
        py: Python<'_>,
        xyt_position: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = truthy)] use_map: bool,
        #[pyo3(from_py_with = truthy)] close_loop: bool,
        #[pyo3(from_py_with = truthy)] smooth: bool,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let opts = self.options(use_map, close_loop, smooth);
        self.goal(py, xyt_position, true, opts, wait)
    }

    /// Drive to `xyt_position` `[x, y, theta]` in the odometry frame (SLAM's map with
    /// `use_map`). True on arrival, a `Motion` with `wait=False`.
    #[pyo3(signature = (xyt_position, use_map=false, close_loop=true, smooth=false, wait=true))]
    fn go_to_absolute(
        &self,
        py: Python<'_>,
        xyt_position: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = truthy)] use_map: bool,
        #[pyo3(from_py_with = truthy)] close_loop: bool,
        #[pyo3(from_py_with = truthy)] smooth: bool,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let opts = self.options(use_map, close_loop, smooth);
        self.goal(py, xyt_position, false, opts, wait)
    }

    /// Drive at `fwd_speed` (m/s) and `turn_speed` (rad/s) for `exe_time` s. Speeds beyond
    /// the base's limits are refused (`OutOfRange`; PyRobot clamped them).
    #[pyo3(signature = (fwd_speed, turn_speed, exe_time=1.0, wait=true))]
    fn set_vel(
        &self,
        py: Python<'_>,
        fwd_speed: f64,
        turn_speed: f64,
        exe_time: f64,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let m = py
            .detach(|| self.base.set_vel_async(fwd_speed, turn_speed, exe_time))
            .py()?;
        finish(py, &self.robot, "base velocity", m, wait)
    }

    /// Stop the base.
    fn stop(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| self.base.stop()).py()
    }

    /// Track `states` (`(T, 3)`: `[x, y, theta]` every `dt` s, odometry frame) with the LQR
    /// tracker, `controls` (`(T, 2)` or `(T-1, 2)`: `[v, w]`) as its feed-forward (derived
    /// from the states when `None`). `dt` is PyRobot's `1 / BASE_CONTROL_RATE` by default.
    #[pyo3(signature = (states, controls=None, close_loop=true, wait=true, dt=None))]
    fn track_trajectory(
        &self,
        py: Python<'_>,
        states: &Bound<'_, PyAny>,
        controls: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = truthy)] close_loop: bool,
        #[pyo3(from_py_with = truthy)] wait: bool,
        dt: Option<f64>,
    ) -> PyResult<Py<PyAny>> {
        let states = rows::<3>(states, "states")?;
        let dt = dt.unwrap_or(1.0 / BASE_CONTROL_RATE);
        let mut controls = match controls {
            Some(c) => rows::<2>(c, "controls")?,
            None => controls_between(&states, dt),
        };
        if controls.len() == states.len() {
            controls.pop();
        }
        if states.len() < 2 || controls.len() + 1 != states.len() {
            return Err(invalid(
                py,
                "controls",
                "as many rows as states (or one fewer), and at least two states",
                format!("{} states and {} controls", states.len(), controls.len()),
            ));
        }
        let reference = Reference {
            dt,
            states,
            controls,
        };
        let base = self.base.clone();
        let m = py
            .detach(move || base.track_trajectory_async(reference, close_loop))
            .py()?;
        finish(py, &self.robot, "trajectory tracking", m, wait)
    }

    /// The base's pose `[x, y, theta]`: from wheel odometry (`"odom"`) or SLAM (`"vslam"`,
    /// SLAM running).
    #[pyo3(signature = (state_type="odom"))]
    fn get_state(&self, py: Python<'_>, state_type: &str) -> PyResult<Vec<f64>> {
        let source = match state_type {
            "odom" => Source::Odometry,
            "vslam" => Source::Slam,
            other => {
                return Err(invalid(
                    py,
                    "state_type",
                    "\"odom\" or \"vslam\"",
                    format!("{other:?}"),
                ))
            }
        };
        Ok(py
            .detach(|| self.base.get_state_from(source))
            .py()?
            .to_vec())
    }

    /// Choose the controller of position goals (PyRobot's names: `"ilqr"`, `"proportional"`,
    /// `"movebase"`; Ferrobot's `"lqr"`, `"dwa"`).
    #[pyo3(signature = (base_controller=None))]
    fn load_controller(&self, py: Python<'_>, base_controller: Option<&str>) -> PyResult<()> {
        *self.controller.lock() = base_controller
            .map(|c| options::controller(py, c))
            .transpose()?;
        Ok(())
    }

    /// PyRobot's planner choice (`"none"` or `"movebase"`): accepted; planning on a map is
    /// `use_map=True` of the position goals.
    #[pyo3(signature = (base_planner=None))]
    fn load_planner(&self, py: Python<'_>, base_planner: Option<&str>) -> PyResult<()> {
        base_planner.map_or(Ok(()), |p| check_planner(py, p))
    }

    /// Explore the scene with SLAM (running) until no frontier is left: the map grows as the
    /// robot drives to the nearest unexplored edge. True when done, a `Motion` with
    /// `wait=False`.
    #[pyo3(signature = (wait=true))]
    fn explore(
        &self,
        py: Python<'_>,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let m = py.detach(|| self.base.explore_async()).py()?;
        finish(py, &self.robot, "exploration", m, wait)
    }

    /// Reset the odometry frame to the base's pose now.
    fn reset_odometry(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| self.base.reset_odometry()).py()
    }

    fn __repr__(&self) -> String {
        format!("<ferrobot.Base of {:?}>", self.robot.name())
    }
}
