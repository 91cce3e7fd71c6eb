//! Validation of the numbers that enter Ferrobot, one place per kind of value: durations,
//! angles, Cartesian positions, orientations, base goals and sizes. Every check returns a
//! typed [`ValueError`] naming the value and the accepted range; none panics, whatever the
//! input (NaN, ±inf, subnormals, ±f64::MAX, `Duration::MAX`).
//!
//! The bounds are physical: wide enough for anything the robots Ferrobot drives can do, narrow
//! enough that no arithmetic on an accepted value overflows, and no allocation or search sized
//! by an accepted value exceeds a few hundred megabytes or a few seconds.

use std::time::Duration;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// A number that is not valid where it was given.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ValueError {
    /// A NaN or infinite value.
    #[error("{what} is not a finite number: {value}")]
    NotFinite {
        /// What.
        what: String,
        /// The value.
        value: f64,
    },
    /// A finite number outside the accepted range.
    #[error("{what} = {} is outside the accepted range [{}, {}]", num(*value), num(*min), num(*max))]
    OutOfRange {
        /// What.
        what: String,
        /// The value.
        value: f64,
        /// Smallest accepted.
        min: f64,
        /// Largest accepted.
        max: f64,
    },
    /// A list of values of the wrong length.
    #[error("{what}: expected {expected} values, got {got}")]
    Length {
        /// What was passed.
        what: &'static str,
        /// How many were expected.
        expected: usize,
        /// How many were given.
        got: usize,
    },
}

/// Result with [`ValueError`].
pub type Result<T, E = ValueError> = std::result::Result<T, E>;

/// A number for a message: plain when moderate, in scientific notation when huge or tiny,
/// six significant digits at most.
pub fn num(v: f64) -> String {
    let a = v.abs();
    if v.is_finite() && a != 0.0 && !(1e-3..1e6).contains(&a) {
        format!("{v:.3e}")
    } else if v.is_finite() {
        let s = format!("{v:.6}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s == "-0" {
            "0".into()
        } else {
            s.into()
        }
    } else {
        format!("{v}")
    }
}

/// Longest duration or timeout the API accepts, s (one hour).
pub const MAX_DURATION_S: f64 = 3600.0;
/// Largest angle the API accepts (joint angles, pitch, roll, yaw), rad: two turns either way,
/// the wire protocol's largest joint position (`ferrobot_protocol::ranges::JOINT_POSITION_MAX`).
pub const MAX_ANGLE: f64 = 4.0 * std::f64::consts::PI;
/// Largest Cartesian coordinate of an arm target or displacement, m.
pub const MAX_ARM_REACH: f64 = 10.0;
/// A quaternion whose norm differs from 1 by more than this is refused, not normalised.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;
/// Farthest base position goal from the current pose, m: longer journeys are split.
pub const MAX_BASE_GOAL_DISTANCE: f64 = 50.0;
/// Largest coordinate of a base pose or obstacle in the odometry frame, m (the firmware
/// integrates odometry in `f32`, good to 0.1 mm there).
pub const MAX_BASE_COORDINATE: f64 = 1000.0;
/// Smallest step of a Cartesian (straight-line) arm motion, m.
pub const MIN_CARTESIAN_STEP: f64 = 1e-4;
/// Most waypoints of one Cartesian arm motion.
pub const MAX_CARTESIAN_WAYPOINTS: usize = 10_000;
/// Most cells of an occupancy grid or a navigation field (4096 × 4096).
pub const MAX_GRID_CELLS: usize = 1 << 24;
/// Most samples of a base reference trajectory.
pub const MAX_REFERENCE_SAMPLES: usize = 200_000;
/// Sample period of a base reference trajectory, s: from 1 ms to 1 s.
pub const REFERENCE_DT: (f64, f64) = (1e-3, 1.0);
/// Fastest base speed anything may name, m/s: the wire protocol's `BASE_SPEED_MAX` (tested
/// equal in `ferrobot`).
pub const BASE_SPEED_MAX: f64 = 2.0;
/// Fastest base turn anything may name, rad/s: the wire protocol's `BASE_TURN_MAX` (tested
/// equal in `ferrobot`).
pub const BASE_TURN_MAX: f64 = 20.0;
/// Most circular obstacles of one base goal.
pub const MAX_OBSTACLES: usize = 10_000;

/// Every value finite; the error names `what[i]` of the first that is not.
pub fn finite(what: &str, values: &[f64]) -> Result<()> {
    for (i, v) in values.iter().enumerate() {
        if !v.is_finite() {
            return Err(ValueError::NotFinite {
                what: element(what, values.len(), i),
                value: *v,
            });
        }
    }
    Ok(())
}

/// The name of element `i` of a list of `len` values called `what`: `what[i]`, or `what` alone
/// for a single value.
fn element(what: &str, len: usize, i: usize) -> String {
    if len > 1 {
        format!("{what}[{i}]")
    } else {
        what.to_string()
    }
}

/// `value` finite and within `[min, max]`.
pub fn in_range(what: &str, value: f64, min: f64, max: f64) -> Result<f64> {
    finite(what, &[value])?;
    if !(min..=max).contains(&value) {
        return Err(ValueError::OutOfRange {
            what: what.to_string(),
            value,
            min,
            max,
        });
    }
    Ok(value)
}

/// Every value finite and within `[min, max]`.
pub fn all_in_range(what: &str, values: &[f64], min: f64, max: f64) -> Result<()> {
    finite(what, values)?;
    // Names are made only for the value at fault: this runs on every motion command.
    match values.iter().position(|v| !(min..=max).contains(v)) {
        Some(i) => Err(ValueError::OutOfRange {
            what: element(what, values.len(), i),
            value: values[i],
            min,
            max,
        }),
        None => Ok(()),
    }
}

