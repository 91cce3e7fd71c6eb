//! Odometry calibration of a simulated base: UMBmark's squares both ways and a 2 m line,
//! measured by the simulator's ground truth, the wheel geometry fitted by least squares (m,
//! rad).

use ferrobot::error::Result;
use ferrobot::odometry_calibration::{self as cal, CalibrationRun, WheelGeometry};

use crate::base_trials::{base_robot, truth};

/// The result of calibrating a simulated base's odometry.
#[derive(Debug, Clone, PartialEq)]
pub struct OdometryCalibration {
    /// The nominal geometry of the configuration.
    pub nominal: WheelGeometry,
    /// The least-squares estimate.
    pub estimate: WheelGeometry,
    /// The runs it was estimated from.
    pub runs: usize,
    /// RMS misfit over the runs of odometry with the nominal geometry: position (m),
    /// heading (rad).
    pub residual_nominal: (f64, f64),
    /// The same with the estimate.
    pub residual: (f64, f64),
}

/// The calibration protocol's moves, relative `[x, y, θ]`: UMBmark's 1 m square
/// counter-clockwise and clockwise, one run per leg, then 2 m out and back.
pub const CALIBRATION_MOVES: [[f64; 3]; 10] = {
    use std::f64::consts::FRAC_PI_2;
    [
        [1.0, 0.0, FRAC_PI_2],
        [1.0, 0.0, FRAC_PI_2],
        [1.0, 0.0, FRAC_PI_2],
        [1.0, 0.0, FRAC_PI_2],
        [1.0, 0.0, -FRAC_PI_2],
        [1.0, 0.0, -FRAC_PI_2],
        [1.0, 0.0, -FRAC_PI_2],
        [1.0, 0.0, -FRAC_PI_2],
        [2.0, 0.0, 0.0],
        [-2.0, 0.0, 0.0],
    ]
};

/// Calibrate the odometry of the simulated `robot` (plants seeded by `seed`): drive
/// [`CALIBRATION_MOVES`] with the configuration's controller on nominal odometry, log the
/// wheel angles of each, measure its start and end with the simulator's ground truth (a
/// motion-capture system on a real base), and fit the geometry by least squares
/// ([`ferrobot::odometry_calibration`]).
pub fn calibrate_odometry(robot: &str, seed: u64) -> Result<OdometryCalibration> {
    let bot = base_robot(robot, seed, None)?;
    let nominal = bot.base()?.odometry_geometry();
    let mut runs = Vec::new();
    for m in CALIBRATION_MOVES {
        let start = truth(&bot)?;
        let base = bot.base()?;
        base.start_wheel_log()?;
        base.go_to_relative(m)?;
        let wheels = base.take_wheel_log()?;
        let end = truth(&bot)?;
        runs.push(CalibrationRun { wheels, start, end });
    }
    let estimate = cal::estimate(&runs, &nominal)?;
    Ok(OdometryCalibration {
        nominal,
        estimate,
        runs: runs.len(),
        residual_nominal: cal::residuals(&runs, &nominal),
        residual: cal::residuals(&runs, &estimate),
    })
}
