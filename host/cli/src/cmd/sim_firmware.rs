//! `ferrobot sim-firmware`: a simulated robot's firmware core served on a PTY, and its world's
//! camera on the Unix socket beside it.

use std::path::PathBuf;
use std::sync::Arc;

use ferrobot::scene::{Scene, SceneSource};

use super::common::load;

/// `ferrobot sim-firmware`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Path of the symlink to create.
    #[arg(long)]
    pub link: std::path::PathBuf,
    /// Seed of the plants' noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The world: a bundled scene or a scene file (default: empty).
    #[arg(long, default_value = "empty")]
    pub scene: String,
    /// Exact depth from the camera (no stereo noise).
    #[arg(long)]
    pub no_noise: bool,
}

/// Serve the firmware core of the simulated robot (plants seeded by `--seed`, in real time,
/// in the scene) on a PTY behind the symlink `--link`, and its camera (if it has one) on the
/// Unix socket `LINK.camera`, until standard input closes.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let (link, seed, scene, noise): (PathBuf, u64, &str, bool) =
        (a.link.clone(), a.seed, &a.scene, !a.no_noise);
    let cfg = load(&a.robot)?;
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
