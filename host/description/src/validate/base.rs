//! `[base]`: its geometry (m), speed limits and tolerances within their ranges; the speed
//! limits and the calibrated odometry are the [`Checks`]' too.

use std::path::Path;

use crate::base::BaseSection;
use crate::checks::Checks;
use crate::error::{in_range as num, Result};

/// Check the base `b`.
pub(super) fn check(b: &BaseSection, file: &Path, checks: &dyn Checks) -> Result<()> {
    for (k, v, lo, hi) in [
        ("base.wheel_radius", b.wheel_radius, 1e-3, 1.0),
        ("base.track", b.track, 1e-2, 5.0),
        ("base.footprint_radius", b.footprint_radius, 1e-2, 5.0),
        ("base.min_wheel_speed", b.min_wheel_speed, 1e-4, 1.0),
    ] {
        num(file, k, v, lo, hi)?;
    }
    checks.base_speeds(file, b)?;
    for (k, v, lo, hi) in [
        (
            "base.translation_tolerance",
            b.translation_tolerance,
            1e-4,
            1.0,
        ),
        (
            "base.rotation_tolerance",
            b.rotation_tolerance,
            1e-4,
            std::f64::consts::PI,
        ),
    ] {
        num(file, k, v, lo, hi)?;
    }
    checks.base_odometry(file, b)
}
