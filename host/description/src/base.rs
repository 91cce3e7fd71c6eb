//! `[base]`: which mobile base, its nominal and calibrated wheel geometry (m), the limits and
//! tolerances of its position controllers (m, rad, m/s, rad/s) and which controller is the
//! default.

use serde::Deserialize;

use crate::error::{Error, Result};

/// Which base.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BaseModel {
    /// Yujin Kobuki.
    Kobuki,
    /// iRobot Create 2.
    Create2,
}

/// Base position controllers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BaseController {
    /// Rotate, drive, rotate, with velocity ramps.
    Proportional,
    /// Time-varying LQR tracking a reference (sharp or smooth) under the tracking limits.
    Lqr,
    /// Iterative LQR: the reference made dynamically consistent and optimal, then tracked.
    Ilqr,
    /// Dynamic window approach: velocity sampling under acceleration limits, scored on
    /// obstacle clearance, progress to the goal and heading (used when obstacles are given).
    Dwa,
}

impl BaseController {
    /// Every controller, in the benchmark's order.
    pub const ALL: [BaseController; 4] = [
        BaseController::Proportional,
        BaseController::Lqr,
        BaseController::Ilqr,
        BaseController::Dwa,
    ];

    /// The configuration and command-line name.
    pub fn name(self) -> &'static str {
        match self {
            BaseController::Proportional => "proportional",
            BaseController::Lqr => "lqr",
            BaseController::Ilqr => "ilqr",
            BaseController::Dwa => "dwa",
        }
    }
}

impl std::str::FromStr for BaseController {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        BaseController::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| Error::UnknownName {
                what: "base controller",
                name: s.to_string(),
            })
    }
}

/// `[base]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseSection {
    /// Which base.
    pub kind: BaseModel,
    /// Nominal wheel radius, m.
    pub wheel_radius: f64,
    /// Nominal wheel separation, m.
    pub track: f64,
    /// Radius of the base's footprint, m (obstacle clearance of the dynamic window).
    pub footprint_radius: f64,
    /// Smallest wheel speed that surely moves the wheels (just above their deadband), m/s:
    /// the creep speed of the finisher after LQR position goals.
    pub min_wheel_speed: f64,
    /// Largest forward speed of position controllers, m/s.
    pub max_linear: f64,
    /// Largest yaw rate of position controllers, rad/s.
    pub max_angular: f64,
    /// Default position controller.
    pub controller: BaseController,
    /// Position tolerance of position controllers, m.
    #[serde(default = "default_translation_tol")]
    pub translation_tolerance: f64,
    /// Heading tolerance of position controllers, rad.
    #[serde(default = "default_rotation_tol")]
    pub rotation_tolerance: f64,
    /// Calibrated odometry geometry, e.g. `odometry = { left_radius = 0.03617,
    /// right_radius = 0.03628, track = 0.2372 }` (m), as `ferrobot calibrate-odometry` prints
    /// it; each value within 10 % of the nominal one. Absent: the nominal `wheel_radius` and
    /// `track`.
    #[serde(default)]
    pub odometry: Option<OdometrySection>,
}

fn default_translation_tol() -> f64 {
    0.01
}
fn default_rotation_tol() -> f64 {
    1f64.to_radians()
}

/// `[base] odometry`: the wheel geometry an odometry calibration measured, m.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OdometrySection {
    /// Left wheel radius, m.
    pub left_radius: f64,
    /// Right wheel radius, m.
    pub right_radius: f64,
    /// Wheel separation, m.
    pub track: f64,
}
