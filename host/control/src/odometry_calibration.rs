//! Odometry calibration of a differential-drive base by least squares (Antonelli, Chiaverini
//! and Fusco, "A calibration method for odometry of mobile robots based on the least-squares
//! technique", IEEE Trans. Robotics 21(5), 2005).
//!
//! Wheel-radius and track errors are systematic: a base whose right wheel is 0.3 % larger
//! than the left turns by about 1.5° over 2 m while its odometry believes it drove straight.
//! Given runs in which the wheel angles were logged and the start and end poses were measured
//! externally (motion capture, or the simulator's ground truth), the effective geometry is
//! found in two linear least-squares problems:
//!
//! 1. heading: the measured heading change of each run is `c_R Φ_R − c_L Φ_L`, with
//!    `c = r / b` and `Φ` the wheels' total angles;
//! 2. position: with `r = c b` and the headings the `c`s give along each run, the measured
//!    displacement is linear in the track `b` alone.
//!
//! Then `r_L = c_L b` and `r_R = c_R b`. Runs must turn both ways (for the `c`s) and drive
//! somewhere (for the radii): UMBmark's squares, clockwise and counter-clockwise, plus a
//! straight line do.
//!
//! Written here rather than taken from a crate: no maintained Rust crate implements odometry
//! calibration, and the method is a two-unknown and a one-unknown least-squares solve.

use nalgebra::{DMatrix, DVector};
use serde::Deserialize;

use crate::error::{Error, Result};
use ferrobot_geometry::{wrap, Pose2};

/// Effective geometry of a differential-drive base, m.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WheelGeometry {
    /// Left wheel radius, m.
    pub left_radius: f64,
    /// Right wheel radius, m.
    pub right_radius: f64,
    /// Wheel separation, m.
    pub track: f64,
}

impl WheelGeometry {
    /// Both wheels of radius `radius` (m), `track` apart (m).
    pub fn nominal(radius: f64, track: f64) -> Self {
        WheelGeometry {
            left_radius: radius,
            right_radius: radius,
            track,
        }
    }

    /// Whether every value is finite and within `fraction` (e.g. 0.1 for 10 %) of `nominal`.
    pub fn near(&self, nominal: &WheelGeometry, fraction: f64) -> bool {
        let ok = |x: f64, n: f64| x.is_finite() && (x - n).abs() <= fraction * n;
        ok(self.left_radius, nominal.left_radius)
            && ok(self.right_radius, nominal.right_radius)
            && ok(self.track, nominal.track)
    }

    /// The pose change `[dx, dy, dθ]` (m, m, rad) in the start frame that odometry with this
    /// geometry computes from `wheels` (accumulated wheel angles, rad, in sample order),
    /// integrating exact arcs between samples.
    pub fn integrate(&self, wheels: &[[f64; 2]]) -> [f64; 3] {
        let mut p = [0.0f64; 3];
        for w in wheels.windows(2) {
            let dl = (w[1][0] - w[0][0]) * self.left_radius;
            let dr = (w[1][1] - w[0][1]) * self.right_radius;
            let ds = 0.5 * (dl + dr);
            let dth = (dr - dl) / self.track;
            // The one arc step of the firmware and the plants; the heading stays unwrapped
            // here, so a run's total turn (a square's 2π) survives.
            let [x, y, _] = ferrobot_geometry::arc_step(p, ds, dth);
            p = [x, y, p[2] + dth];
        }
        p
    }
}

/// One calibration run: the wheel angles logged during it and its externally measured start
/// and end poses.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationRun {
    /// Accumulated wheel angles `[left, right]` (rad) at each sample, from the start at rest
    /// to the end at rest.
    pub wheels: Vec<[f64; 2]>,
    /// Measured start pose `[x, y, θ]` (m, m, rad) in a fixed world frame.
    pub start: [f64; 3],
    /// Measured end pose `[x, y, θ]` in the same frame.
    pub end: [f64; 3],
}

impl CalibrationRun {
    /// The measured pose change in the start frame; the heading change is unwrapped to the
    /// multiple of 2π nearest to what `guess` integrates.
    fn measured(&self, guess: &WheelGeometry) -> [f64; 3] {
        let d = Pose2::from(self.start).between(&Pose2::from(self.end));
        let odo = guess.integrate(&self.wheels)[2];
        [d.x, d.y, odo + wrap(d.theta - odo)]
    }
}

