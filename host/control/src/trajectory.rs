//! Base trajectory control on a unicycle model: reference trajectories under velocity and
//! acceleration limits, and a time-varying LQR that tracks them from odometry.
//!
//! State `[x, y, θ]` (m, m, rad) in the odometry frame; control `[v, ω]` (m/s, rad/s).
//! Discrete model with step `dt`: `x⁺ = x + dt·v·cos θ`, `y⁺ = y + dt·v·sin θ`, `θ⁺ = θ + dt·ω`.

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Matrix3x2, Vector2, Vector3};

use crate::error::Result;
use ferrobot_geometry::validate;

pub use ferrobot_geometry::wrap;

/// Limits a reference respects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Largest |v|, m/s.
    pub v: f64,
    /// Largest |ω|, rad/s.
    pub w: f64,
    /// Largest |dv/dt|, m/s².
    pub accel_v: f64,
    /// Largest |dω/dt|, rad/s².
    pub accel_w: f64,
}

impl Limits {
    /// PyRobot's tracking limits (0.2 m/s, 0.5 rad/s) with 0.5 m/s² and 1.5 rad/s².
    pub const TRACKING: Limits = Limits {
        v: 0.2,
        w: 0.5,
        accel_v: 0.5,
        accel_w: 1.5,
    };

    /// Every limit finite and positive: speeds up to the protocol's base maxima, accelerations
    /// from 0.001 to 100 per second.
    pub fn check(&self) -> Result<()> {
        use validate::{BASE_SPEED_MAX, BASE_TURN_MAX};
        validate::in_range("limit v", self.v, 1e-3, BASE_SPEED_MAX)?;
        validate::in_range("limit w", self.w, 1e-3, BASE_TURN_MAX)?;
        validate::in_range("limit accel_v", self.accel_v, 1e-3, 100.0)?;
        validate::in_range("limit accel_w", self.accel_w, 1e-3, 100.0)?;
        Ok(())
    }
}

/// A sampled trajectory: states and the controls that lead from each to the next.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Sample period, s.
    pub dt: f64,
    /// States `[x, y, θ]`, one more than controls.
    pub states: Vec<[f64; 3]>,
    /// Controls `[v, ω]`.
    pub controls: Vec<[f64; 2]>,
}

/// One step of the discrete unicycle model: state `x` `[x, y, θ]` under control `u` `[v, ω]`
/// for `dt` s (the heading wrapped to (−π, π]).
pub fn step(x: [f64; 3], u: [f64; 2], dt: f64) -> [f64; 3] {
    [
        x[0] + dt * u[0] * x[2].cos(),
        x[1] + dt * u[0] * x[2].sin(),
        wrap(x[2] + dt * u[1]),
    ]
}

/// A speed profile covering `dist` (≥ 0) under a speed and acceleration bound: trapezoid or
/// triangle, sampled every `dt`; the last sample lands exactly on `dist`. An error when it
/// would have more than [`validate::MAX_REFERENCE_SAMPLES`] samples.
fn profile(dist: f64, vmax: f64, amax: f64, dt: f64) -> Result<Vec<f64>> {
    if dist <= 1e-12 {
        return Ok(Vec::new());
    }
    let vpeak = vmax.min((dist * amax).sqrt());
    let t_acc = vpeak / amax;
    let t_cruise = (dist - vpeak * t_acc) / vpeak;
    let total = 2.0 * t_acc + t_cruise.max(0.0);
    let samples = (total / dt).ceil().max(1.0);
    validate::in_range(
        "reference samples",
        samples,
        1.0,
        validate::MAX_REFERENCE_SAMPLES as f64,
    )?;
    let n = samples as usize;
    // Distance covered by time t on the continuous profile, in closed form.
    let t_c = t_cruise.max(0.0);
    let covered = |t: f64| {
        let t = t.clamp(0.0, total);
        if t < t_acc {
            0.5 * amax * t * t
        } else if t < t_acc + t_c {
            0.5 * amax * t_acc * t_acc + vpeak * (t - t_acc)
        } else {
            dist - 0.5 * amax * (total - t) * (total - t)
        }
    };
    // Each sample's speed is the exact mean over its period: the samples add up to `dist`, none
    // exceeds the peak, and neighbours differ by at most `amax·dt`.
    Ok((0..n)
        .map(|k| (covered((k + 1) as f64 * dt) - covered(k as f64 * dt)) / dt)
        .collect())
}

