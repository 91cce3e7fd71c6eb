//! `ferrobot sim-firmware`: a simulated robot's firmware core served on a PTY.

use std::path::PathBuf;

use super::common::load;

/// Serve the firmware core of the simulated `robot` (plants seeded by `seed`, in real time)
/// on a PTY behind the symlink `link` until standard input closes.
pub fn run(robot: &str, link: PathBuf, seed: u64) -> ferrobot::Result<()> {
    let cfg = load(robot)?;
    let sim = ferrobot_sim::LockstepSim::with(
        ferrobot::backend::sim::sim_robot(&cfg),
        cfg.firmware_profile(),
        seed,
    );
    ferrobot_sim::serve::run_firmware_server(sim, &cfg.name, link).map_err(|e| match e {
        ferrobot_sim::serve::ServeError::LinkExists(path) => ferrobot::Error::PathExists { path },
        e => ferrobot::Error::Link(e.to_string()),
    })
}