/// Residual misfit of a geometry over the runs: RMS position (m) and heading (rad) error
/// between odometry with it and the measurements.
pub fn residuals(runs: &[CalibrationRun], g: &WheelGeometry) -> (f64, f64) {
    let (mut sp, mut st) = (0.0, 0.0);
    for r in runs {
        let m = r.measured(g);
        let o = g.integrate(&r.wheels);
        sp += (m[0] - o[0]).powi(2) + (m[1] - o[1]).powi(2);
        st += (m[2] - o[2]).powi(2);
    }
    let n = runs.len().max(1) as f64;
    ((sp / n).sqrt(), (st / n).sqrt())
}

/// Largest accumulated wheel angle a calibration run may hold, rad.
pub const MAX_WHEEL_ANGLE: f64 = 1e6;

/// Least-squares solution of `a x = b` for two unknowns; `None` when the runs do not
/// determine them (condition number above 1e6).
fn solve2(rows: &[[f64; 2]], rhs: &[f64]) -> Option<[f64; 2]> {
    // nalgebra's SVD panics on NaN: refuse anything not finite first.
    if rows.iter().flatten().chain(rhs).any(|x| !x.is_finite()) {
        return None;
    }
    let a = DMatrix::from_fn(rows.len(), 2, |i, j| rows[i][j]);
    let b = DVector::from_column_slice(rhs);
    let svd = a.svd(true, true);
    let sv = &svd.singular_values;
    let (hi, lo) = (sv.max(), sv.min());
    if !(lo > 0.0 && hi / lo < 1e6) {
        return None;
    }
    let x = svd.solve(&b, 0.0).ok()?;
    Some([x[0], x[1]])
}