/// The inputs shared by the reference builders: poses, limits and sample period.
fn check_inputs(start: [f64; 3], goal: [f64; 3], lim: &Limits, dt: f64) -> Result<()> {
    validate::base_pose("reference start", start)?;
    validate::base_pose("reference goal", goal)?;
    lim.check()?;
    let (lo, hi) = validate::REFERENCE_DT;
    validate::in_range("reference dt", dt, lo, hi)?;
    Ok(())
}

impl Reference {
    fn push_rotation(&mut self, to: f64, lim: &Limits) -> Result<()> {
        let from = self.states.last().map(|s| s[2]).unwrap_or(0.0);
        let d = wrap(to - from);
        for w in profile(d.abs(), lim.w, lim.accel_w, self.dt)? {
            self.push([0.0, w * d.signum()]);
        }
        Ok(())
    }

    /// Whether the reference can be tracked: `dt` in [`validate::REFERENCE_DT`], one more
    /// state than controls, at most [`validate::MAX_REFERENCE_SAMPLES`] states, every state
    /// (the last too) a valid base pose, every control within the protocol's base speed and
    /// turn maxima, and a duration of at most
    /// [`validate::MAX_DURATION_S`].
    pub fn check(&self) -> Result<()> {
        let (lo, hi) = validate::REFERENCE_DT;
        validate::in_range("trajectory dt", self.dt, lo, hi)?;
        validate::count(
            "trajectory states",
            self.states.len(),
            0..=validate::MAX_REFERENCE_SAMPLES,
        )?;
        validate::length(
            "trajectory states (one more than controls)",
            self.states.len(),
            self.controls.len() + 1,
        )?;
        for x in &self.states {
            validate::base_pose("trajectory state", *x)?;
        }
        use validate::{BASE_SPEED_MAX, BASE_TURN_MAX};
        for u in &self.controls {
            validate::in_range(
                "trajectory control v",
                u[0],
                -BASE_SPEED_MAX,
                BASE_SPEED_MAX,
            )?;
            validate::in_range("trajectory control w", u[1], -BASE_TURN_MAX, BASE_TURN_MAX)?;
        }
        validate::seconds("trajectory duration", self.dt * self.controls.len() as f64)?;
        Ok(())
    }

    fn push(&mut self, u: [f64; 2]) {
        let x = *self.states.last().unwrap_or(&[0.0; 3]);
        self.states.push(step(x, u, self.dt));
        self.controls.push(u);
    }

    /// PyRobot's "sharp" reference: turn towards the goal, drive straight (backwards when it
    /// lies behind), turn to the goal heading.
    pub fn sharp(start: [f64; 3], goal: [f64; 3], lim: &Limits, dt: f64) -> Result<Reference> {
        check_inputs(start, goal, lim, dt)?;
        let mut r = Reference {
            dt,
            states: vec![start],
            controls: Vec::new(),
        };
        let (dx, dy) = (goal[0] - start[0], goal[1] - start[1]);
        let dist = dx.hypot(dy);
        if dist > 1e-6 {
            let bearing = dy.atan2(dx);
            let backwards = wrap(bearing - start[2]).abs() > std::f64::consts::FRAC_PI_2;
            let heading = if backwards {
                wrap(bearing + std::f64::consts::PI)
            } else {
                bearing
            };
            r.push_rotation(heading, lim)?;
            let sign = if backwards { -1.0 } else { 1.0 };
            for v in profile(dist, lim.v, lim.accel_v, dt)? {
                r.push([sign * v, 0.0]);
            }
        }
        r.push_rotation(goal[2], lim)?;
        Ok(r)
    }

