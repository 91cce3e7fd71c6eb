//! `ferrobot record-rgbd ROBOT --scene SCENE --route NAME --out DIR`: a simulated drive along
//! a scene's route written as an RGB-D sequence in the TUM RGB-D benchmark's layout (`rgb/`,
//! `depth/` with 16-bit depth of 5000 units per metre, `rgb.txt`, `depth.txt`,
//! `groundtruth.txt` of the camera's optical frame in the world, `camera.yaml`), which
//! `ferrobot slam --dataset DIR` and other SLAM systems read.

use std::path::Path;

use ferrobot::slam::DatasetWriter;

use super::route::Drive;

/// TUM RGB-D's depth units per metre.
pub const TUM_DEPTH_FACTOR: f64 = 5000.0;

/// `ferrobot record-rgbd`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Scene name or path.
    #[arg(long, default_value = "apartment")]
    pub scene: String,
    /// Route of the scene to drive.
    #[arg(long)]
    pub route: String,
    /// Seed of the plants' and the camera's noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory (must be missing or empty).
    #[arg(long)]
    pub out: std::path::PathBuf,
}

/// Drive and record; prints how many frames went where.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let (robot, scene, route, seed, out): (&str, &str, &str, u64, &Path) =
        (&a.robot, &a.scene, &a.route, a.seed, &a.out);
    if out.exists() && std::fs::read_dir(out)?.next().is_some() {
        return Err(ferrobot::Error::PathExists {
            path: out.to_path_buf(),
        });
    }
    let d = Drive::new(robot, scene, route, seed)?;
    let k = d.bot.camera()?.intrinsics()?;
    let mut w = DatasetWriter::create(out, TUM_DEPTH_FACTOR)?;
    let mut frames = 0;
    d.run(|s| {
        frames += 1;
        w.add(
            s.frame.time.as_secs_f64(),
            &s.frame.rgb,
            &s.frame.depth,
            Some(s.camera_truth),
        )?;
        Ok(())
    })?;
    w.finish(&k)?;
    say!(
        "{frames} frames of {route} in {scene} written to {}",
        out.display()
    );
    Ok(())
}
