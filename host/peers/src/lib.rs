//! The Python peers that Ferrobot's tests and benchmarks compare against: ROBOTIS' Dynamixel
//! SDK, OMPL with FCL (planning), scikit-learn (clustering), PyBullet (rendering). They live
//! in one virtual environment, `target/py-venv` at the workspace's root, which
//! `scripts/python-env.sh [plan|cluster|bench]` makes and `scripts/test.sh` fills; the
//! variable `FERROBOT_PYTHON` names another interpreter instead.
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

/// The interpreter a benchmark uses for a peer: [`python`] when it imports `modules`, else
/// `None` (the benchmark reports the peer as not run).
pub fn for_bench(modules: &str) -> Option<PathBuf> {
    let py = python();
    can_import(&py, modules).then_some(py)
}

#[cfg(test)]
mod tests {
    use super::*;

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
