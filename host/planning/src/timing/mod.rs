//! Time-optimal timing of a joint-space path under per-joint velocity and acceleration
//! limits: the algorithm of Kunz & Stilman, "Time-Optimal Trajectory Generation for Path
//! Following with Bounded Acceleration and Velocity" (RSS 2012), written anew. The path's
//! corners are blended with circular arcs, the path speed is integrated in the phase
//! plane forward and backward between switching points, and the trajectory is sampled from
//! the timed profile. Units: joint positions in rad (or m for a prismatic joint; everything
//! below says rad), velocities rad/s, accelerations rad/s², times s. The algorithm's steps
//! are described in `docs/design/planning.md`.

use crate::{Error, Result};

mod backward;
mod forward;
mod integrate;
mod knots;
mod limit_curves;
mod path;
mod phase;
mod switches;

use knots::{timed_knots, Knot};
use path::{clean_waypoints, Path};
use phase::{Phase, Pt};

/// Largest accepted |joint position| of a waypoint, rad: a sanity bound, not a joint limit.
pub const MAX_POSITION: f64 = 1e3;
/// Smallest accepted velocity (rad/s) or acceleration (rad/s²) limit.
pub const MIN_LIMIT: f64 = 1e-6;
/// Largest accepted velocity (rad/s) or acceleration (rad/s²) limit.
pub const MAX_LIMIT: f64 = 1e6;
/// Consecutive waypoints closer than this (Euclidean, rad) are one waypoint.
pub const SAME_WAYPOINT: f64 = 1e-9;
/// Most samples [`Trajectory::samples`] makes before the end.
pub const MAX_SAMPLES: usize = 1_000_000;
/// Most integration steps (forward, backward, scanning) one call may take; a path that needs
/// more (very slow limits with a fine time step) is refused with an error.
pub const MAX_STEPS: usize = 2_000_000;

/// A waypoint that lies within this distance (rad) of the straight line between its
/// neighbours, between them, is dropped: the path goes straight through.
const STRAIGHT: f64 = 1e-9;
/// Lines and arcs shorter than this (rad) are left out.
const MIN_LEN: f64 = 1e-12;
/// A corner that turns by more than π minus this (rad) is not blended: the motion stops there.
const REVERSAL: f64 = 1e-6;
/// Joints whose tangent component is below this do not bound the path acceleration (their
/// acceleration `c'·s̈` is negligible; their `c''·ṡ²` is bounded by the acceleration limit
/// curve).
const TINY_TANGENT: f64 = 1e-12;
/// Relative tolerance of the phase-plane comparisons.
const REL: f64 = 1e-9;
/// Largest turn of the tangent (rad) within one integration step on an arc.
const MAX_TURN: f64 = 0.005;
/// Turn of the tangent (rad) between samples of the search for switching points on arcs.
const SCAN_TURN: f64 = 0.01;
/// Most samples of one arc in that search.
const MAX_SCAN: usize = 100_000;
/// Step lengths tried (each a quarter of the last) along the velocity limit curve.
const FOLLOW_TRIES: usize = 12;

/// Per-joint limits, one entry per joint, in the order of the waypoints' joints.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// Largest |joint velocity|, rad/s, in [[`MIN_LIMIT`], [`MAX_LIMIT`]].
    pub velocity: Vec<f64>,
    /// Largest |joint acceleration|, rad/s², in [[`MIN_LIMIT`], [`MAX_LIMIT`]].
    pub acceleration: Vec<f64>,
}

impl Limits {
    /// The same velocity (rad/s) and acceleration (rad/s²) limit for each of `dof` joints.
    pub fn uniform(dof: usize, velocity: f64, acceleration: f64) -> Self {
        Self {
            velocity: vec![velocity; dof],
            acceleration: vec![acceleration; dof],
        }
    }
}

/// How the path is blended and integrated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimingOptions {
    /// Largest distance (Euclidean in joint space, rad) of a corner's blend from the corner, in
    /// [0, 1]; 0 means no blending: the motion stops at every corner. Default 0.05.
    pub max_deviation: f64,
    /// Integration step of the phase-plane profile on the blends, s, in [1e-5, 0.1]. Default
    /// 1e-3.
    pub time_step: f64,
}

impl Default for TimingOptions {
    fn default() -> Self {
        Self {
            max_deviation: 0.05,
            time_step: 1e-3,
        }
    }
}

