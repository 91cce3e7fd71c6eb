//! `ferrobot calibrate-camera`: hand-eye calibration of the head camera against the marker on
//! the gripper ([`ferrobot::hand_eye`]), with the simulated camera mounted off its URDF pose
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

/// What to calibrate, and how.
pub struct CalibrateArgs<'a> {
    /// Robot name or configuration path.
    pub robot: &'a str,
    /// The simulated camera's mount error `[dx, dy, dz, droll, dpitch, dyaw]`, m and rad.
    pub perturb: [f64; 6],
    /// Arm poses (1-6).
    pub poses: usize,
    /// Head grid side (1-5).
    pub grid: usize,
    /// Scene name or path.
    pub scene: &'a str,
    /// Where the robot runs.
    pub backend: &'a BackendArgs,
    /// The calibration file to write.
    pub out: Option<&'a Path>,
    /// Print JSON.
    pub json: bool,
}

/// Calibrate and report.
pub fn run(a: &CalibrateArgs) -> ferrobot::Result<()> {
    let opts = HandEyeOptions::with_counts(a.poses, a.grid)?;
    if let Some(out) = a.out {
        // Refused before the robot moves: a directory, or a file in no directory.
        let dir = out.parent().filter(|d| !d.as_os_str().is_empty());
        if out.is_dir() || dir.is_some_and(|d| !d.is_dir()) {
            return Err(ferrobot::Error::Config {
                file: out.to_path_buf(),
                key: "-".into(),
                problem: "cannot write the calibration there (a directory, or no such directory)"
                    .into(),
            });
        }
    }
    let builder: RobotBuilder = robot_builder(a.robot)
        .backend(a.backend.backend()?)
        .scene(a.scene)
        .camera_mount_error(a.perturb)
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
    let truth = nominal.pose * ferrobot::mount_error_pose(&a.perturb);
    let fitted = report.calibration.pose();
    let error = truth.inverse() * fitted;
    if let Some(out) = a.out {
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
        if let Some(out) = a.out {
            say!("calibration written to {}", out.display());
        }
    }
    Ok(())
}

fn write(c: &CameraCalibration, out: &Path) -> ferrobot::Result<()> {
    c.save(out).map_err(|e| ferrobot::Error::Config {
        file: out.to_path_buf(),
        key: "-".into(),
        problem: format!("cannot write the calibration: {e}"),
    })
}
