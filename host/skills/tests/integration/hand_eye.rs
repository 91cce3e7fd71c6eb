//! Hand-eye calibration on the simulator: the simulated camera is mounted 2 cm and 3° off its
//! URDF pose; calibration against the marker on the gripper recovers the true mount, and a
//! robot built with the calibration file sees the table where it is (and not before).

use ferrobot::config::CameraCalibration;
use ferrobot::{Error, Robot};
use ferrobot_sim::camera::BandedCamera;
use ferrobot_sim::render::RenderedImage;
use ferrobot_skills::{HandEyeOptions, Skills};
use nalgebra::{Isometry3, Point3, Vector3};

/// A 19.7 mm, 2.98° mount error (m, rad).
const PERTURB: [f64; 6] = [0.012, -0.01, 0.012, 0.03, -0.03, 0.03];

fn perturbation() -> Isometry3<f64> {
    ferrobot::mount_error_pose(&PERTURB)
}

/// In `tabletop` with the arm aside and the head down 0.8 rad, exact depth: the median and
/// the 95th percentile distance (m) of the table's pixels, back-projected into `base_link` by
/// the camera API, from the table's surface (a box).
fn table_error(bot: &Robot) -> (f64, f64) {
    bot.arm()
        .unwrap()
        .set_joint_positions(&[1.5, 0.0, 0.0, 0.0, 0.0])
        .unwrap();
    bot.head().unwrap().set_pan_tilt(0.0, 0.8).unwrap();
    let frame = bot.camera().unwrap().get_frame().unwrap();
    // The table's pixels, from a noiseless render of the truth by the same (mis-mounted)
    // camera.
    let (px, table, world_to_base) = {
        let sim = bot.simulator().unwrap();
        let body = sim.body().unwrap().clone();
        let section = bot.config().camera.clone().unwrap();
        let mut cam = BandedCamera::new(sim.scene(), &body, &section, 1, false).unwrap();
        cam.set_mount_error(&body, &perturbation());
        let truth = sim.truth();
        let mut img = RenderedImage::new(section.width, section.height);
        cam.capture_into(&truth, &mut img);
        let w = section.width as usize;
        let px: Vec<(i64, i64)> = (0..img.labels.len())
            .filter(|&i| cam.label_name(img.labels[i]) == Some("table"))
            .map(|i| ((i / w) as i64, (i % w) as i64))
            .collect();
        let i = sim.scene().body_index("table").unwrap();
        let base = truth.links[body.tree.link_index("base_link").unwrap()];
        (px, truth.bodies[i], base.inverse())
    };
    assert!(px.len() > 10_000, "{} table pixels", px.len());
    let rows: Vec<i64> = px.iter().map(|p| p.0).collect();
    let cols: Vec<i64> = px.iter().map(|p| p.1).collect();
    let pts = frame.pixels(&rows, &cols, false).unwrap();
    // The table: a box of 0.45 x 0.8 x 0.1 m.
    let half = Vector3::new(0.225, 0.4, 0.05);
    let to_table = (world_to_base * table).inverse();
    let mut d: Vec<f64> = pts
        .points
        .iter()
        .flatten()
        .map(|p: &Point3<f64>| {
            let q = (to_table * p).coords.abs() - half;
            if q.max() <= 0.0 {
                -q.max()
            } else {
                q.map(|v| v.max(0.0)).norm()
            }
        })
        .collect();
    d.sort_by(f64::total_cmp);
    (d[d.len() / 2], d[d.len() * 95 / 100])
}