/// The state of the trajectory at one time.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryPoint {
    /// Time from the start, s.
    pub time: f64,
    /// Joint positions, rad.
    pub position: Vec<f64>,
    /// Joint velocities, rad/s.
    pub velocity: Vec<f64>,
    /// Joint accelerations, rad/s².
    pub acceleration: Vec<f64>,
}

/// A timed trajectory along the blended path: see [`time_optimal`].
#[derive(Debug, Clone)]
pub struct Trajectory {
    path: Path,
    knots: Vec<Knot>,
    duration: f64,
}

/// Time-optimal trajectory through `path` (waypoints, rad, each with one position per joint),
/// starting and ending at rest, within `limits`, blending the corners as `opts` says.
///
/// Consecutive waypoints within [`SAME_WAYPOINT`] of each other are taken as one, keeping
/// the first and the last waypoints exactly (unless the whole path is within that distance of
/// its first waypoint: then the trajectory is that point); a path of one point gives a
/// trajectory of zero duration. Waypoints on the straight line between their neighbours are passed without
/// stopping. The trajectory starts exactly at the first waypoint and ends exactly at the last.
///
/// Errors: [`Error::Invalid`] for an empty path, waypoints of different lengths, a position
/// that is not finite or beyond ±[`MAX_POSITION`], limits of the wrong length or not finite
/// within [[`MIN_LIMIT`], [`MAX_LIMIT`]], options out of their ranges, or a path that would
/// take more than [`MAX_STEPS`] integration steps; also (it should not happen) when the
/// integration fails.
pub fn time_optimal(
    path: &[Vec<f64>],
    limits: &Limits,
    opts: &TimingOptions,
) -> Result<Trajectory> {
    let dof = validate(path, limits, opts)?;
    let points = clean_waypoints(path);
    let mut path = Path::build(&points, opts.max_deviation, dof);
    path.add_speed_breaks(&limits.velocity);
    // The arcs are integrated step by step, and no faster than the norm of the speed limits:
    // refuse at once what cannot fit the step budget.
    let speed = norm(&limits.velocity);
    let on_arcs: f64 = path
        .segs
        .iter()
        .filter(|g| !g.is_line())
        .map(|g| g.len)
        .sum();
    if on_arcs / speed / opts.time_step > MAX_STEPS as f64 {
        return Err(too_many_steps());
    }
    let mut budget = MAX_STEPS;
    let mut profile: Vec<Pt> = Vec::new();
    for piece in &path.pieces {
        let mut phase = Phase {
            path: &path,
            piece,
            vmax: &limits.velocity,
            amax: &limits.acceleration,
            dt: opts.time_step,
            t: vec![0.0; dof],
            c: vec![0.0; dof],
            loaded: None,
            budget: &mut budget,
        };
        profile.extend(phase.run()?);
    }
    let knots = timed_knots(&path, &profile)?;
    let duration = knots.last().map_or(0.0, |k| k.t);
    if !duration.is_finite() {
        return Err(failed("the duration is not finite"));
    }
    Ok(Trajectory {
        path,
        knots,
        duration,
    })
}

