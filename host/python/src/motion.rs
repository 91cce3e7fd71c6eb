//! Blocking calls that Ctrl-C interrupts, and [`Motion`], what `wait=False` returns.
//!
//! A blocking call runs without the GIL (other Python threads run meanwhile) and looks for a
//! signal every [`SIGNAL_POLL`]: on Ctrl-C the robot's motions are cancelled (joints hold, the
//! base stops; nothing latches) and `KeyboardInterrupt` is raised once the call has ended.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use ferrobot::Robot;
use parking_lot::Mutex;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

use crate::errors::OrRaise;

/// How often a blocking call looks for a signal (Ctrl-C), wall-clock.
pub const SIGNAL_POLL: Duration = Duration::from_millis(10);

/// Runs `f`, a blocking call of the Rust API, on a worker thread while this one waits without
/// the GIL, looking for signals every [`SIGNAL_POLL`]. On a signal's exception
/// (`KeyboardInterrupt`) the robot's motions are cancelled, again every [`SIGNAL_POLL`] until
/// `f` returns (a call that starts a new motion after the first cancel, such as a streamed
/// line, is stopped too), and the exception is raised.
pub fn blocking<T, F>(py: Python<'_>, robot: &Robot, f: F) -> PyResult<T>
where
    T: Send + 'static,
    F: FnOnce() -> ferrobot::Result<T> + Send + 'static,
{
    run_blocking(py, robot, move || f().py())
}

/// [`blocking`] for a call whose result is already Python's (a skill's error, a conversion).
pub fn run_blocking<T, F>(py: Python<'_>, robot: &Robot, f: F) -> PyResult<T>
where
    T: Send + 'static,
    F: FnOnce() -> PyResult<T> + Send + 'static,
{
    let (tx, rx) = mpsc::sync_channel(1);
    std::thread::Builder::new()
        .name("ferrobot-call".into())
        .spawn(move || {
            let _ = tx.send(f());
        })
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start a thread: {e}")))?;
    // The receiver is moved into each wait and back (it is not `Sync`).
    let mut rx = Some(rx);
    let mut recv = |py: Python<'_>| {
        let r = rx.take().expect("the receiver is put back after each wait");
        let (got, r) = py.detach(move || (r.recv_timeout(SIGNAL_POLL), r));
        rx = Some(r);
        got
    };
    loop {
        match recv(py) {
            Ok(r) => return r,
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => return Err(died()),
        }
        if let Err(signal) = py.check_signals() {
            loop {
                robot.cancel_motions();
                match recv(py) {
                    Ok(_) | Err(mpsc::RecvTimeoutError::Disconnected) => return Err(signal),
                    Err(mpsc::RecvTimeoutError::Timeout) => {}
                }
            }
        }
    }
}

fn died() -> PyErr {
    PyRuntimeError::new_err(
        "ferrobot: the call's thread ended without a result (a bug: please report it)",
    )
}

/// How a finished motion ended.
enum Outcome {
    Ok,
    Failed(PyErr),
}

/// A motion under way, returned by the calls given `wait=False`: `wait(timeout)`, `done()`,
/// `cancel()`. In the simulator, time passes only while a program waits (a motion's `wait` or
/// `done`, `Robot.wait`), as it does for the Rust API.
#[pyclass(frozen, module = "ferrobot._native")]
pub struct Motion {
    robot: Robot,
    what: String,
    motion: Mutex<Option<ferrobot::Motion>>,
    outcome: Mutex<Option<Outcome>>,
}

impl Motion {
    /// Wraps a motion of the Rust API; `what` names it in `repr`.
    pub fn new(robot: &Robot, what: &str, motion: ferrobot::Motion) -> Self {
        Motion {
            robot: robot.clone(),
            what: what.into(),
            motion: Mutex::new(Some(motion)),
            outcome: Mutex::new(None),
        }
    }

    /// Waits with no time limit (Ctrl-C cancels): what the calls given `wait=True` do.
    pub fn wait_blocking(&self, py: Python<'_>) -> PyResult<bool> {
        self.wait(py, None)
    }

    /// Lets [`ferrobot::motion::POLL`] pass; the result once finished.
    fn poll(&self) -> Option<ferrobot::Result<()>> {
        let mut guard = self.motion.lock();
        let m = guard.as_mut()?;
        m.poll()?;
        guard.take().map(|m| m.wait())
    }

    /// The stored outcome, as Python's result.
    fn result(&self, py: Python<'_>) -> Option<PyResult<bool>> {
        match &*self.outcome.lock() {
            None => None,
            Some(Outcome::Ok) => Some(Ok(true)),
            Some(Outcome::Failed(e)) => Some(Err(e.clone_ref(py))),
        }
    }

    fn finish(&self, py: Python<'_>, r: ferrobot::Result<()>) -> PyResult<bool> {
        let outcome = match r.py() {
            Ok(()) => Outcome::Ok,
            Err(e) => Outcome::Failed(e),
        };
        *self.outcome.lock() = Some(outcome);
        self.result(py).unwrap_or(Ok(true))
    }
}

#[pymethods]
impl Motion {
    /// Wait until the motion ends, at most `timeout` seconds of wall-clock time (`None`: no
    /// limit). True when it ended well; False when `timeout` passed first; the motion's error
    /// (a `ferrobot.Error`) when it failed. Ctrl-C cancels it and raises `KeyboardInterrupt`.
    #[pyo3(signature = (timeout=None))]
    fn wait(&self, py: Python<'_>, timeout: Option<f64>) -> PyResult<bool> {
        let deadline = match timeout {
            None => None,
            Some(t) if (0.0..=ferrobot::validate::MAX_DURATION_S).contains(&t) => {
                Some(Instant::now() + Duration::from_secs_f64(t))
            }
            Some(t) => {
                return Err(crate::errors::invalid(
                    py,
                    "timeout",
                    &format!(
                        "seconds in [0, {}], or None",
                        ferrobot::validate::MAX_DURATION_S
                    ),
                    format!("{t}"),
                ))
            }
        };
        loop {
            if let Some(r) = self.result(py) {
                return r;
            }
            if let Some(r) = py.detach(|| self.poll()) {
                return self.finish(py, r);
            }
            if let Err(signal) = py.check_signals() {
                self.robot.cancel_motions();
                *self.outcome.lock() = Some(Outcome::Failed(signal.clone_ref(py)));
                return Err(signal);
            }
            if deadline.is_some_and(|d| Instant::now() >= d) {
                return Ok(false);
            }
        }
    }

    /// Whether the motion has ended (well or not). In the simulator each call lets 10 ms of
    /// simulated time pass, so that a loop of `done()` moves the robot.
    fn done(&self, py: Python<'_>) -> PyResult<bool> {
        if self.outcome.lock().is_some() {
            return Ok(true);
        }
        match py.detach(|| self.poll()) {
            Some(r) => {
                // A failure is raised by `wait()`, not here.
                let _ = self.finish(py, r);
                Ok(true)
            }
            None => Ok(false),
        }
    }

    /// Stop the motion where it is (joints hold, the base stops); `wait()` then raises
    /// `ferrobot.Cancelled`. Nothing happens to a motion that has ended.
    fn cancel(&self, py: Python<'_>) -> PyResult<()> {
        let m = self.motion.lock().take();
        if let Some(m) = m {
            m.cancel().py()?;
            let e = ferrobot::Error::Cancelled;
            *self.outcome.lock() = Some(Outcome::Failed(crate::errors::to_py(py, e)));
        }
        Ok(())
    }

    fn __repr__(&self) -> String {
        let state = match &*self.outcome.lock() {
            None => "under way",
            Some(Outcome::Ok) => "done",
            Some(Outcome::Failed(_)) => "failed",
        };
        format!("<ferrobot.Motion {} ({state})>", self.what)
    }
}