    /// PyRobot's "smooth" reference: a cubic Bézier from start to goal with control points
    /// `arm` metres along the start and goal headings, driven at a speed profile under the
    /// limits (slowing where the curvature would ask for too much yaw rate); a final turn
    /// absorbs what heading error remains.
    pub fn smooth(
        start: [f64; 3],
        goal: [f64; 3],
        lim: &Limits,
        dt: f64,
        arm: f64,
    ) -> Result<Reference> {
        check_inputs(start, goal, lim, dt)?;
        validate::in_range("Bézier arm", arm, 0.0, 10.0)?;
        let p0 = Vector2::new(start[0], start[1]);
        let p3 = Vector2::new(goal[0], goal[1]);
        if (p3 - p0).norm() < 1e-6 {
            return Reference::sharp(start, goal, lim, dt);
        }
        let p1 = p0 + arm * Vector2::new(start[2].cos(), start[2].sin());
        let p2 = p3 - arm * Vector2::new(goal[2].cos(), goal[2].sin());
        let at = |s: f64| {
            let t = 1.0 - s;
            p0 * t * t * t + p1 * 3.0 * t * t * s + p2 * 3.0 * t * s * s + p3 * s * s * s
        };
        // Arc-length table.
        let n = 2000;
        let mut len = vec![0.0; n + 1];
        for k in 1..=n {
            len[k] = len[k - 1] + (at(k as f64 / n as f64) - at((k - 1) as f64 / n as f64)).norm();
        }
        let total = len[n];
        let s_at = |d: f64| {
            let k = len.partition_point(|&l| l < d).clamp(1, n);
            let f = (d - len[k - 1]) / (len[k] - len[k - 1]).max(1e-12);
            ((k - 1) as f64 + f.clamp(0.0, 1.0)) / n as f64
        };
        // Speed limited by the largest curvature on the curve too: v·κ ≤ ω_max.
        let mut kmax: f64 = 0.0;
        for k in 1..n {
            let (a, b, c) = (
                at((k - 1) as f64 / n as f64),
                at(k as f64 / n as f64),
                at((k + 1) as f64 / n as f64),
            );
            let (d1, d2) = (b - a, c - b);
            let cross = d1.x * d2.y - d1.y * d2.x;
            let denom = (d1.norm() * d2.norm() * (c - a).norm()).max(1e-12);
            kmax = kmax.max((2.0 * cross / denom).abs());
        }
        let v = if kmax > 0.0 {
            lim.v.min(0.9 * lim.w / kmax)
        } else {
            lim.v
        };
        let mut r = Reference {
            dt,
            states: vec![start],
            controls: Vec::new(),
        };
        let mut travelled = 0.0;
        let mut theta = start[2];
        for ds in profile(total, v, lim.accel_v, dt)?.iter().map(|s| s * dt) {
            travelled += ds;
            let p = at(s_at(travelled));
            let prev = *r.states.last().unwrap_or(&start);
            let heading = (p.y - prev[1]).atan2(p.x - prev[0]);
            let w = (wrap(heading - theta) / dt).clamp(-lim.w, lim.w);
            theta = wrap(theta + w * dt);
            let dist = (p.x - prev[0]).hypot(p.y - prev[1]);
            r.states.push([p.x, p.y, theta]);
            r.controls.push([dist / dt, w]);
        }
        r.push_rotation(goal[2], lim)?;
        Ok(r)
    }

    /// A circle of radius `v/ω` driven at `v`, `ω` for `duration` s, from `start`.
    pub fn circle(start: [f64; 3], v: f64, w: f64, duration: f64, dt: f64) -> Result<Reference> {
        validate::base_pose("reference start", start)?;
        let (vmax, wmax) = (validate::BASE_SPEED_MAX, validate::BASE_TURN_MAX);
        validate::in_range("circle speed v", v, -vmax, vmax)?;
        validate::in_range("circle turn rate w", w, -wmax, wmax)?;
        validate::seconds("circle duration", duration)?;
        let (lo, hi) = validate::REFERENCE_DT;
        validate::in_range("reference dt", dt, lo, hi)?;
        let n = validate::count(
            "reference samples",
            (duration / dt).round() as usize,
            0..=validate::MAX_REFERENCE_SAMPLES,
        )?;
        let mut r = Reference {
            dt,
            states: vec![start],
            controls: Vec::new(),
        };
        for _ in 0..n {
            r.push([v, w]);
        }
        Ok(r)
    }

