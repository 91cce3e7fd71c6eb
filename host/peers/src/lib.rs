//! The Python peers that Ferrobot's tests and benchmarks compare against: ROBOTIS' Dynamixel
//! SDK, OMPL with FCL (planning), scikit-learn (clustering), PyBullet (rendering), Intel's
//! librealsense (the RealSense server, `realsense/serve_realsense.py` beside this crate). They
//! live in one virtual environment, `target/py-venv` at the workspace's root, which
//! `scripts/python-env.sh [plan|cluster|bench|realsense|...]` makes and `scripts/test.sh`
//! fills; the variable `FERROBOT_PYTHON` names another interpreter instead.
//!
//! One rule for every test that needs a peer: with `FERROBOT_PYTHON` set (as the test command
//! sets it), a peer that cannot be imported fails the test, naming the setup command; without
//! it, the workspace's environment is used when it has the peer, and the test is skipped,
//! saying so, when it has not.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The workspace's root (this crate sits at `host/peers`).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The workspace's virtual environment's interpreter, `target/py-venv/bin/python` (it may not
/// exist).
pub fn venv_python() -> PathBuf {
    workspace_root().join("target/py-venv/bin/python")
}

/// The interpreter for the peers: `FERROBOT_PYTHON` when set and not empty, else
/// [`venv_python`].
pub fn python() -> PathBuf {
    std::env::var_os("FERROBOT_PYTHON")
        .filter(|p| !p.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(venv_python)
}

/// Whether `python` runs and imports every module of `modules` (comma-separated, Python's
/// `import` syntax: `"sklearn.cluster, threadpoolctl"`).
pub fn can_import(python: &Path, modules: &str) -> bool {
    Command::new(python)
        .args(["-c", &format!("import {modules}")])
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
}

/// The interpreter a test uses for a peer, by the [crate]'s rule: `Some` when `FERROBOT_PYTHON`
/// is set (panicking, with `setup` named as the cure, when it cannot import `modules`) or when
/// the workspace's environment imports them; `None` (skip: the reason is printed) otherwise.
/// `setup` is the command that installs the peer, e.g. `scripts/python-env.sh cluster`.
pub fn for_test(modules: &str, setup: &str) -> Option<PathBuf> {
    if let Some(py) = std::env::var_os("FERROBOT_PYTHON").filter(|p| !p.is_empty()) {
        let py = PathBuf::from(py);
        assert!(
            can_import(&py, modules),
            "FERROBOT_PYTHON={} cannot import {modules}; run `{setup}` (scripts/test.sh does)",
            py.display()
        );
        return Some(py);
    }
    let venv = venv_python();
    if can_import(&venv, modules) {
        return Some(venv);
    }
    eprintln!("skipped: no Python that imports {modules} (run `{setup}`)");
    None
}

/// The file in a virtual environment that says PyPI has no wheel of `package` for its
/// platform: `scripts/python-env.sh` writes it (with pip's words) where pip finds none.
pub fn no_wheel_note(python: &Path, package: &str) -> PathBuf {
    // `ENV/bin/python` -> `ENV/.no-wheel-PACKAGE`
    let env = python
        .parent()
        .and_then(Path::parent)
        .unwrap_or(Path::new("."));
    env.join(format!(".no-wheel-{package}"))
}

/// [`for_test`] for a peer whose wheel PyPI has for some platforms only (pyrealsense2): the
/// test is also skipped, saying so, where `scripts/python-env.sh` found no wheel of `package`
/// for this platform ([`no_wheel_note`]), and only then when `FERROBOT_PYTHON` is set (as the
/// test command sets it): anywhere else a peer that cannot be imported fails the test.
pub fn for_test_where_wheels_exist(modules: &str, setup: &str, package: &str) -> Option<PathBuf> {
    let py = python();
    if can_import(&py, modules) {
        return Some(py);
    }
    let note = no_wheel_note(&py, package);
    if let Ok(why) = std::fs::read_to_string(&note) {
        eprintln!(
            "skipped: PyPI has no {package} wheel for this platform ({}: {})",
            note.display(),
            why.trim()
        );
        return None;
    }
    for_test(modules, setup)
}

/// The interpreter a benchmark uses for a peer: [`python`] when it imports `modules`, else
/// `None` (the benchmark reports the peer as not run).
pub fn for_bench(modules: &str) -> Option<PathBuf> {
    let py = python();
    can_import(&py, modules).then_some(py)
}

/// A TCP port free on loopback now, for a test's server to listen on (another process could
/// take it before the server binds it; tests that share a machine take their chances with
/// that, as with any free port).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free loopback port")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_no_wheel_note_sits_in_the_interpreters_environment() {
        assert_eq!(
            no_wheel_note(Path::new("/w/target/py-venv/bin/python"), "pyrealsense2"),
            Path::new("/w/target/py-venv/.no-wheel-pyrealsense2")
        );
    }

    #[test]
    fn a_missing_interpreter_imports_nothing() {
        assert!(!can_import(Path::new("/nonexistent/python"), "sys"));
    }

    #[test]
    fn an_unknown_module_is_not_importable() {
        let py = PathBuf::from("python3");
        assert!(
            can_import(&py, "sys, json"),
            "the system's Python imports sys"
        );
        assert!(!can_import(&py, "no_such_module_ferrobot"));
    }
}