/// A duration given in seconds: finite, in `[0, MAX_DURATION_S]`.
pub fn seconds(what: &str, s: f64) -> Result<Duration> {
    in_range(what, s, 0.0, MAX_DURATION_S)?;
    Duration::try_from_secs_f64(s).map_err(|_| ValueError::OutOfRange {
        what: what.to_string(),
        value: s,
        min: 0.0,
        max: MAX_DURATION_S,
    })
}

/// A timeout: at most [`MAX_DURATION_S`].
pub fn timeout(what: &str, d: Duration) -> Result<Duration> {
    if d.as_secs_f64() > MAX_DURATION_S {
        return Err(ValueError::OutOfRange {
            what: what.to_string(),
            value: d.as_secs_f64(),
            min: 0.0,
            max: MAX_DURATION_S,
        });
    }
    Ok(d)
}

/// Angles (rad): finite, within ±[`MAX_ANGLE`].
pub fn angles(what: &str, values: &[f64]) -> Result<()> {
    all_in_range(what, values, -MAX_ANGLE, MAX_ANGLE)
}

/// An arm target or displacement (m): finite, each coordinate within ±[`MAX_ARM_REACH`].
pub fn arm_point(what: &str, p: [f64; 3]) -> Result<Vector3<f64>> {
    all_in_range(what, &p, -MAX_ARM_REACH, MAX_ARM_REACH)?;
    Ok(Vector3::from(p))
}

/// A quaternion `[x, y, z, w]` of norm 1 within [`QUATERNION_NORM_TOLERANCE`]; normalised
/// exactly. A far-from-unit quaternion is a mistake (Euler angles or a scaled axis passed by
/// error), so it is refused rather than silently normalised.
pub fn unit_quaternion(q: [f64; 4]) -> Result<UnitQuaternion<f64>> {
    finite("quaternion", &q)?;
    let [x, y, z, w] = q;
    let quat = Quaternion::new(w, x, y, z);
    let norm = quat.norm();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(ValueError::OutOfRange {
            what: "quaternion norm".into(),
            value: norm,
            min: 1.0 - QUATERNION_NORM_TOLERANCE,
            max: 1.0 + QUATERNION_NORM_TOLERANCE,
        });
    }
    Ok(UnitQuaternion::from_quaternion(quat))
}

/// A base pose or goal `[x, y, θ]` in the odometry frame: finite, x and y within
/// ±[`MAX_BASE_COORDINATE`], θ within ±[`MAX_ANGLE`].
pub fn base_pose(what: &str, p: [f64; 3]) -> Result<()> {
    all_in_range(what, &p[..2], -MAX_BASE_COORDINATE, MAX_BASE_COORDINATE)?;
    angles(&format!("{what} heading"), &p[2..])
}

/// A base goal `goal` reachable in one motion from `here`: a valid pose at most
/// [`MAX_BASE_GOAL_DISTANCE`] away.
pub fn base_goal(goal: [f64; 3], here: [f64; 3]) -> Result<()> {
    base_pose("base goal", goal)?;
    let d = (goal[0] - here[0]).hypot(goal[1] - here[1]);
    in_range("base goal distance", d, 0.0, MAX_BASE_GOAL_DISTANCE)?;
    Ok(())
}

/// A list of `got` values where `expected` are needed.
pub fn length(what: &'static str, got: usize, expected: usize) -> Result<()> {
    if got != expected {
        return Err(ValueError::Length {
            what,
            expected,
            got,
        });
    }
    Ok(())
}

/// A count within `range`.
pub fn count(what: &str, n: usize, range: std::ops::RangeInclusive<usize>) -> Result<usize> {
    if !range.contains(&n) {
        return Err(ValueError::OutOfRange {
            what: what.to_string(),
            value: n as f64,
            min: *range.start() as f64,
            max: *range.end() as f64,
        });
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hostile_durations_are_refused() {
        for s in [
            f64::NAN,
            f64::INFINITY,
            -1.0,
            1e20,
            f64::MAX,
            MAX_DURATION_S * 1.0001,
        ] {
            assert!(seconds("t", s).is_err(), "{s}");
        }
        assert_eq!(seconds("t", 1.5).unwrap(), Duration::from_millis(1500));
        assert_eq!(seconds("t", 5e-324).unwrap(), Duration::ZERO);
        assert!(timeout("t", Duration::MAX).is_err());
    }

    #[test]
    fn quaternions_far_from_unit_norm_are_refused() {
        assert!(unit_quaternion([0.0, 0.0, 0.0, 1.0]).is_ok());
        assert!(unit_quaternion([0.0, 0.0, 0.0, 1.0009]).is_ok());
        for q in [
            [0.0, 0.0, 0.0, 1.002],
            [0.0, 0.0, 0.0, 1e30],
            [0.0; 4],
            [f64::NAN, 0.0, 0.0, 1.0],
        ] {
            assert!(unit_quaternion(q).is_err(), "{q:?}");
        }
    }

    #[test]
    fn base_goals_are_bounded() {
        assert!(base_goal([1.0, 1.0, 0.0], [0.0; 3]).is_ok());
        assert!(base_goal([1000.0, 1000.0, 0.0], [0.0; 3]).is_err());
        assert!(base_goal([1e300, 0.0, 0.0], [0.0; 3]).is_err());
        assert!(base_goal([0.0, 0.0, 1e9], [0.0; 3]).is_err());
    }
}
