//! `ferrobot sim-firmware`: a simulated robot's firmware core served on a PTY, and its world's
//! camera on the Unix socket beside it.

use std::path::PathBuf;
use std::sync::Arc;

use ferrobot::scene::{Scene, SceneSource};

use super::common::load;

/// Serve the firmware core of the simulated `robot` (plants seeded by `seed`, in real time,
/// in `scene`) on a PTY behind the symlink `link`, and its camera (if it has one) on the Unix
/// socket `LINK.camera`, until standard input closes.
pub fn run(
    robot: &str,
    link: PathBuf,
    seed: u64,
    scene: &str,
    noise: bool,
) -> ferrobot::Result<()> {
    let cfg = load(robot)?;
    let scene = Arc::new(Scene::load(&SceneSource::from_arg(scene))?);
    let sim = ferrobot_sim::LockstepSim::with_scene(
        ferrobot::backend::sim::sim_robot(&cfg),
        ferrobot::profile::firmware_profile(&cfg),
        seed,
        scene,
    )?;
    let camera = cfg
        .camera
        .clone()
        .map(|section| ferrobot_sim::camera_server::CameraOptions {
            section,
            seed,
            noise,
            mount_error: nalgebra::Isometry3::identity(),
            marker: false,
        });
    ferrobot_sim::firmware_server::run_firmware_server(sim, &cfg.name, link, camera).map_err(|e| {
        match e {
            ferrobot_sim::serve::ServeError::LinkExists(path) => {
                ferrobot::Error::PathExists { path }
            }
            e => ferrobot::Error::Link(e.to_string()),
        }
    })
}
