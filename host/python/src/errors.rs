//! Rust errors as Python exceptions: every [`ferrobot::Error`] variant becomes the class of the
//! same name in `ferrobot.errors` (defined in Python, so that a class can also be a
//! `ValueError` or an `OSError`), its fields as the exception's attributes.

use ferrobot::Error;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyModule};
use pyo3::BoundObject;

/// The module of the exception classes.
static ERRORS: PyOnceLock<Py<PyModule>> = PyOnceLock::new();

/// A field of an exception: its name and value.
type Field = (&'static str, Py<PyAny>);

/// `ferrobot.errors`' class `name` raised with `message` and `fields` (the base class
/// `Error` when the module has no such class).
pub fn raise(py: Python<'_>, name: &str, message: String, fields: Vec<Field>) -> PyErr {
    let build = || -> PyResult<PyErr> {
        let module =
            ERRORS.get_or_try_init(py, || py.import("ferrobot.errors").map(|m| m.unbind()))?;
        let module = module.bind(py);
        let class = module.getattr(name).or_else(|_| module.getattr("Error"))?;
        let kwargs = PyDict::new(py);
        for (k, v) in fields {
            kwargs.set_item(k, v)?;
        }
        let value = class.call((message,), Some(&kwargs))?;
        Ok(PyErr::from_value(value))
    };
    build().unwrap_or_else(|e| e)
}

/// `InvalidArgument`: a value of the wrong type or shape.
pub fn invalid(py: Python<'_>, argument: &str, expected: &str, got: String) -> PyErr {
    raise(
        py,
        "InvalidArgument",
        format!("{argument}: expected {expected}, got {got}"),
        vec![
            ("argument", obj(py, argument)),
            ("expected", obj(py, expected)),
            ("got", obj(py, got)),
        ],
    )
}

fn obj<'py, T: IntoPyObject<'py>>(py: Python<'py>, v: T) -> Py<PyAny> {
    match v.into_pyobject(py) {
        Ok(b) => b.into_any().unbind(),
        Err(_) => py.None(),
    }
}

/// The fields of an exception from variables of the same names.
macro_rules! fields {
    ($py:expr; $($k:ident),*) => { vec![$((stringify!($k), obj($py, $k))),*] };
}

/// The Python exception of a Rust API error.
pub fn to_py(py: Python<'_>, e: Error) -> PyErr {
    let message = e.to_string();
    let (name, fields): (&str, Vec<Field>) = match e {
        Error::UnknownRobot { name, known } => ("UnknownRobot", fields![py; name, known]),
        Error::Config { file, key, problem } => {
            let file = file.display().to_string();
            ("Config", fields![py; file, key, problem])
        }
        Error::NoComponent { robot, component } => ("NoComponent", fields![py; robot, component]),
        Error::JointCount {
            what,
            expected,
            got,
        } => ("JointCount", fields![py; what, expected, got]),
        Error::NotFinite { what, value } => ("NotFinite", fields![py; what, value]),
        Error::OutOfRange {
            what,
            value,
            min,
            max,
        } => ("OutOfRange", fields![py; what, value, min, max]),
        Error::OutOfLimits {
            joint,
            value,
            min,
            max,
        } => ("OutOfLimits", fields![py; joint, value, min, max]),
        Error::Unreachable { why } => ("Unreachable", fields![py; why]),
        Error::InvalidMap { why } => ("InvalidMap", fields![py; why]),
        Error::Calibration { why } => ("Calibration", fields![py; why]),
        Error::StalePlan { why } => ("StalePlan", fields![py; why]),
        Error::UnknownName { what, name } => ("UnknownName", fields![py; what, name]),
        Error::Timeout { what, after } => {
            let after = after.as_secs_f64();
            ("Timeout", fields![py; what, after])
        }
        Error::Stalled {
            joint,
            position,
            error,
        } => ("Stalled", fields![py; joint, position, error]),
        Error::Rejected { what, reason } => {
            let reason = format!("{reason:?}");
            ("Rejected", fields![py; what, reason])
        }
        Error::EmergencyStop => ("EmergencyStop", vec![]),
        Error::Cancelled => ("Cancelled", vec![]),
        Error::Preempted { what } => ("Preempted", fields![py; what]),
        Error::Fault { kind, detail } => {
            let kind = format!("{kind:?}");
            ("Fault", fields![py; kind, detail])
        }
        Error::VersionMismatch {
            host,
            host_schema,
            firmware,
            firmware_schema,
        } => (
            "VersionMismatch",
            fields![py; host, host_schema, firmware, firmware_schema],
        ),
        Error::WrongRobot {
            config,
            config_base,
            firmware,
            firmware_base,
        } => (
            "WrongRobot",
            fields![py; config, config_base, firmware, firmware_base],
        ),
        Error::SlamLost { frames } => ("SlamLost", fields![py; frames]),
        Error::HardwareCheck { faults, table } => ("HardwareCheck", fields![py; faults, table]),
        Error::PathExists { path } => {
            let path = path.display().to_string();
            ("PathExists", fields![py; path])
        }
        other => detail_fields(py, other),
    };
    raise(py, name, message, fields)
}

/// The variants that wrap another error or a message: `detail`, its text.
fn detail_fields(py: Python<'_>, e: Error) -> (&'static str, Vec<Field>) {
    match e {
        Error::JointTableMismatch(detail) => detail_of("JointTableMismatch", py, detail),
        Error::Link(detail) => detail_of("Link", py, detail),
        Error::Usage(detail) => detail_of("Usage", py, detail),
        Error::Scene(e) => detail_of("Scene", py, e.to_string()),
        Error::Perception(e) => detail_of("Perception", py, e.to_string()),
        Error::Planning(e) => detail_of("Planning", py, e.to_string()),
        Error::Navigation(e) => detail_of("Navigation", py, e.to_string()),
        Error::Slam(e) => detail_of("Slam", py, e.to_string()),
        Error::Io(e) => detail_of("Io", py, e.to_string()),
        // A variant added later: the base class, with its message.
        _ => ("Error", vec![]),
    }
}

fn detail_of(name: &'static str, py: Python<'_>, detail: String) -> (&'static str, Vec<Field>) {
    (name, vec![("detail", obj(py, detail))])
}

/// The Python exception of a skill's error (the robot's own, or why a grasp failed).
pub fn skill_to_py(py: Python<'_>, e: ferrobot_skills::Error) -> PyErr {
    match e {
        ferrobot_skills::Error::Robot(e) => to_py(py, e),
        other => {
            let message = other.to_string();
            raise(
                py,
                "Skill",
                message.clone(),
                vec![("detail", obj(py, message))],
            )
        }
    }
}

/// `.py()?`: a Rust API result as a Python one.
pub trait OrRaise<T> {
    /// The value, or the error as its Python exception.
    fn py(self) -> PyResult<T>;
}

impl<T> OrRaise<T> for ferrobot::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(|e| Python::attach(|py| to_py(py, e)))
    }
}

impl<T> OrRaise<T> for ferrobot_skills::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(|e| Python::attach(|py| skill_to_py(py, e)))
    }
}
