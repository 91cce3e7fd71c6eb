//! `ferrobot calibrate-odometry`: the simulated base's odometry, calibrated against ground
//! truth; also the calibration's JSON and text for `bench base --calibrate`.

use ferrobot::odometry_calibration::WheelGeometry;
use ferrobot_cli::odometry_calibration::OdometryCalibration;
use serde::Serialize;

use super::common::print_json;

/// A calibration as JSON (`odometry_calibration` of `bench base --calibrate --json`), fields
/// in alphabetical order, here and below (see [`print_json`]).
#[derive(Serialize)]
pub struct CalibrationJson {
    /// The least-squares estimate.
    estimate: GeometryJson,
    /// The configuration's geometry.
    nominal: GeometryJson,
    /// RMS misfit per run with the estimate.
    residual: ResidualJson,
    /// RMS misfit per run with the nominal geometry.
    residual_nominal: ResidualJson,
    /// Runs the estimate was fitted to.
    runs: usize,
}

impl CalibrationJson {
    /// The JSON of `c`.
    pub fn new(c: &OdometryCalibration) -> Self {
        CalibrationJson {
            estimate: GeometryJson::new(&c.estimate),
            nominal: GeometryJson::new(&c.nominal),
            residual: ResidualJson::new(c.residual),
            residual_nominal: ResidualJson::new(c.residual_nominal),
            runs: c.runs,
        }
    }
}

/// `calibrate-odometry --json`: the calibration, with the robot and the seed.
#[derive(Serialize)]
struct CalibrateOdometryJson<'a> {
    /// See [`CalibrationJson`].
    estimate: GeometryJson,
    /// See [`CalibrationJson`].
    nominal: GeometryJson,
    /// See [`CalibrationJson`].
    residual: ResidualJson,
    /// See [`CalibrationJson`].
    residual_nominal: ResidualJson,
    /// The robot.
    robot: &'a str,
    /// See [`CalibrationJson`].
    runs: usize,
    /// Seed of the plants' noise.
    seed: u64,
}

/// A differential drive's geometry, m.
#[derive(Serialize)]
struct GeometryJson {
    /// Left wheel radius.
    left_radius: f64,
    /// Right wheel radius.
    right_radius: f64,
    /// Wheel separation.
    track: f64,
}

impl GeometryJson {
    /// The JSON of `g`.
    fn new(g: &WheelGeometry) -> Self {
        GeometryJson {
            left_radius: g.left_radius,
            right_radius: g.right_radius,
            track: g.track,
        }
    }
}

/// An RMS misfit of odometry against ground truth per run.
#[derive(Serialize)]
struct ResidualJson {
    /// Heading, rad.
    heading_rad: f64,
    /// Position, m.
    position_m: f64,
}

impl ResidualJson {
    /// The JSON of `(position m, heading rad)`.
    fn new((position_m, heading_rad): (f64, f64)) -> Self {
        ResidualJson {
            heading_rad,
            position_m,
        }
    }
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

/// `ferrobot calibrate-odometry`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Seed of the plants' noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Calibrate the odometry of the simulated robot (plants seeded by `--seed`) and print the
/// estimate.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let (robot, seed) = (a.robot.as_str(), a.seed);
    let c = ferrobot_cli::odometry_calibration::calibrate_odometry(robot, seed)?;
    if a.json {
        let c = CalibrationJson::new(&c);
        print_json(&CalibrateOdometryJson {
            estimate: c.estimate,
            nominal: c.nominal,
            residual: c.residual,
            residual_nominal: c.residual_nominal,
            robot,
            runs: c.runs,
            seed,
        });
    } else {
        say!("{robot}, seed {seed}: {}", calibration_text(&c));
    }
    Ok(())
}