/// PyRobot's procedure (6 arm poses times a 3 x 3 head grid, 54 images; 1.5 s): the 2 cm / 3°
/// mount error is recovered within 1 mm and 0.1°, the file written and read back, and a robot
/// built with it puts the table's points within 1 mm of the table's top (median; 2 mm at the
/// 95th percentile), where the uncalibrated robot puts them centimetres off.
#[test]
fn calibration_recovers_the_mount_and_the_camera_uses_it() {
    let bot = Robot::builder("locobot")
        .camera_mount_error(PERTURB)
        .calibration_marker(true)
        .build()
        .unwrap();
    let report = bot.calibrate_camera(&HandEyeOptions::default()).unwrap();
    let nominal = bot.config().camera_mount().unwrap().pose;
    let truth = nominal * perturbation();
    let fitted = report.calibration.pose();
    let e = truth.inverse() * fitted;
    let (dt, dr) = (
        (fitted.translation.vector - truth.translation.vector).norm(),
        e.rotation.angle().to_degrees(),
    );
    println!(
        "{} images, {} seen, {} kept, rms {:.3} px: {:.3} mm, {:.4} deg",
        report.captured,
        report.seen,
        report.used,
        report.rms_px,
        dt * 1e3,
        dr
    );
    assert_eq!(report.captured, 54);
    assert!(report.used >= 50, "{} images used", report.used);
    assert!(report.rms_px < 1.0, "{}", report.rms_px);
    assert!(dt < 1e-3 && dr < 0.1, "{dt} m, {dr} deg");

    let file_dir = tempfile::tempdir().expect("temporary directory");
    let file = file_dir.path().join("hand-eye.toml");
    report.calibration.save(&file).unwrap();
    assert_eq!(CameraCalibration::load(&file).unwrap(), report.calibration);
    let build = |calibrated: bool| {
        let b = Robot::builder("locobot")
            .scene("tabletop")
            .depth_noise(false)
            .camera_mount_error(PERTURB);
        let b = if calibrated {
            b.camera_calibration(&file)
        } else {
            b
        };
        b.build().unwrap()
    };
    let before = table_error(&build(false));
    let after = table_error(&build(true));
    let _ = std::fs::remove_file(&file);
    println!(
        "table top: before {:.2} / {:.2} mm, after {:.2} / {:.2} mm (median / 95 %)",
        before.0 * 1e3,
        before.1 * 1e3,
        after.0 * 1e3,
        after.1 * 1e3
    );
    assert!(before.0 > 0.01, "{before:?}");
    assert!(after.0 < 1e-3 && after.1 < 2e-3, "{after:?}");
}

/// Bad input and a marker that cannot be seen are typed errors; nothing panics.
#[test]
fn bad_input_and_an_unseen_marker_are_typed_errors() {
    // Absurd or non-finite mount errors.
    for p in [
        [f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, f64::INFINITY, 0.0],
        [0.5, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 2.0, 0.0, 0.0],
    ] {
        let e = Robot::builder("locobot")
            .camera_mount_error(p)
            .build()
            .expect_err("refused");
        assert!(e.is_input(), "{e}");
    }
    // Too few poses or a grid out of range.
    assert!(HandEyeOptions::with_counts(0, 2).is_err());
    assert!(HandEyeOptions::with_counts(2, 9).is_err());
    // A missing or malformed calibration file.
    let e = Robot::builder("locobot")
        .camera_calibration("/nonexistent/calibration.toml")
        .build()
        .expect_err("refused");
    assert!(matches!(e, Error::Config { .. }), "{e}");
    let bad_dir = tempfile::tempdir().expect("temporary directory");
    let bad = bad_dir.path().join("bad-cal.toml");
    std::fs::write(
        &bad,
        "robot = \"locobot\"\nparent = \"head_tilt_link\"\nchild = \"camera_link\"\n\
         xyz = [0.0, 0.0, 0.0]\nquaternion = [0.0, 0.0, 0.0, 2.0]\n",
    )
    .unwrap();
    let e = Robot::builder("locobot")
        .camera_calibration(&bad)
        .build()
        .expect_err("refused");
    let _ = std::fs::remove_file(&bad);
    assert!(matches!(e, Error::Config { .. }), "{e}");
    // The head looking away from the marker: never seen.
    let bot = Robot::builder("locobot")
        .calibration_marker(true)
        .build()
        .unwrap();
    let opts = HandEyeOptions {
        arm_poses: vec![vec![0.0, 0.3, 0.3, -0.9, 0.0]],
        pan_offsets: vec![1.0],
        tilt_offsets: vec![-1.0],
        ..HandEyeOptions::default()
    };
    let e = bot.calibrate_camera(&opts).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Perception(ferrobot::perception::PerceptionError::MarkerNotSeen(_))
        ),
        "{e}"
    );
    assert!(!e.is_input());
    // A robot built without its marker shown: never seen either.
    let e = Robot::new("locobot")
        .unwrap()
        .calibrate_camera(&HandEyeOptions::with_counts(1, 1).unwrap())
        .unwrap_err();
    assert!(e.to_string().contains("calibration_marker"), "{e}");
}
