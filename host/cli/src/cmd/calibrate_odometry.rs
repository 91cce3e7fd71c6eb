//! `ferrobot calibrate-odometry`: the simulated base's odometry, calibrated against ground
//! truth; also the calibration's JSON and text for `bench base --calibrate`.

use ferrobot_cli::bench_base::OdometryCalibration;
use serde_json::json;

/// The calibration as JSON.
pub fn calibration_json(c: &OdometryCalibration) -> serde_json::Value {
    let g = |g: &ferrobot::odometry_calibration::WheelGeometry| json!({"left_radius": g.left_radius, "right_radius": g.right_radius, "track": g.track});
    json!({
        "nominal": g(&c.nominal),
        "estimate": g(&c.estimate),
        "runs": c.runs,
        "residual_nominal": {"position_m": c.residual_nominal.0, "heading_rad": c.residual_nominal.1},
        "residual": {"position_m": c.residual.0, "heading_rad": c.residual.1},
    })
}

/// The calibration as text, ending with the configuration line.
pub fn calibration_text(c: &OdometryCalibration) -> String {
    let (n, e) = (&c.nominal, &c.estimate);
    let pct = |x: f64, y: f64| 100.0 * (x / y - 1.0);
    format!(
        "odometry calibration from {} runs measured by ground truth:\n\
         - left radius  {:.5} m ({:+.2} % of nominal {:.5})\n\
         - right radius {:.5} m ({:+.2} % of nominal {:.5})\n\
         - track        {:.5} m ({:+.2} % of nominal {:.5})\n\
         - RMS misfit per run: nominal {:.1} mm / {:.2} deg, calibrated {:.1} mm / {:.2} deg\n\
         [base] line: odometry = {{ left_radius = {:.6}, right_radius = {:.6}, track = {:.6} }}",
        c.runs,
        e.left_radius,
        pct(e.left_radius, n.left_radius),
        n.left_radius,
        e.right_radius,
        pct(e.right_radius, n.right_radius),
        n.right_radius,
        e.track,
        pct(e.track, n.track),
        n.track,
        c.residual_nominal.0 * 1000.0,
        c.residual_nominal.1.to_degrees(),
        c.residual.0 * 1000.0,
        c.residual.1.to_degrees(),
        e.left_radius,
        e.right_radius,
        e.track
    )
}

/// Calibrate the odometry of the simulated `robot` (plants seeded by `seed`) and print the
/// estimate.
pub fn run(robot: &str, seed: u64, json: bool) -> ferrobot::Result<()> {
    let c = ferrobot_cli::bench_base::calibrate_odometry(robot, seed)?;
    if json {
        let mut o = calibration_json(&c);
        o["robot"] = json!(robot);
        o["seed"] = json!(seed);
        println!("{o}");
    } else {
        println!("{robot}, seed {seed}: {}", calibration_text(&c));
    }
    Ok(())
}