    /// Hold the last state for `n` more samples (zero controls): time for a tracker to settle.
    /// An error when the reference would have more than [`validate::MAX_REFERENCE_SAMPLES`].
    pub fn hold(mut self, n: usize) -> Result<Reference> {
        validate::count(
            "reference samples",
            self.states.len().saturating_add(n),
            0..=validate::MAX_REFERENCE_SAMPLES,
        )?;
        for _ in 0..n {
            self.push([0.0, 0.0]);
        }
        Ok(self)
    }

    /// The final state.
    pub fn end(&self) -> [f64; 3] {
        *self.states.last().unwrap_or(&[0.0; 3])
    }
}

/// Time-varying LQR along a reference: unicycle linearised at each reference sample, cost
/// `Σ eᵀQe + δuᵀRδu`, gains from the backward Riccati recursion.
#[derive(Debug, Clone)]
pub struct LqrTracker {
    /// The reference.
    pub reference: Reference,
    gains: Vec<Matrix2x3<f64>>,
}

impl LqrTracker {
    /// Gains for `reference` with state weights `q` and control weight `r` (PyRobot: Q =
    /// diag(3, 3, 4), R = 0.2·I).
    pub fn new(reference: Reference, q: [f64; 3], r: f64) -> Self {
        let dt = reference.dt;
        let qm = Matrix3::from_diagonal(&Vector3::from(q));
        let rm = Matrix2::identity() * r;
        // A malformed reference (see `Reference::check`) gets gains only where it has states.
        let n = reference
            .controls
            .len()
            .min(reference.states.len().saturating_sub(1));
        let mut p = qm;
        let mut gains = vec![Matrix2x3::zeros(); n];
        for k in (0..n).rev() {
            let th = reference.states[k][2];
            let v = reference.controls[k][0];
            #[rustfmt::skip]
            let a = Matrix3::new(
                1.0, 0.0, -dt * v * th.sin(),
                0.0, 1.0, dt * v * th.cos(),
                0.0, 0.0, 1.0,
            );
            #[rustfmt::skip]
            let b = Matrix3x2::new(
                dt * th.cos(), 0.0,
                dt * th.sin(), 0.0,
                0.0, dt,
            );
            let s = rm + b.transpose() * p * b;
            let kk = s.try_inverse().unwrap_or_else(Matrix2::identity) * b.transpose() * p * a;
            p = qm + a.transpose() * p * (a - b * kk);
            gains[k] = kk;
        }
        LqrTracker { reference, gains }
    }

    /// The control at sample `k` for the measured state `x` (closed loop), or the reference
    /// control alone (open loop).
    pub fn control(&self, k: usize, x: [f64; 3], closed_loop: bool) -> [f64; 2] {
        let Some(u) = self.reference.controls.get(k) else {
            return [0.0, 0.0];
        };
        if !closed_loop {
            return *u;
        }
        let (Some(r), Some(g)) = (self.reference.states.get(k), self.gains.get(k)) else {
            return *u;
        };
        let e = Vector3::new(x[0] - r[0], x[1] - r[1], wrap(x[2] - r[2]));
        let du = -g * e;
        [u[0] + du[0], u[1] + du[1]]
    }
}

/// How much more [`ilqr`] weighs the final state than the others.
pub const TERMINAL_WEIGHT: f64 = 100.0;

/// Result of [`ilqr`].
#[derive(Debug, Clone)]
pub struct IlqrSolution {
    /// The optimised, dynamically consistent trajectory.
    pub reference: Reference,
    /// Iterations run.
    pub iterations: usize,
    /// Final cost.
    pub cost: f64,
    /// Whether the relative cost change fell below the tolerance.
    pub converged: bool,
}

