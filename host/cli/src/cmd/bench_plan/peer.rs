//! OMPL on the same problems: the Python peer `host/planning/peer/plan_peer.py` run on the
//! export (RRTConnect with simplification, our time limit, seed and extension step), its
//! summary JSON compared with ours.

use std::path::{Path, PathBuf};
use std::process::Command;

use ferrobot::Error;

/// An error of the peer, with how to install it.
fn peer_error(why: String) -> Error {
    Error::Io(std::io::Error::other(format!(
        "the OMPL peer: {why}; `scripts/python-env.sh plan` installs OMPL and FCL into \
         target/py-venv (or set FERROBOT_PYTHON to a Python that has them)"
    )))
}

/// Checks, before any planning, that the peer's Python has OMPL and FCL.
pub(super) fn preflight() -> ferrobot::Result<()> {
    let python = ferrobot_peers::python();
    let out = Command::new(&python)
        .args(["-c", "import ompl.geometric, fcl, numpy"])
        .output()
        .map_err(|e| peer_error(format!("cannot run {}: {e}", python.display())))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().rev().find(|l| !l.trim().is_empty());
        return Err(peer_error(format!(
            "{} cannot import OMPL and FCL: {}",
            python.display(),
            last.unwrap_or("no message")
        )));
    }
    Ok(())
}

/// Runs OMPL's RRTConnect (the peer, with simplification) on the export at `path` with our
/// time limit (s), seed and extension step (rad; `None`: OMPL's default, as ours); its
/// summary.
fn run_peer(
    path: &Path,
    time_limit: f64,
    seed: u64,
    range: Option<f64>,
) -> ferrobot::Result<serde_json::Value> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../planning/peer/plan_peer.py");
    if !script.is_file() {
        return Err(peer_error(format!("{} is missing", script.display())));
    }
    let python = ferrobot_peers::python();
    let out = Command::new(&python)
        .arg(&script)
        .arg("ompl")
        .arg(path)
        .arg("--simplify")
        .args(["--time-limit", &time_limit.to_string()])
        // OMPL's seed is 32-bit.
        .args(["--seed", &(seed % (1 << 31)).to_string()])
        .args(["--range", &range.unwrap_or(0.0).to_string()])
        .output()
        .map_err(|e| peer_error(format!("cannot run {}: {e}", python.display())))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("no message");
        return Err(peer_error(format!(
            "{} failed ({}): {last}",
            python.display(),
            out.status
        )));
    }
    serde_json::from_slice(&out.stdout)
        .map_err(|e| peer_error(format!("its output is not JSON: {e}")))
}

/// Cleans up a temporary directory when dropped.
pub(super) struct TempDir(pub(super) PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// OMPL's summary of the export at `path` ([`run_peer`]), with `ratio_median`: its median
/// time over ours (`ours_median_ms`), or null.
pub(super) fn compare(
    path: &Path,
    time_limit: f64,
    seed: u64,
    range: Option<f64>,
    ours_median_ms: f64,
) -> ferrobot::Result<serde_json::Value> {
    let mut v = run_peer(path, time_limit, seed, range)?;
    let theirs = v["time_ms"]["median"].as_f64();
    let ratio = theirs.map(|t| t / ours_median_ms).and_then(super::finite);
    if let Some(o) = v.as_object_mut() {
        o.insert("ratio_median".into(), serde_json::json!(ratio));
    }
    Ok(v)
}