/// The effective geometry from `runs`, starting from the `nominal` one (used only to unwrap
/// headings). Errors when the runs do not determine it (they must turn both ways and drive)
/// or when the estimate is more than 10 % from nominal (the measurements are then wrong).
pub fn estimate(runs: &[CalibrationRun], nominal: &WheelGeometry) -> Result<WheelGeometry> {
    let bad = |why: String| Error::Calibration { why };
    // Bounded inputs keep every sum below overflow: wheel angles within ±1e6 rad, poses
    // within the odometry frame's bounds.
    if runs.iter().any(|r| {
        r.wheels.len() < 2
            || r.wheels
                .iter()
                .flatten()
                .any(|x| !(x.is_finite() && x.abs() <= MAX_WHEEL_ANGLE))
            || ferrobot_geometry::validate::base_pose("run start", r.start).is_err()
            || ferrobot_geometry::validate::base_pose("run end", r.end).is_err()
    }) {
        return Err(bad(format!(
            "every run needs at least two finite wheel samples within ±{MAX_WHEEL_ANGLE} rad and poses within the odometry frame's bounds"
        )));
    }
    let positive = |x: f64| x.is_finite() && x > 0.0 && x <= 10.0;
    if ![nominal.left_radius, nominal.right_radius, nominal.track]
        .into_iter()
        .all(positive)
    {
        return Err(bad(format!(
            "the nominal geometry {nominal:?} is not positive and finite"
        )));
    }
    let measured: Vec<[f64; 3]> = runs.iter().map(|r| r.measured(nominal)).collect();
    // 1. Heading: Δθ = c_R Φ_R − c_L Φ_L.
    let mut rows = Vec::new();
    let mut rhs = Vec::new();
    for (r, m) in runs.iter().zip(&measured) {
        let (first, last) = (r.wheels[0], r.wheels[r.wheels.len() - 1]);
        rows.push([-(last[0] - first[0]), last[1] - first[1]]);
        rhs.push(m[2]);
    }
    let [c_l, c_r] = solve2(&rows, &rhs).ok_or_else(|| {
        bad("the runs' wheel angles do not determine the heading model: turn both ways".into())
    })?;
    // 2. Position: with r = c·b, the displacement along the headings the c's give is
    //    linear in b alone (one unknown keeps r_R / r_L = c_R / c_L, which the position
    //    barely sees).
    let (mut aa, mut am) = (0.0, 0.0);
    for (r, m) in runs.iter().zip(&measured) {
        let (mut ax, mut ay) = (0.0, 0.0);
        let mut th = 0.0;
        for w in r.wheels.windows(2) {
            let (al, ar) = (w[1][0] - w[0][0], w[1][1] - w[0][1]);
            let dth = c_r * ar - c_l * al;
            let ds = 0.5 * (c_l * al + c_r * ar);
            ax += ds * (th + 0.5 * dth).cos();
            ay += ds * (th + 0.5 * dth).sin();
            th += dth;
        }
        aa += ax * ax + ay * ay;
        am += ax * m[0] + ay * m[1];
    }
    // Travel of at least a wheel radius's worth, relative to the nominal track.
    if aa.sqrt() < nominal.left_radius / nominal.track {
        return Err(bad(
            "the runs do not determine the wheel radii: include straight travel".into(),
        ));
    }
    let b = am / aa;
    let g = WheelGeometry {
        left_radius: c_l * b,
        right_radius: c_r * b,
        track: b,
    };
    if !g.near(nominal, 0.1) {
        return Err(bad(format!(
            "the estimate {g:?} is more than 10 % from the nominal {nominal:?}: check the measurements"
        )));
    }
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs along a UMBmark-like path, integrated with `truth`: straight legs and turns of
    /// both signs, sampled finely, measured exactly.
    fn runs(truth: &WheelGeometry) -> Vec<CalibrationRun> {
        let mut out = Vec::new();
        let mut pose: [f64; 3] = [0.3, -0.2, 0.4];
        let mut wheels = [0.0f64; 2];
        // Legs: (left, right) wheel angle increments per sample, samples.
        let legs: [([f64; 2], usize); 6] = [
            ([0.05, 0.05], 800),
            ([-0.02, 0.02], 300),
            ([0.03, 0.031], 500),
            ([0.02, -0.02], 500),
            ([-0.04, -0.04], 400),
            ([0.05, 0.02], 300),
        ];
        for (inc, n) in legs {
            let mut log = vec![wheels];
            for _ in 0..n {
                wheels[0] += inc[0];
                wheels[1] += inc[1];
                log.push(wheels);
            }
            let d = truth.integrate(&log);
            let end = Pose2::from(pose).compose(&Pose2::from(d)).to_array();
            out.push(CalibrationRun {
                wheels: log,
                start: pose,
                end,
            });
            pose = end;
        }
        out
    }

    #[test]
    fn recovers_the_geometry_that_made_the_runs() {
        let nominal = WheelGeometry::nominal(0.036, 0.235);
        let truth = WheelGeometry {
            left_radius: 0.036 * 1.005,
            right_radius: 0.036 * 1.008,
            track: 0.235 * 1.01,
        };
        let g = estimate(&runs(&truth), &nominal).expect("estimate");
        for (a, b) in [
            (g.left_radius, truth.left_radius),
            (g.right_radius, truth.right_radius),
            (g.track, truth.track),
        ] {
            assert!((a / b - 1.0).abs() < 1e-5, "{g:?} vs {truth:?}");
        }
        let (p, t) = residuals(&runs(&truth), &g);
        assert!(p < 1e-5 && t < 1e-5, "{p} m, {t} rad");
        // The nominal geometry misfits by millimetres and about a degree.
        let (p, t) = residuals(&runs(&truth), &nominal);
        assert!(p > 1e-3 && t > 0.01, "{p} m, {t} rad");
    }

    #[test]
    fn straight_runs_alone_are_refused() {
        let g = WheelGeometry::nominal(0.035, 0.23);
        let run = CalibrationRun {
            wheels: (0..100).map(|k| [k as f64 * 0.1; 2]).collect(),
            start: [0.0; 3],
            end: [0.35, 0.0, 0.0],
        };
        let e = estimate(&[run.clone(), run], &g).expect_err("underdetermined");
        assert!(matches!(e, Error::Calibration { .. }), "{e}");
    }

    #[test]
    fn wrong_measurements_are_refused() {
        let truth = WheelGeometry::nominal(0.035, 0.23);
        let mut r = runs(&truth);
        for run in &mut r {
            run.end[0] = run.start[0] + 2.0 * (run.end[0] - run.start[0]);
            run.end[1] = run.start[1] + 2.0 * (run.end[1] - run.start[1]);
        }
        let e = estimate(&r, &truth).expect_err("twice the distance");
        assert!(e.to_string().contains("10 %"), "{e}");
        r[0].end[0] = f64::NAN;
        assert!(estimate(&r, &truth).is_err());
    }
}