impl Trajectory {
    /// Duration, s.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.path.first.len()
    }

    /// Length of the blended path, rad (Euclidean arc length in joint space).
    pub fn path_length(&self) -> f64 {
        self.path.length
    }

    /// Joint positions (rad) at arc length `s` (rad) along the blended path, `s` clamped to
    /// [0, [`Self::path_length`]]: callers collision-check the path actually followed with it.
    pub fn path_position(&self, s: f64) -> Vec<f64> {
        let mut q = vec![0.0; self.dof()];
        self.path.position(s, &mut q);
        q
    }

    /// State at time `t` (s), clamped to [0, [`Self::duration`]] (NaN is taken as 0). At the end
    /// the position is exactly the last waypoint and the velocity zero; the acceleration there
    /// is that of the final deceleration.
    pub fn sample(&self, t: f64) -> TrajectoryPoint {
        let n = self.dof();
        let t = if t.is_nan() {
            0.0
        } else {
            t.clamp(0.0, self.duration)
        };
        let mut point = TrajectoryPoint {
            time: t,
            position: vec![0.0; n],
            velocity: vec![0.0; n],
            acceleration: vec![0.0; n],
        };
        if self.knots.len() < 2 {
            point.position.copy_from_slice(&self.path.first);
            return point;
        }
        let k = self
            .knots
            .partition_point(|kn| kn.t <= t)
            .saturating_sub(1)
            .min(self.knots.len() - 2);
        let (a, b) = (&self.knots[k], &self.knots[k + 1]);
        let tau = t - a.t;
        let v = (a.v + a.u * tau).clamp(0.0, a.v.max(b.v));
        let s = (a.s + a.v * tau + 0.5 * a.u * tau * tau).clamp(a.s, b.s);
        let seg = &self.path.segs[a.seg];
        // Tangent into the velocity, curvature into the acceleration, then scaled.
        seg.derivatives(s, &mut point.velocity, &mut point.acceleration);
        seg.position(s, &mut point.position);
        for (qd, qdd) in point.velocity.iter_mut().zip(&mut point.acceleration) {
            let (t, c) = (*qd, *qdd);
            *qd = t * v;
            *qdd = t * a.u + c * v * v;
        }
        if t >= self.duration {
            point.position.copy_from_slice(&self.path.last);
            point.velocity.iter_mut().for_each(|q| *q = 0.0);
        }
        point
    }

    /// Samples at 0, `dt`, 2 `dt`, … (s) before the end, then at the end: a single sample for
    /// a trajectory of zero duration. A `dt` that is not a positive finite number gives the
    /// start and the end only; at most [`MAX_SAMPLES`] samples are made before the end (a
    /// smaller `dt` is widened to fit).
    pub fn samples(&self, dt: f64) -> Vec<TrajectoryPoint> {
        let mut out = Vec::new();
        if dt > 0.0 && dt.is_finite() {
            let dt = dt.max(self.duration / MAX_SAMPLES as f64);
            let n = ((self.duration / dt).ceil() as usize).min(MAX_SAMPLES);
            out.reserve(n + 1);
            for k in 0..n {
                let t = k as f64 * dt;
                if t >= self.duration {
                    break;
                }
                out.push(self.sample(t));
            }
        } else if self.duration > 0.0 {
            out.push(self.sample(0.0));
        }
        out.push(self.sample(self.duration));
        out
    }
}

// ---------------------------------------------------------------------------------------
// Validation of the input, and the errors.

fn invalid(what: &str, why: impl Into<String>) -> Error {
    Error::Invalid {
        what: what.into(),
        why: why.into(),
    }
}

fn too_many_steps() -> Error {
    invalid(
        "path",
        format!("timing it would take more than {MAX_STEPS} integration steps (limits too slow for the time step?)"),
    )
}

fn failed(why: &str) -> Error {
    invalid("trajectory timing", why)
}

fn validate(path: &[Vec<f64>], limits: &Limits, opts: &TimingOptions) -> Result<usize> {
    let Some(first) = path.first() else {
        return Err(invalid("path", "it has no waypoint"));
    };
    let dof = first.len();
    if dof == 0 {
        return Err(invalid("path", "the waypoints have no joint"));
    }
    for (k, p) in path.iter().enumerate() {
        if p.len() != dof {
            return Err(invalid(
                "path",
                format!("waypoint {k} has {} joints, waypoint 0 has {dof}", p.len()),
            ));
        }
        if let Some(i) = p
            .iter()
            .position(|q| !q.is_finite() || q.abs() > MAX_POSITION)
        {
            return Err(invalid(
                "path",
                format!(
                    "waypoint {k}, joint {i}: {} is not a finite position within ±{MAX_POSITION} rad",
                    p[i]
                ),
            ));
        }
    }
    for (name, values) in [
        ("velocity limits", &limits.velocity),
        ("acceleration limits", &limits.acceleration),
    ] {
        if values.len() != dof {
            return Err(invalid(
                name,
                format!("{} given for {dof} joints", values.len()),
            ));
        }
        if let Some(i) = values
            .iter()
            .position(|v| !(MIN_LIMIT..=MAX_LIMIT).contains(v))
        {
            return Err(invalid(
                name,
                format!(
                    "joint {i}: {} is not within [{MIN_LIMIT}, {MAX_LIMIT}]",
                    values[i]
                ),
            ));
        }
    }
    if !(0.0..=1.0).contains(&opts.max_deviation) {
        return Err(invalid(
            "max_deviation",
            format!("{} rad is not within [0, 1]", opts.max_deviation),
        ));
    }
    if !(1e-5..=0.1).contains(&opts.time_step) {
        return Err(invalid(
            "time_step",
            format!("{} s is not within [1e-5, 0.1]", opts.time_step),
        ));
    }
    Ok(dof)
}

fn norm(a: &[f64]) -> f64 {
    a.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