fn cost_of(xs: &[[f64; 3]], us: &[[f64; 2]], r: &Reference, q: &Matrix3<f64>, rw: f64) -> f64 {
    let mut c = 0.0;
    for (k, x) in xs.iter().enumerate() {
        let xr = r.states[k.min(r.states.len() - 1)];
        let e = Vector3::new(x[0] - xr[0], x[1] - xr[1], wrap(x[2] - xr[2]));
        let w = if k + 1 == xs.len() {
            TERMINAL_WEIGHT
        } else {
            1.0
        };
        c += w * (e.transpose() * q * e)[0];
    }
    for (k, u) in us.iter().enumerate() {
        let ur = r.controls[k];
        c += rw * ((u[0] - ur[0]).powi(2) + (u[1] - ur[1]).powi(2));
    }
    c
}

/// Iterative LQR on the unicycle: find the dynamically consistent trajectory from `start` that
/// best follows `reference` (state weights `q`, control weight `r`, terminal state weighted
/// by [`TERMINAL_WEIGHT`]) within `lim`, iterating backward and forward passes with a line search until the
/// relative cost change is below 1e-9 or 100 iterations. An error for a reference that fails
/// [`Reference::check`], a start that is no base pose, or bad weights or limits.
pub fn ilqr(
    start: [f64; 3],
    reference: &Reference,
    q: [f64; 3],
    r: f64,
    lim: &Limits,
) -> Result<IlqrSolution> {
    reference.check()?;
    validate::base_pose("ILQR start", start)?;
    validate::all_in_range("ILQR state weights", &q, 0.0, 1e6)?;
    validate::in_range("ILQR control weight", r, 1e-9, 1e6)?;
    lim.check()?;
    let dt = reference.dt;
    let n = reference.controls.len();
    let qm = Matrix3::from_diagonal(&Vector3::from(q));
    let rm = Matrix2::identity() * r;
    let clamp = |u: [f64; 2]| [u[0].clamp(-lim.v, lim.v), u[1].clamp(-lim.w, lim.w)];
    let rollout = |us: &[[f64; 2]]| {
        let mut xs = Vec::with_capacity(us.len() + 1);
        xs.push(start);
        for u in us {
            let x = *xs.last().unwrap_or(&start);
            xs.push(step(x, *u, dt));
        }
        xs
    };
    let mut us: Vec<[f64; 2]> = reference.controls.iter().map(|u| clamp(*u)).collect();
    let mut xs = rollout(&us);
    let mut cost = cost_of(&xs, &us, reference, &qm, r);
    let mut converged = false;
    let mut iterations = 0;
    let mut reg = 1e-6;
    for it in 0..100 {
        iterations = it + 1;
        // Backward pass.
        let mut ks = vec![Vector2::zeros(); n];
        let mut gains = vec![Matrix2x3::zeros(); n];
        let xr = reference.states[n];
        let en = Vector3::new(xs[n][0] - xr[0], xs[n][1] - xr[1], wrap(xs[n][2] - xr[2]));
        let mut vx = qm * en * TERMINAL_WEIGHT;
        let mut vxx = qm * TERMINAL_WEIGHT;
        for k in (0..n).rev() {
            let (th, v) = (xs[k][2], us[k][0]);
            #[rustfmt::skip]
            let a = Matrix3::new(1.0, 0.0, -dt * v * th.sin(), 0.0, 1.0, dt * v * th.cos(), 0.0, 0.0, 1.0);
            #[rustfmt::skip]
            let b = Matrix3x2::new(dt * th.cos(), 0.0, dt * th.sin(), 0.0, 0.0, dt);
            let xr = reference.states[k];
            let e = Vector3::new(xs[k][0] - xr[0], xs[k][1] - xr[1], wrap(xs[k][2] - xr[2]));
            let du = Vector2::new(
                us[k][0] - reference.controls[k][0],
                us[k][1] - reference.controls[k][1],
            );
            let qx = qm * e + a.transpose() * vx;
            let qu = rm * du + b.transpose() * vx;
            let qxx = qm + a.transpose() * vxx * a;
            let quu = rm + b.transpose() * vxx * b + Matrix2::identity() * reg;
            let qux = b.transpose() * vxx * a;
            let inv = quu.try_inverse().unwrap_or_else(Matrix2::identity);
            let kk = -inv * qu;
            let kg = -inv * qux;
            vx = qx + kg.transpose() * quu * kk + kg.transpose() * qu + qux.transpose() * kk;
            vxx = qxx + kg.transpose() * quu * kg + kg.transpose() * qux + qux.transpose() * kg;
            vxx = (vxx + vxx.transpose()) * 0.5;
            ks[k] = kk;
            gains[k] = kg;
        }
        // Forward pass with a line search.
        let mut improved = false;
        for alpha in [1.0, 0.5, 0.25, 0.1, 0.03, 0.01] {
            let mut nx = vec![start];
            let mut nu = Vec::with_capacity(n);
            for k in 0..n {
                let x = nx[k];
                let dx = Vector3::new(x[0] - xs[k][0], x[1] - xs[k][1], wrap(x[2] - xs[k][2]));
                let d = ks[k] * alpha + gains[k] * dx;
                let u = clamp([us[k][0] + d[0], us[k][1] + d[1]]);
                nu.push(u);
                nx.push(step(x, u, dt));
            }
            let c = cost_of(&nx, &nu, reference, &qm, r);
            if c < cost {
                let change = (cost - c) / cost.max(1e-300);
                xs = nx;
                us = nu;
                cost = c;
                improved = true;
                reg = (reg * 0.5).max(1e-9);
                if change < 1e-9 {
                    converged = true;
                }
                break;
            }
        }
        if !improved {
            // No step lowers the cost: a local optimum (or more damping needed).
            reg *= 10.0;
            if reg > 1e3 {
                converged = true;
            }
        }
        if converged || cost < 1e-18 {
            converged = true;
            break;
        }
    }
    Ok(IlqrSolution {
        reference: Reference {
            dt,
            states: xs,
            controls: us,
        },
        iterations,
        cost,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn within_limits(r: &Reference, lim: &Limits) {
        let mut prev = [0.0, 0.0];
        for u in &r.controls {
            assert!(
                u[0].abs() <= lim.v + 1e-9 && u[1].abs() <= lim.w + 1e-9,
                "{u:?}"
            );
            assert!(
                (u[0] - prev[0]).abs() <= lim.accel_v * r.dt * 1.05 + 1e-9,
                "{u:?} after {prev:?}"
            );
            assert!(
                (u[1] - prev[1]).abs() <= lim.accel_w * r.dt * 1.05 + 1e-9,
                "{u:?} after {prev:?}"
            );
            prev = *u;
        }
    }

    #[test]
    fn references_end_at_the_goal_within_the_limits() {
        let lim = Limits::TRACKING;
        for goal in [
            [2.0, 0.0, 0.0],
            [-2.0, 0.0, 0.0],
            [0.0, 0.0, std::f64::consts::FRAC_PI_2],
            [1.0, 1.0, 0.0],
            [-1.0, -1.0, 0.0],
        ] {
            let r = Reference::sharp([0.0; 3], goal, &lim, 0.1).expect("reference");
            let e = r.end();
            assert!(
                (e[0] - goal[0]).hypot(e[1] - goal[1]) < 1e-6 && wrap(e[2] - goal[2]).abs() < 1e-6,
                "{goal:?}: {e:?}"
            );
            within_limits(&r, &lim);
            let s = Reference::smooth([0.0; 3], goal, &lim, 0.1, 0.8).expect("reference");
            let e = s.end();
            assert!(
                (e[0] - goal[0]).hypot(e[1] - goal[1]) < 2e-3 && wrap(e[2] - goal[2]).abs() < 1e-6,
                "{goal:?}: {e:?}"
            );
        }
    }

    #[test]
    fn ilqr_makes_the_smooth_reference_consistent_and_converges() {
        let lim = Limits::TRACKING;
        let r = Reference::smooth([0.0; 3], [1.0, 1.0, 0.0], &lim, 0.1, 0.8).expect("reference");
        let sol = ilqr([0.0; 3], &r, [3.0, 3.0, 4.0], 0.2, &lim).expect("ilqr");
        assert!(
            sol.converged,
            "{} iterations, cost {}",
            sol.iterations, sol.cost
        );
        // Rolling its controls out reproduces its states exactly, and it ends near the goal.
        let mut x = [0.0; 3];
        for (k, u) in sol.reference.controls.iter().enumerate() {
            x = step(x, *u, 0.1);
            let s = sol.reference.states[k + 1];
            assert!((x[0] - s[0]).abs() < 1e-12 && (x[1] - s[1]).abs() < 1e-12);
            assert!(u[0].abs() <= lim.v + 1e-12 && u[1].abs() <= lim.w + 1e-12);
        }
        let e = sol.reference.end();
        assert!(
            (e[0] - 1.0).hypot(e[1] - 1.0) < 5e-3 && wrap(e[2]).abs() < 1e-2,
            "{e:?}"
        );
        // From a perturbed start the optimum still reaches the goal.
        let sol = ilqr([0.03, -0.02, 0.05], &r, [3.0, 3.0, 4.0], 0.2, &lim).expect("ilqr");
        let e = sol.reference.end();
        assert!((e[0] - 1.0).hypot(e[1] - 1.0) < 1e-2, "{e:?}");
    }

    #[test]
    fn hostile_references_are_refused_before_allocating() {
        let lim = Limits::TRACKING;
        for dt in [0.0, -0.1, f64::NAN, f64::INFINITY, 1e-300, 1e9] {
            assert!(
                Reference::sharp([0.0; 3], [1.0, 0.0, 0.0], &lim, dt).is_err(),
                "{dt}"
            );
        }
        let slow = Limits { v: 1e-3, ..lim };
        assert!(Reference::sharp([0.0; 3], [900.0, 0.0, 0.0], &slow, 1e-3).is_err());
        assert!(Reference::sharp([0.0; 3], [1e300, 0.0, 0.0], &lim, 0.1).is_err());
        let bad = Limits { w: f64::NAN, ..lim };
        assert!(Reference::smooth([0.0; 3], [1.0, 1.0, 0.0], &bad, 0.1, 0.8).is_err());
        assert!(Reference::circle([0.0; 3], 0.1, 0.2, 1e20, 0.1).is_err());
        let r = Reference::sharp([0.0; 3], [1.0, 0.0, 0.0], &lim, 0.1).expect("reference");
        assert!(r.clone().hold(usize::MAX).is_err());
        let mut nan_end = r.clone();
        if let Some(x) = nan_end.states.last_mut() {
            x[0] = f64::NAN;
        }
        assert!(nan_end.check().is_err());
        assert!(ilqr([0.0; 3], &nan_end, [3.0, 3.0, 4.0], 0.2, &lim).is_err());
        // A malformed reference handed to the tracker directly does not panic.
        let short = Reference {
            dt: 0.1,
            states: vec![[0.0; 3]],
            controls: vec![[0.1, 0.0]; 5],
        };
        let t = LqrTracker::new(short, [3.0, 3.0, 4.0], 0.2);
        assert_eq!(t.control(3, [0.0; 3], true), [0.1, 0.0]);
    }

    #[test]
    fn lqr_pulls_a_perturbed_unicycle_onto_the_reference() {
        let r = Reference::sharp([0.0; 3], [1.0, 1.0, 0.0], &Limits::TRACKING, 0.1)
            .and_then(|r| r.hold(30))
            .expect("reference");
        let t = LqrTracker::new(r.clone(), [3.0, 3.0, 4.0], 0.2);
        let mut x = [0.05, -0.04, 0.1];
        for k in 0..r.controls.len() {
            x = step(x, t.control(k, x, true), 0.1);
        }
        // A unicycle at rest cannot correct sideways, so the tracker must remove the offset while
        // the reference moves: from 6.4 cm it ends within 3 mm and 0.01 rad.
        let e = r.end();
        assert!(
            (x[0] - e[0]).hypot(x[1] - e[1]) < 3e-3 && wrap(x[2] - e[2]).abs() < 1e-2,
            "{x:?} vs {e:?}"
        );
    }
}
