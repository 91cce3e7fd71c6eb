//! `ferrobot calibrate-camera`: hand-eye calibration of the head camera against the marker on
//! the gripper ([`ferrobot_skills::hand_eye`]), with the simulated camera mounted off its URDF pose
//! by `--perturb`; prints how far the fitted mount lies from the true one and writes the
//! calibration file (`--out`) that robots are then built with
//! (`RobotBuilder::camera_calibration`).

use std::path::Path;

use ferrobot::config::CameraCalibration;
use ferrobot::RobotBuilder;
use ferrobot_skills::{HandEyeOptions, Skills};
use serde::Serialize;

use super::common::{print_json, robot_builder, BackendArgs};

/// `calibrate-camera --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct CalibrateJson {
    /// Images taken.
    captured: usize,
    /// Images the fit kept.
    images: usize,
    /// Root-mean-square reprojection error of the kept images' marker corners, px.
    reprojection_rms_px: f64,
    /// Angle between the fitted and the true camera link orientations, degrees.
    rotation_error_deg: f64,
    /// Images in which the marker was found.
    seen: usize,
    /// Distance between the fitted and the true camera link origins, m.
    translation_error_m: f64,
}

/// `ferrobot calibrate-camera`'s arguments: what to calibrate, and how.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// The simulated camera's mount error DX DY DZ DROLL DPITCH DYAW (m and rad, in the camera
    /// link's frame; each within 0.1 m and 0.5 rad).
    #[arg(long, num_args = 6, allow_negative_numbers = true,
          value_names = ["DX", "DY", "DZ", "DROLL", "DPITCH", "DYAW"])]
    pub perturb: Option<Vec<f64>>,
    /// Arm poses holding the marker (1-6).
    #[arg(long, default_value_t = 6)]
    pub poses: usize,
    /// Head grid side: GRID x GRID pan/tilt views per arm pose (1-5).
    #[arg(long, default_value_t = 3)]
    pub grid: usize,
    /// Scene name or path.
    #[arg(long, default_value = "empty")]
    pub scene: String,
    /// Where the robot runs.
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Write the calibration (TOML) here, for `RobotBuilder::camera_calibration`.
    #[arg(long)]
    pub out: Option<std::path::PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Calibrate and report.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let p = a.perturb.as_deref().unwrap_or(&[0.0; 6]);
    // The simulated camera's mount error `[dx, dy, dz, droll, dpitch, dyaw]`, m and rad.
    let perturb = [p[0], p[1], p[2], p[3], p[4], p[5]];
    let out_file = a.out.as_deref();
    let opts = HandEyeOptions::with_counts(a.poses, a.grid)?;
    if let Some(out) = out_file {
        check_out(out)?;
    }
    let builder: RobotBuilder = robot_builder(&a.robot)
        .backend(a.backend.backend()?)
        .scene(&a.scene)
        .camera_mount_error(perturb)
        .calibration_marker(true);
    let bot = builder.build()?;
    let nominal = bot
        .config()
        .camera_mount()
        .ok_or_else(|| ferrobot::Error::NoComponent {
            robot: bot.name().to_string(),
            component: "camera mount",
        })?;
    let report = bot.calibrate_camera(&opts)?;
    let truth = nominal.pose * ferrobot::mount_error_pose(&perturb);
    let fitted = report.calibration.pose();
    let error = truth.inverse() * fitted;
    if let Some(out) = out_file {
        write(&report.calibration, out)?;
    }
    let j = CalibrateJson {
        captured: report.captured,
        images: report.used,
        reprojection_rms_px: report.rms_px,
        rotation_error_deg: error.rotation.angle().to_degrees(),
        seen: report.seen,
        translation_error_m: (fitted.translation.vector - truth.translation.vector).norm(),
    };
    if a.json {
        print_json(&j);
    } else {
        let t = fitted.translation.vector;
        let q = fitted.rotation.coords;
        say!(
            "{} -> {}: xyz [{:.5}, {:.5}, {:.5}] m, quaternion [{:.6}, {:.6}, {:.6}, {:.6}]",
            nominal.parent,
            nominal.child,
            t.x,
            t.y,
            t.z,
            q.x,
            q.y,
            q.z,
            q.w
        );
        say!(
            "images: {} taken, marker seen in {}, {} kept; reprojection rms {:.3} px",
            j.captured,
            j.seen,
            j.images,
            j.reprojection_rms_px
        );
        say!(
            "against the true mount: {:.3} mm, {:.4} deg",
            j.translation_error_m * 1e3,
            j.rotation_error_deg
        );
        for why in &report.missed {
            say!("marker not seen: {why}");
        }
        if let Some(out) = out_file {
            say!("calibration written to {}", out.display());
        }
    }
    Ok(())
}

/// Refuses, before the robot moves, to write the calibration to a directory or to a file in
/// no directory.
fn check_out(out: &Path) -> ferrobot::Result<()> {
    let dir = out.parent().filter(|d| !d.as_os_str().is_empty());
    if out.is_dir() || dir.is_some_and(|d| !d.is_dir()) {
        return Err(ferrobot::Error::Config {
            file: out.to_path_buf(),
            key: "-".into(),
            problem: "cannot write the calibration there (a directory, or no such directory)"
                .into(),
        });
    }
    Ok(())
}

/// Writes the calibration file.
fn write(c: &CameraCalibration, out: &Path) -> ferrobot::Result<()> {
    c.save(out).map_err(|e| ferrobot::Error::Config {
        file: out.to_path_buf(),
        key: "-".into(),
        problem: format!("cannot write the calibration: {e}"),
    })
}
