//! Time-optimal timing of a joint-space path under per-joint velocity and acceleration
//! limits.
//!
//! The algorithm is the one of Kunz & Stilman, "Time-Optimal Trajectory Generation for Path
//! Following with Bounded Acceleration and Velocity" (RSS 2012), written anew:
//!
//! 1. **Blending.** The piecewise-linear path through the waypoints gets a circular arc at each
//!    corner, tangent to both lines and no farther than [`TimingOptions::max_deviation`] from
//!    the corner (and using at most half of each adjacent line), so the path is differentiable.
//!    It is parameterised by arc length `s` (in the units of the joints, rad). Where no arc fits
//!    (`max_deviation` 0, or the path turns back on itself) the motion stops at the corner: the
//!    path is cut there into pieces timed one after the other, each from rest to rest.
//! 2. **Phase plane.** The limits bound the path speed `ṡ` (the *velocity limit curve*) and,
//!    where the path is curved, the speed at which some acceleration is still possible (the
//!    *acceleration limit curve*); below them they bound the path acceleration `s̈`. The profile
//!    `ṡ(s)` is integrated forward at the largest `s̈` until it reaches a limit curve (following
//!    the velocity limit curve while that is possible), then backward at the smallest `s̈` from
//!    the next *switching point* until it meets the forward profile, then forward again from
//!    the switching point, and so on; the end is reached backward from rest. Switching points
//!    are where the profile can touch the lower limit curve without crossing it: the curvature
//!    discontinuities (ends of the arcs) and the points where a joint's tangent vanishes on an
//!    arc (kinks of the acceleration limit curve), when the profile can pass there; the tangent
//!    points of the acceleration limit curve; the ends of the stretches where the velocity limit
//!    curve falls faster than the profile may decelerate; and the points where the lower curve
//!    changes from one to the other. The last three are found by sampling the arcs (every
//!    0.01 rad of turn) and bisection.
//!
//!    Integration on the arcs uses steps of [`TimingOptions::time_step`], shortened so that the
//!    tangent turns by at most 0.005 rad, with the extreme acceleration allowed at both ends of
//!    the step (the range moves fast near a kink); it is exact (constant `s̈`) on the lines.
//!    The profile is kept under the velocity limit curve along the chords between knots, not
//!    only at them.
//! 3. **Sampling.** Between the knots of the profile `s̈` is constant; a sample at time `t` is
//!    `q = c(s)`, `q̇ = c'(s) ṡ`, `q̈ = c'(s) s̈ + c''(s) ṡ²`.
//!
//! Internally the profile is kept as `x = ṡ²`, in which a constant `s̈` is a straight line
//! (`dx/ds = 2 s̈`), so the meeting point of a backward and a forward profile is exact.
//!
//! Units: joint positions in rad (or m for a prismatic joint; everything below says rad),
//! velocities rad/s, accelerations rad/s², times s.

use std::f64::consts::PI;

use crate::{Error, Result};

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
// Validation and clean-up of the input.

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

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

fn norm(a: &[f64]) -> f64 {
    a.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Is `p` within [`STRAIGHT`] of the segment from `a` to `b`, strictly between its ends?
fn on_chord(a: &[f64], b: &[f64], p: &[f64]) -> bool {
    let ab: Vec<f64> = a.iter().zip(b).map(|(x, y)| y - x).collect();
    let ap: Vec<f64> = a.iter().zip(p).map(|(x, y)| y - x).collect();
    let len2 = dot(&ab, &ab);
    if len2 <= 0.0 {
        return false;
    }
    let f = dot(&ap, &ab) / len2;
    if !(f > 0.0 && f < 1.0) {
        return false;
    }
    let off: f64 = ap
        .iter()
        .zip(&ab)
        .map(|(x, y)| (x - f * y) * (x - f * y))
        .sum::<f64>()
        .sqrt();
    off <= STRAIGHT
}

/// Drops repeated waypoints (keeping the first and the last exactly) and waypoints on the
/// straight line between their neighbours.
fn clean_waypoints(path: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let (Some(first), Some(last)) = (path.first(), path.last()) else {
        return Vec::new();
    };
    let mut pts: Vec<&Vec<f64>> = vec![first];
    for p in path {
        if pts.last().is_some_and(|q| dist(q, p) > SAME_WAYPOINT) {
            pts.push(p);
        }
    }
    // The last waypoint exactly, instead of an earlier one it repeats.
    while pts.len() > 1 && pts.last().is_some_and(|q| dist(q, last) <= SAME_WAYPOINT) {
        pts.pop();
    }
    if dist(first, last) > SAME_WAYPOINT || pts.len() > 1 {
        pts.push(last);
    }
    // Straight through waypoints on the line between their neighbours.
    let mut kept: Vec<&Vec<f64>> = Vec::with_capacity(pts.len());
    let mut dropped: Vec<&Vec<f64>> = Vec::new();
    for (k, &p) in pts.iter().enumerate() {
        if let (Some(&a), Some(&b)) = (kept.last(), pts.get(k + 1)) {
            if on_chord(a, b, p) && dropped.iter().all(|q| on_chord(a, b, q)) {
                dropped.push(p);
                continue;
            }
        }
        kept.push(p);
        dropped.clear();
    }
    kept.into_iter().cloned().collect()
}

// ---------------------------------------------------------------------------------------
// The blended path.

#[derive(Debug, Clone)]
enum Shape {
    /// From `a` to `b` along the unit `dir`.
    Line {
        a: Vec<f64>,
        b: Vec<f64>,
        dir: Vec<f64>,
    },
    /// Circular arc of radius `r` from `a`, leaving in the unit direction `u` and bending
    /// toward the unit `n` (orthogonal to `u`).
    Arc {
        a: Vec<f64>,
        u: Vec<f64>,
        n: Vec<f64>,
        r: f64,
    },
}

#[derive(Debug, Clone)]
struct Segment {
    /// Arc length of its start along the whole path, rad.
    start: f64,
    /// Length, rad.
    len: f64,
    shape: Shape,
}

impl Segment {
    fn end(&self) -> f64 {
        self.start + self.len
    }

    fn is_line(&self) -> bool {
        matches!(self.shape, Shape::Line { .. })
    }

    /// Position at path arc length `s` (clamped into the segment).
    fn position(&self, s: f64, out: &mut [f64]) {
        let l = (s - self.start).clamp(0.0, self.len);
        match &self.shape {
            Shape::Line { a, b, .. } => {
                if l >= self.len {
                    out.copy_from_slice(b);
                } else {
                    let f = l / self.len;
                    for ((o, p), q) in out.iter_mut().zip(a).zip(b) {
                        *o = p + (q - p) * f;
                    }
                }
            }
            Shape::Arc { a, u, n, r } => {
                let phi = l / r;
                let along = r * phi.sin();
                let half = (0.5 * phi).sin();
                let across = 2.0 * r * half * half;
                for i in 0..out.len() {
                    out[i] = a[i] + u[i] * along + n[i] * across;
                }
            }
        }
    }

    /// Unit tangent `c'(s)` and curvature vector `c''(s)` at path arc length `s`.
    fn derivatives(&self, s: f64, t: &mut [f64], c: &mut [f64]) {
        match &self.shape {
            Shape::Line { dir, .. } => {
                t.copy_from_slice(dir);
                c.iter_mut().for_each(|x| *x = 0.0);
            }
            Shape::Arc { u, n, r, .. } => {
                let (sin, cos) = ((s - self.start).clamp(0.0, self.len) / r).sin_cos();
                for i in 0..t.len() {
                    t[i] = u[i] * cos + n[i] * sin;
                    c[i] = (n[i] * cos - u[i] * sin) / r;
                }
            }
        }
    }
}

/// A stretch of the path timed from rest to rest: segments `segs`, arc lengths `s0..s1`.
#[derive(Debug, Clone)]
struct Piece {
    segs: std::ops::Range<usize>,
    s0: f64,
    s1: f64,
}

#[derive(Debug, Clone)]
struct Path {
    segs: Vec<Segment>,
    pieces: Vec<Piece>,
    /// Sorted arc lengths where the integration must put a knot: the ends of the segments, the
    /// points of the arcs where a joint's tangent component vanishes, and those where the
    /// joint that bounds the speed changes.
    breaks: Vec<f64>,
    /// Those points of the arcs, with their segment.
    kinks: Vec<(f64, usize)>,
    first: Vec<f64>,
    last: Vec<f64>,
    length: f64,
}

enum Corner {
    Blend {
        start: Vec<f64>,
        end: Vec<f64>,
        u: Vec<f64>,
        n: Vec<f64>,
        r: f64,
        len: f64,
    },
    Stop,
    Straight,
}

/// The blend at `p` between `prev` and `next` (distinct from `p`).
fn corner(prev: &[f64], p: &[f64], next: &[f64], max_dev: f64) -> Corner {
    if max_dev <= 0.0 {
        return Corner::Stop;
    }
    let (l1, l2) = (dist(prev, p), dist(p, next));
    let u: Vec<f64> = prev.iter().zip(p).map(|(a, b)| (b - a) / l1).collect();
    let v: Vec<f64> = p.iter().zip(next).map(|(a, b)| (b - a) / l2).collect();
    let diff: f64 = u.iter().zip(&v).map(|(a, b)| (b - a) * (b - a)).sum();
    let sum: f64 = u.iter().zip(&v).map(|(a, b)| (b + a) * (b + a)).sum();
    let angle = 2.0 * diff.sqrt().atan2(sum.sqrt());
    if angle.is_nan() || angle <= 0.0 {
        return Corner::Straight;
    }
    if angle >= PI - REVERSAL {
        return Corner::Stop;
    }
    // Distance from the corner to where the arc touches the lines: the arc's midpoint is
    // `d tan(angle / 4)` from the corner.
    let d = (0.5 * l1).min(0.5 * l2).min(max_dev / (0.25 * angle).tan());
    let r = d / (0.5 * angle).tan();
    let cos = dot(&u, &v);
    let w: Vec<f64> = v.iter().zip(&u).map(|(b, a)| b - cos * a).collect();
    let nw = norm(&w);
    let len = angle * r;
    if !(nw > 0.0 && r > MIN_LEN && len > MIN_LEN && len.is_finite()) {
        return Corner::Stop;
    }
    Corner::Blend {
        start: p.iter().zip(&u).map(|(q, a)| q - d * a).collect(),
        end: p.iter().zip(&v).map(|(q, b)| q + d * b).collect(),
        n: w.iter().map(|x| x / nw).collect(),
        u,
        r,
        len,
    }
}

impl Path {
    /// The blended path through `pts` (cleaned: at least one point, no repeats).
    fn build(pts: &[Vec<f64>], max_dev: f64, dof: usize) -> Self {
        let first = pts.first().cloned().unwrap_or_else(|| vec![0.0; dof]);
        let last = pts.last().cloned().unwrap_or_else(|| first.clone());
        let mut path = Path {
            segs: Vec::new(),
            pieces: Vec::new(),
            breaks: Vec::new(),
            kinks: Vec::new(),
            first,
            last,
            length: 0.0,
        };
        let (mut piece_first, mut piece_s0) = (0, 0.0);
        let mut cur = path.first.clone();
        for k in 1..pts.len() {
            let p = &pts[k];
            let kind = match pts.get(k + 1) {
                Some(next) => corner(&pts[k - 1], p, next, max_dev),
                None => Corner::Stop,
            };
            match kind {
                Corner::Blend {
                    start,
                    end,
                    u,
                    n,
                    r,
                    len,
                } => {
                    path.line(&cur, &start);
                    let s = path.length;
                    path.segs.push(Segment {
                        start: s,
                        len,
                        shape: Shape::Arc { a: start, u, n, r },
                    });
                    path.length = path.segs[path.segs.len() - 1].end();
                    cur = end;
                }
                Corner::Stop => {
                    path.line(&cur, p);
                    if path.segs.len() > piece_first {
                        path.pieces.push(Piece {
                            segs: piece_first..path.segs.len(),
                            s0: piece_s0,
                            s1: path.length,
                        });
                    }
                    piece_first = path.segs.len();
                    piece_s0 = path.length;
                    cur = p.clone();
                }
                Corner::Straight => {}
            }
        }
        path.find_breaks();
        path
    }

    fn line(&mut self, a: &[f64], b: &[f64]) {
        let len = dist(a, b);
        if len <= MIN_LEN {
            return;
        }
        let seg = Segment {
            start: self.length,
            len,
            shape: Shape::Line {
                a: a.to_vec(),
                b: b.to_vec(),
                dir: a.iter().zip(b).map(|(x, y)| (y - x) / len).collect(),
            },
        };
        self.length = seg.end();
        self.segs.push(seg);
    }

    fn find_breaks(&mut self) {
        for (k, seg) in self.segs.iter().enumerate() {
            self.breaks.push(seg.start);
            if let Shape::Arc { u, n, r, .. } = &seg.shape {
                for (ui, ni) in u.iter().zip(n) {
                    if ui.abs() + ni.abs() < MIN_LEN {
                        continue;
                    }
                    // u_i cos φ + n_i sin φ = 0.
                    let mut phi = (-ui).atan2(*ni);
                    if phi < 0.0 {
                        phi += PI;
                    }
                    let l = phi * r;
                    if l > MIN_LEN && l < seg.len - MIN_LEN {
                        self.kinks.push((seg.start + l, k));
                    }
                }
            }
        }
        self.breaks.push(self.length);
        self.breaks.extend(self.kinks.iter().map(|&(s, _)| s));
        self.breaks.sort_by(f64::total_cmp);
        self.breaks.dedup();
        self.kinks.sort_by(|a, b| a.0.total_cmp(&b.0));
    }

    /// Adds to the breaks the points of the arcs where the joint that bounds the speed
    /// changes, `|t_i| / v_i = |t_j| / v_j` (`vmax`, rad/s): between them the velocity limit
    /// curve is one joint's, convex along the arc.
    fn add_speed_breaks(&mut self, vmax: &[f64]) {
        let mut more = Vec::new();
        for seg in &self.segs {
            let Shape::Arc { u, n, r, .. } = &seg.shape else {
                continue;
            };
            for i in 0..u.len() {
                for j in i + 1..u.len() {
                    for sign in [1.0, -1.0] {
                        // (u_i / v_i − ± u_j / v_j) cos φ + (n_i / v_i − ± n_j / v_j) sin φ = 0.
                        let a = u[i] / vmax[i] - sign * u[j] / vmax[j];
                        let b = n[i] / vmax[i] - sign * n[j] / vmax[j];
                        if a.abs() + b.abs() < MIN_LEN {
                            continue;
                        }
                        let mut phi = (-a).atan2(b);
                        if phi < 0.0 {
                            phi += PI;
                        }
                        let l = phi * r;
                        if l > MIN_LEN && l < seg.len - MIN_LEN {
                            more.push(seg.start + l);
                        }
                    }
                }
            }
        }
        self.breaks.extend(more);
        self.breaks.sort_by(f64::total_cmp);
        self.breaks.dedup();
    }

    /// Index of the segment at arc length `s`: the one starting there when `s` is a boundary.
    fn segment_at(&self, s: f64) -> usize {
        self.segs
            .partition_point(|g| g.start <= s)
            .saturating_sub(1)
    }

    fn position(&self, s: f64, out: &mut [f64]) {
        if self.segs.is_empty() || s.is_nan() || s <= 0.0 {
            out.copy_from_slice(&self.first);
        } else if s >= self.length {
            out.copy_from_slice(&self.last);
        } else {
            self.segs[self.segment_at(s)].position(s, out);
        }
    }
}

// ---------------------------------------------------------------------------------------
// Phase-plane integration of one piece.

/// A point of the profile: arc length `s` (rad) and squared path speed `x = ṡ²` (rad²/s²).
#[derive(Debug, Clone, Copy)]
struct Pt {
    s: f64,
    x: f64,
}

/// A switching point: where a backward integration starts and the forward one resumes.
#[derive(Debug, Clone, Copy)]
struct Switch {
    s: f64,
    x: f64,
}

/// Outcome of a step along the velocity limit curve.
#[derive(Debug, Clone, Copy)]
enum Follow {
    /// The next knot.
    To(Pt),
    /// The curve falls faster than the profile may: stop before here.
    Unfollowable,
    /// The curve rises faster than the profile may: accelerate under it instead.
    Rises,
}

/// A point of the forward integration: segment `k`, arc length `s`, squared speed `x`, the
/// next break `nb`, the velocity limit curve `xv` and its slope (going forward), and the
/// range `lo..hi` of path accelerations.
#[derive(Debug, Clone, Copy)]
struct At {
    k: usize,
    s: f64,
    x: f64,
    nb: f64,
    xv: f64,
    slope: f64,
    lo: f64,
    hi: f64,
}

/// What a pass of the forward integration did.
#[derive(Debug, Clone, Copy)]
enum Pass {
    /// Put a knot on (or just under) the velocity limit curve: follow it next.
    OnCurve,
    /// Put a knot under the limit curves.
    Under,
    /// Stopped.
    Stop(Stop),
}

/// How far the acceleration range at the end of a trial step misses the trial acceleration
/// (on the side the extreme pushes against, and on the other; `None` above the acceleration
/// limit curve), and the step's end `(s, x)`.
type Miss = (Option<(f64, f64)>, f64, f64);

/// Why a forward integration stopped before the end.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stop {
    /// At the end of the piece.
    End,
    /// At the acceleration limit curve.
    AccelLimit,
    /// On the velocity limit curve where it falls faster than the profile may.
    VelocityLimit,
}

struct Phase<'a> {
    path: &'a Path,
    piece: &'a Piece,
    vmax: &'a [f64],
    amax: &'a [f64],
    dt: f64,
    /// Tangent and curvature at the point last loaded.
    t: Vec<f64>,
    c: Vec<f64>,
    /// Segment and arc length of the point loaded in `t`, `c`.
    loaded: Option<(usize, f64)>,
    budget: &'a mut usize,
}

fn tol(a: f64) -> f64 {
    REL * (1.0 + a.abs())
}

impl Phase<'_> {
    fn spend(&mut self) -> Result<()> {
        if *self.budget == 0 {
            return Err(too_many_steps());
        }
        *self.budget -= 1;
        Ok(())
    }

    /// The piece's segment at `s` seen going forward (the one starting at a boundary).
    fn seg_fwd(&self, s: f64) -> usize {
        let r = &self.piece.segs;
        r.start
            + self.path.segs[r.clone()]
                .partition_point(|g| g.start <= s)
                .saturating_sub(1)
    }

    /// The piece's segment at `s` seen going backward (the one ending at a boundary).
    fn seg_bwd(&self, s: f64) -> usize {
        let r = &self.piece.segs;
        r.start
            + self.path.segs[r.clone()]
                .partition_point(|g| g.start < s)
                .saturating_sub(1)
    }

    fn next_break(&self, s: f64) -> f64 {
        let b = &self.path.breaks;
        b.get(b.partition_point(|&x| x <= s))
            .map_or(self.piece.s1, |&x| x.min(self.piece.s1))
    }

    fn prev_break(&self, s: f64) -> f64 {
        let b = &self.path.breaks;
        match b.partition_point(|&x| x < s) {
            0 => self.piece.s0,
            i => b[i - 1].max(self.piece.s0),
        }
    }

    fn load(&mut self, k: usize, s: f64) {
        if self.loaded == Some((k, s)) {
            return;
        }
        let path = self.path;
        path.segs[k].derivatives(s, &mut self.t, &mut self.c);
        self.loaded = Some((k, s));
    }

    /// Is squared speed `x` above a limit curve at the loaded point?
    fn above(&self, x: f64) -> bool {
        x > self.vel_curve().0 || self.accel_range(x).is_none()
    }

    /// Range of path accelerations (rad/s²) at squared speed `x` at the loaded point; `None`
    /// above the acceleration limit curve (a range empty by rounding only is its midpoint).
    fn accel_range(&self, x: f64) -> Option<(f64, f64)> {
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for ((&ti, &ci), &a) in self.t.iter().zip(&self.c).zip(self.amax) {
            if ti.abs() < TINY_TANGENT {
                continue;
            }
            let (p, q) = ((-a - ci * x) / ti, (a - ci * x) / ti);
            let (l, h) = if ti > 0.0 { (p, q) } else { (q, p) };
            lo = lo.max(l);
            hi = hi.min(h);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        if lo <= hi {
            Some((lo, hi))
        } else if lo - hi <= REL * (lo.abs() + hi.abs()) + 1e-12 {
            let m = 0.5 * (lo + hi);
            Some((m, m))
        } else {
            None
        }
    }

    /// Velocity limit curve at the loaded point: squared speed (rad²/s²) and its slope
    /// `dx/ds` (rad/s²).
    fn vel_curve(&self) -> (f64, f64) {
        let (mut best, mut slope) = (f64::INFINITY, 0.0);
        for ((&ti, &ci), &v) in self.t.iter().zip(&self.c).zip(self.vmax) {
            if ti == 0.0 {
                continue;
            }
            let q = v / ti;
            if q * q < best {
                best = q * q;
                slope = -2.0 * best * ci / ti;
            }
        }
        (best, slope)
    }

    /// Acceleration limit curve at the loaded point: the largest squared speed (rad²/s²) at
    /// which some path acceleration keeps every joint within its limit.
    fn acc_curve(&self) -> f64 {
        self.acc_curve_slope().0
    }

    /// The acceleration limit curve at the loaded point (rad²/s²) and its slope `dx/ds`
    /// (rad/s²) on an arc. Each pair of joints `(i, j)` bounds it by
    /// `(a_i |t_j| + a_j |t_i|) / |c_i t_j − c_j t_i|`, whose denominator is constant along a
    /// circle (`t' = c`, `c' = −t / r²`).
    fn acc_curve_slope(&self) -> (f64, f64) {
        let (mut best, mut slope) = (f64::INFINITY, 0.0);
        let n = self.t.len();
        for i in 0..n {
            let (ti, ci, ai) = (self.t[i], self.c[i], self.amax[i]);
            if ci == 0.0 && ti == 0.0 {
                continue;
            }
            for j in i + 1..n {
                let (tj, cj, aj) = (self.t[j], self.c[j], self.amax[j]);
                let den = (ci * tj - cj * ti).abs();
                if den > 0.0 {
                    let x = (ai * tj.abs() + aj * ti.abs()) / den;
                    if x < best {
                        best = x;
                        slope = (ai * tj.signum() * cj + aj * ti.signum() * ci) / den;
                    }
                }
            }
        }
        (best, slope)
    }

    fn limit_at(&mut self, k: usize, s: f64) -> (f64, f64) {
        self.load(k, s);
        (self.vel_curve().0, self.acc_curve())
    }

    /// One forward step of `tau` (s; shorter if decelerating hard) at path acceleration `u`,
    /// ending at `s_max` at the latest.
    fn step_fwd(&self, s: f64, x: f64, u: f64, s_max: f64, tau: f64) -> Result<(f64, f64)> {
        let v = x.max(0.0).sqrt();
        let tau = if u < 0.0 { tau.min(0.5 * v / -u) } else { tau };
        let s1 = (s + 0.5 * tau * (2.0 * v + u * tau)).min(s_max);
        if s1.is_nan() || s1 <= s {
            return Err(failed("the forward integration stalled"));
        }
        Ok((s1, (x + 2.0 * u * (s1 - s)).max(0.0)))
    }

    /// One backward step, the mirror of [`Self::step_fwd`], ending at `s_min` at the earliest.
    fn step_bwd(&self, s: f64, x: f64, u: f64, s_min: f64, tau: f64) -> Result<(f64, f64)> {
        let v = x.max(0.0).sqrt();
        let tau = if u > 0.0 { tau.min(0.5 * v / u) } else { tau };
        let s0 = (s - 0.5 * tau * (2.0 * v - u * tau)).max(s_min);
        if s0.is_nan() || s0 >= s {
            return Err(failed("the backward integration stalled"));
        }
        Ok((s0, (x - 2.0 * u * (s - s0)).max(0.0)))
    }

    /// One step on arc segment `k` from `(s, x)` toward `bound` at the extreme path
    /// acceleration that the limits allow at both ends of the step: the largest `u ≤ hi`
    /// forward (`fwd`), the smallest `u ≥ lo` backward, `(lo, hi)` being the range at the
    /// start. This keeps the integration stable where the range changes fast (near a kink).
    /// Where the range at the end no longer contains that `u` (near the acceleration limit
    /// curve, where the range is narrow and moves), the time step is shortened. When no `u`
    /// in the range keeps the end under the acceleration limit curve, the step at the
    /// extreme is returned (it reaches the curve). Returns `(u, s1, x1)`.
    fn step(
        &mut self,
        k: usize,
        s: f64,
        x: f64,
        range: (f64, f64),
        bound: f64,
        fwd: bool,
    ) -> Result<(f64, f64, f64)> {
        // No longer than it takes to reach `bound` at the current speed.
        let v = x.max(0.0).sqrt();
        let reach = (bound - s).abs() / v;
        let mut tau = if reach < self.dt { reach } else { self.dt };
        for _ in 0..6 {
            let (u, s1, x1, ok) = self.step_tau(k, s, x, range, bound, fwd, tau)?;
            if ok {
                return Ok((u, s1, x1));
            }
            tau *= 0.25;
        }
        let (u, s1, x1, _) = self.step_tau(k, s, x, range, bound, fwd, tau)?;
        Ok((u, s1, x1))
    }

    /// [`Self::step`] with time step `tau`; the last value says whether the range at the end
    /// contains `u` (or the end is above the acceleration limit curve for every `u`).
    #[allow(clippy::too_many_arguments)]
    fn step_tau(
        &mut self,
        k: usize,
        s: f64,
        x: f64,
        (lo, hi): (f64, f64),
        bound: f64,
        fwd: bool,
        tau: f64,
    ) -> Result<(f64, f64, f64, bool)> {
        // By how much the range at the end misses `u` on the side that the extreme pushes
        // against, and on the other side (`None`: the end is above the curve).
        let miss = |me: &mut Self, u: f64| -> Result<Miss> {
            let (s1, x1) = if fwd {
                me.step_fwd(s, x, u, bound, tau)?
            } else {
                me.step_bwd(s, x, u, bound, tau)?
            };
            me.load(k, s1);
            let m = me
                .accel_range(x1)
                .map(|(l, h)| if fwd { (u - h, l - u) } else { (l - u, u - h) });
            Ok((m, s1, x1))
        };
        let small = |u: f64| 1e-6 * (1.0 + u.abs());
        let fits = |m: Option<(f64, f64)>, u: f64| m.is_some_and(|m| m.0 <= small(u));
        let done = |m: Option<(f64, f64)>, u: f64| m.is_some_and(|m| m.1 <= small(u));
        let (first, other) = if fwd { (hi, lo) } else { (lo, hi) };
        let (m, s1, x1) = miss(self, first)?;
        if fits(m, first) {
            return Ok((first, s1, x1, done(m, first)));
        }
        if let Some((m, _)) = m {
            // The extreme at the end.
            let u = if fwd {
                (first - m).max(lo)
            } else {
                (first + m).min(hi)
            };
            let (m2, s2, x2) = miss(self, u)?;
            if fits(m2, u) {
                return Ok((u, s2, x2, done(m2, u)));
            }
        }
        let (mo, _, _) = miss(self, other)?;
        if !fits(mo, other) {
            return Ok((first, s1, x1, mo.is_none()));
        }
        let (mut good, mut bad) = (other, first);
        for _ in 0..60 {
            if (bad - good).abs() <= 1e-12 * (1.0 + good.abs()) {
                break;
            }
            let mid = 0.5 * (good + bad);
            let (mm, _, _) = miss(self, mid)?;
            if fits(mm, mid) {
                good = mid;
            } else {
                bad = mid;
            }
        }
        let (m, s1, x1) = miss(self, good)?;
        Ok((good, s1, x1, done(m, good)))
    }

    /// Bisection for where `past(σ)` starts to hold in `(lo, hi]`, given that it does not at
    /// `lo` and does at `hi`: the final bracket (about 1e-13 relative), whose first end is
    /// not past and second is.
    fn bisect(
        &mut self,
        mut lo: f64,
        mut hi: f64,
        mut past: impl FnMut(&mut Self, f64) -> bool,
    ) -> (f64, f64) {
        for _ in 0..64 {
            if hi - lo <= 1e-13 * (1.0 + hi.abs()) {
                break;
            }
            let mid = 0.5 * (lo + hi);
            if past(self, mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        (lo, hi)
    }

    /// Where to evaluate the limits at `s` on segment `k` when moving toward `toward`: just
    /// inside the segment, toward `toward`, when `s` is a break (an end of the segment or a
    /// kink, where the one-sided limits differ from those at the point), else `s`.
    fn inside(&self, k: usize, s: f64, toward: f64) -> f64 {
        let at_break = self
            .path
            .breaks
            .binary_search_by(|b| b.total_cmp(&s))
            .is_ok();
        if self.path.segs[k].is_line() || !at_break {
            return s;
        }
        s + (toward - s).signum() * self.probe(k).min(0.01 * (toward - s).abs())
    }

    /// Integrates forward from the profile's last point at the largest acceleration,
    /// following the velocity limit curve where possible, until the end or a limit curve.
    fn forward(&mut self, prof: &mut Vec<Pt>) -> Result<Stop> {
        // Whether the last knot was put on (or just under) the velocity limit curve.
        let mut following = false;
        // Passes in a row that put no knot further on than the last: a couple on reaching a
        // limit curve; more would go on for ever.
        let (mut idle, mut last_s) = (0, f64::NEG_INFINITY);
        loop {
            self.spend()?;
            let Some(&Pt { s, x }) = prof.last() else {
                return Err(failed("empty profile"));
            };
            if s >= self.piece.s1 {
                return Ok(Stop::End);
            }
            if s > last_s {
                (idle, last_s) = (0, s);
            } else {
                idle += 1;
                if idle > 8 {
                    return Err(failed("the forward integration stalled"));
                }
            }
            let Some(at) = self.at(s, x) else {
                return Ok(Stop::AccelLimit);
            };
            let mut pass = None;
            if following || x >= at.xv * (1.0 - REL) {
                pass = self.along_curve(prof, &at)?;
            }
            let pass = match pass {
                Some(pass) => pass,
                None => self.under_curves(prof, &at)?,
            };
            match pass {
                Pass::OnCurve => following = true,
                Pass::Under => following = false,
                Pass::Stop(stop) => return Ok(stop),
            }
        }
    }

    /// The forward integration's point `(s, x)`: `None` above the acceleration limit curve.
    fn at(&mut self, s: f64, x: f64) -> Option<At> {
        let k = self.seg_fwd(s);
        let nb = self.next_break(s);
        let se = self.inside(k, s, nb);
        self.load(k, s);
        let (xv, _) = self.vel_curve();
        self.load(k, se);
        let (_, slope) = self.vel_curve();
        let (lo, hi) = self.accel_range(x)?;
        Some(At {
            k,
            s,
            x,
            nb,
            xv,
            slope,
            lo,
            hi,
        })
    }

    /// A pass on the velocity limit curve: follows it while the limits allow. `None` where
    /// it rises faster than the profile may (the profile accelerates under it instead).
    fn along_curve(&mut self, prof: &mut Vec<Pt>, at: &At) -> Result<Option<Pass>> {
        let want = 0.5 * at.slope;
        if want < at.lo - tol(at.lo) {
            return Ok(Some(Pass::Stop(Stop::VelocityLimit)));
        }
        let knot = if self.path.segs[at.k].is_line() {
            (want <= at.hi).then_some(Pt { s: at.nb, x: at.xv })
        } else {
            match self.follow_step(at)? {
                Follow::To(p) => Some(p),
                Follow::Unfollowable => return Ok(Some(Pass::Stop(Stop::VelocityLimit))),
                Follow::Rises => None,
            }
        };
        Ok(knot.map(|p| {
            prof.push(p);
            Pass::OnCurve
        }))
    }

    /// A pass under the limit curves at the largest acceleration: to the next break or the
    /// velocity limit curve on a line, one step on an arc, stopping at the acceleration
    /// limit curve.
    fn under_curves(&mut self, prof: &mut Vec<Pt>, at: &At) -> Result<Pass> {
        let At {
            k, s, x, nb, xv, ..
        } = *at;
        if self.path.segs[k].is_line() {
            // No curvature: the acceleration range is the same all along the line.
            let x_end = x + 2.0 * at.hi * (nb - s);
            if x_end > xv && at.hi > 0.0 {
                let sh = (s + (xv - x) / (2.0 * at.hi)).clamp(s, nb);
                prof.push(Pt { s: sh, x: xv });
                return Ok(Pass::OnCurve);
            }
            prof.push(Pt {
                s: nb,
                x: x_end.max(0.0),
            });
            return Ok(Pass::Under);
        }
        let reach = nb.min(s + self.max_ds(k));
        let (u, s1, x1) = self.step(k, s, x, (at.lo, at.hi), reach, true)?;
        let Some(top) = self.goes_over(at, u, s1, x1) else {
            prof.push(Pt { s: s1, x: x1 });
            return Ok(Pass::Under);
        };
        let (sc, _) = self.bisect(s, top, |me, q| {
            me.load(k, q);
            me.above(x + 2.0 * u * (q - s))
        });
        self.load(k, sc);
        let (xvc, _) = self.vel_curve();
        let xc = x + 2.0 * u * (sc - s);
        if self.accel_range(xvc).is_some() {
            // At the velocity limit curve: whether it can be followed is seen next.
            prof.push(Pt {
                s: sc,
                x: xc.min(xvc),
            });
            return Ok(Pass::OnCurve);
        }
        prof.push(Pt { s: sc, x: xc });
        Ok(Pass::Stop(Stop::AccelLimit))
    }

    /// Where the forward step from `at` at path acceleration `u` to `(s1, x1)` goes above a
    /// limit curve: an arc length past which to look for the crossing, or `None` when it
    /// stays under both curves at the end and halfway, and under the velocity limit curve in
    /// between (that curve is convex along the step, one joint bounding the speed between
    /// breaks, about `xv + slope δ + κ δ² / 2`, and may sag under the straight `x + 2 u δ`
    /// where the two start close).
    fn goes_over(&mut self, at: &At, u: f64, s1: f64, x1: f64) -> Option<f64> {
        let At {
            k, s, x, xv, slope, ..
        } = *at;
        let sm = 0.5 * (s + s1);
        self.load(k, sm);
        let over_mid = self.above(x + 2.0 * u * (sm - s));
        // The end last: it is where the next step starts.
        self.load(k, s1);
        let over_end = self.above(x1);
        let (xv1, _) = self.vel_curve();
        let (ds, g0, g1) = (s1 - s, xv - x, xv1 - x1);
        let dg = slope - 2.0 * u;
        let kappa = 2.0 * (g1 - g0 - dg * ds) / (ds * ds);
        let dip = -dg / kappa;
        let sags = dg < 0.0 && kappa > 0.0 && dip < ds && g0 - dg * dg / (2.0 * kappa) < -1e-9 * xv;
        if sags {
            Some(s + dip)
        } else if over_mid {
            Some(sm)
        } else if over_end {
            Some(s1)
        } else {
            None
        }
    }

    /// One step along the velocity limit curve on an arc from `at`, on or just under the
    /// curve. The knot is put on the curve's tangent at `at` (the curve of each joint is
    /// convex on an arc, so the chord to the knot stays under it), and not above the curve at
    /// the knot or halfway, nor past where the acceleration limit curve comes under the
    /// velocity one. The acceleration of the chord must be allowed at both of its ends, else
    /// the step is shortened: where the curve comes to rise faster than the profile may, to
    /// follow it up to about there (giving up at once would accelerate from `at` faster than
    /// the curve rises there, meet it again at once, and start the next step where this one
    /// did, for ever); where it comes to fall faster than the profile may decelerate, to stop
    /// before there, the knot being raised toward the curve just after a velocity switching
    /// point ([`Self::raised_knot`]).
    fn follow_step(&mut self, at: &At) -> Result<Follow> {
        let At {
            k,
            s,
            x,
            nb,
            xv,
            slope,
            hi,
            ..
        } = *at;
        let full = (xv.sqrt() * self.dt).min(self.max_ds(k));
        if full.is_nan() || s + full <= s {
            return Err(failed("the forward integration stalled"));
        }
        let mut ds = full;
        // Whether the last step tried failed for rising faster than the profile may.
        let mut rises = false;
        for _ in 0..FOLLOW_TRIES {
            let mut s1 = if s + ds >= nb { nb } else { s + ds };
            self.load(k, s1);
            if self.accel_range(self.vel_curve().0).is_none() {
                // The acceleration limit curve comes under the velocity one: up to there.
                (s1, _) = self.bisect(s, s1, |me, q| {
                    me.load(k, q);
                    me.accel_range(me.vel_curve().0).is_none()
                });
                if s1 <= s {
                    return Ok(Follow::Rises);
                }
            }
            let ds1 = s1 - s;
            self.load(k, 0.5 * (s + s1));
            let (xvm, _) = self.vel_curve();
            self.load(k, s1);
            let (xv1, _) = self.vel_curve();
            let x1 = xv1.min(2.0 * xvm - x).min(xv + slope * ds1);
            let u = (x1 - x) / (2.0 * ds1);
            if u > hi + tol(hi) {
                return Ok(Follow::Rises);
            }
            let Some((lo1, hi1)) = self.accel_range(x1) else {
                return Ok(Follow::Rises);
            };
            rises = u > hi1 + tol(hi1);
            if rises {
                ds = 0.25 * ds.min(ds1);
                continue;
            }
            if u >= lo1 - tol(lo1) {
                return Ok(Follow::To(Pt { s: s1, x: x1 }));
            }
            if let Some(p) = self.raised_knot(at, s1, xv1, lo1) {
                return Ok(Follow::To(p));
            }
            ds = 0.25 * ds.min(ds1);
        }
        Ok(if rises {
            Follow::Rises
        } else {
            Follow::Unfollowable
        })
    }

    /// The knot at `s1` of a step along the velocity limit curve from `at` (`xv1` the curve
    /// there, `lo1` the smallest acceleration allowed on the tangent there), raised toward
    /// the curve where the chord to it would decelerate more than the limits allow there.
    /// Just after a velocity switching point the curve is followable but a chord under it is
    /// not, by a little (a constant acceleration cannot both stay under the convex curve and
    /// decelerate no more than the limit allows at the knot): the chord may rise above the
    /// curve by 1e-7 of it at most, not above the curve at the knot, if that keeps the
    /// deceleration within 1e-6 of the limit. `None` when it may not (shorten the step).
    fn raised_knot(&mut self, at: &At, s1: f64, xv1: f64, lo1: f64) -> Option<Pt> {
        let At {
            k, s, x, xv, slope, ..
        } = *at;
        let ds1 = s1 - s;
        // The curve is about `xv + slope δ + κ δ² / 2` along the step: a chord from `x` of
        // slope `slope + e` rises above it by at most `e² / (2 κ) − (xv − x)`.
        let kappa = 2.0 * (xv1 - xv - slope * ds1) / (ds1 * ds1);
        let room = (xv - x).max(0.0) + 1e-7 * xv;
        let rise = if kappa > 0.0 {
            (2.0 * kappa * room).sqrt()
        } else {
            room / ds1
        };
        let mut lo1 = lo1;
        for _ in 0..3 {
            let x1 = xv1.min(x + 2.0 * (lo1 + tol(lo1)) * ds1);
            let u = (x1 - x) / (2.0 * ds1);
            self.load(k, s1);
            match self.accel_range(x1) {
                Some((l, h)) if u <= h + tol(h) => {
                    if u >= l - 1e-6 * (1.0 + l.abs()) {
                        return (2.0 * u <= slope + rise).then_some(Pt { s: s1, x: x1 });
                    }
                    lo1 = l;
                }
                _ => return None,
            }
        }
        None
    }

    /// Integrates backward at the smallest acceleration from `start` until the curve meets
    /// the profile, and splices it in.
    fn backward(&mut self, prof: &mut Vec<Pt>, start: Pt) -> Result<()> {
        let Some(&last) = prof.last() else {
            return Err(failed("empty profile"));
        };
        let mut above = vec![start];
        let mut cur = start;
        let mut prev: Option<(f64, f64)> = None;
        if start.s <= last.s {
            let d = start.x - interp(prof, start.s);
            if d > 0.0 {
                splice(
                    prof,
                    Pt {
                        s: start.s,
                        x: start.x - d,
                    },
                    &[],
                );
                return Ok(());
            }
            prev = Some((start.s, d));
        }
        loop {
            self.spend()?;
            if cur.s <= self.piece.s0 {
                return Err(failed(
                    "the backward integration did not meet the forward profile",
                ));
            }
            let k = self.seg_bwd(cur.s);
            let pb = self.prev_break(cur.s);
            let se = self.inside(k, cur.s, pb);
            self.load(k, se);
            let Some((lo, hi)) = self.accel_range(cur.x) else {
                return Err(failed(
                    "the backward integration went above the acceleration limit curve",
                ));
            };
            let next = if self.path.segs[k].is_line() {
                Pt {
                    s: pb,
                    x: cur.x - 2.0 * lo * (cur.s - pb),
                }
            } else {
                let reach = pb.max(cur.s - self.max_ds(k));
                let (_, s0, x0) = self.step(k, cur.s, cur.x, (lo, hi), reach, false)?;
                Pt { s: s0, x: x0 }
            };
            if let Some(p) = meet(prof, cur, next, &mut prev) {
                splice(prof, p, &above);
                return Ok(());
            }
            if next.s > last.s {
                self.load(k, next.s);
                if self.above((next.x - 1e-12) / (1.0 + 1e-6)) {
                    return Err(failed(
                        "the backward integration crossed a limit curve before meeting the forward profile",
                    ));
                }
            }
            above.push(next);
            cur = next;
        }
    }

    /// Switching points on the acceleration limit curve at curvature discontinuities and
    /// kinks.
    fn accel_switches(&mut self) -> Vec<Switch> {
        let mut out = Vec::new();
        let range = self.piece.segs.clone();
        for k in range.start + 1..range.end {
            let sb = self.path.segs[k].start;
            out.extend(self.switch_at(k - 1, k, sb));
        }
        let path = self.path;
        for &(s, k) in &path.kinks {
            if range.contains(&k) {
                out.extend(self.switch_at(k, k, s));
            }
        }
        out
    }

    /// The switching point on the acceleration limit curve at `s`, the end of segment `kb`
    /// and the start of `ka` (the same segment at a kink), if the profile can pass there:
    /// backward from it staying under the curve before, forward under the curve after.
    fn switch_at(&mut self, kb: usize, ka: usize, s: f64) -> Option<Switch> {
        let (xv_b, xa_b) = self.limit_at(kb, s);
        let (xv_a, xa_a) = self.limit_at(ka, s);
        let xs = xa_b.min(xa_a);
        if !xs.is_finite() || xs > xv_b.min(xv_a) * (1.0 + REL) {
            return None;
        }
        let (hb, ha) = (self.side_step(kb, s), self.side_step(ka, s));
        let before_ok = xa_b > xa_a * (1.0 + REL) || {
            let (_, xm) = self.limit_at(kb, s - hb);
            self.accel_range(xs)
                .is_some_and(|(lo, _)| 2.0 * lo >= (xa_b - xm) / hb)
        };
        let after_ok = xa_a > xa_b * (1.0 + REL) || {
            let (_, xp) = self.limit_at(ka, s + ha);
            self.accel_range(xs)
                .is_some_and(|(_, hi)| 2.0 * hi <= (xp - xa_a) / ha)
        };
        (before_ok && after_ok).then_some(Switch { s, x: xs })
    }

    /// A one-sided finite-difference step at the break `s` on segment `k`, short of the
    /// neighbouring breaks, rad.
    fn side_step(&self, k: usize, s: f64) -> f64 {
        let gap = (s - self.prev_break(s)).min(self.next_break(s) - s);
        let gap = if gap > 0.0 {
            gap
        } else {
            self.path.segs[k].len
        };
        self.probe(k).min(0.25 * gap)
    }

    /// Number of samples of the search for switching points over `len` (rad) of arc `k`.
    fn scan_count(&self, k: usize, len: f64) -> usize {
        let r = match &self.path.segs[k].shape {
            Shape::Arc { r, .. } => *r,
            Shape::Line { .. } => return 1,
        };
        let n = (len / (SCAN_TURN * r)).ceil();
        if n.is_finite() {
            (n as usize).clamp(8, MAX_SCAN)
        } else {
            MAX_SCAN
        }
    }

    /// Longest integration step on segment `k`, rad: on an arc, [`MAX_TURN`] of its radius,
    /// so that the limits, checked at the ends of a step, change little within it.
    fn max_ds(&self, k: usize) -> f64 {
        match &self.path.segs[k].shape {
            Shape::Arc { r, .. } => MAX_TURN * r,
            Shape::Line { .. } => f64::INFINITY,
        }
    }

    /// A small arc-length step for finite differences on segment `k`, rad.
    fn probe(&self, k: usize) -> f64 {
        let seg = &self.path.segs[k];
        let r = match &seg.shape {
            Shape::Arc { r, .. } => *r,
            Shape::Line { .. } => 1.0,
        };
        (1e-6 * r.min(1.0))
            .max(1e-13 * (1.0 + seg.end().abs()))
            .min(0.25 * seg.len)
    }

    /// Is the limit curve at `s` on arc `k` one along which the profile can only arrive
    /// (backward), not leave (forward)? For the velocity limit curve where it is the lower
    /// one: it falls faster than the profile may decelerate. For the acceleration limit
    /// curve: its slope is below the profile's `2 s̈` on it.
    fn backward_only(&mut self, k: usize, s: f64) -> bool {
        self.load(k, s);
        let (xv, slope_v) = self.vel_curve();
        let (xa, slope_a) = self.acc_curve_slope();
        if xv <= xa {
            self.accel_range(xv)
                .is_some_and(|(lo, _)| 0.5 * slope_v < lo - tol(lo))
        } else {
            self.accel_range(xa * (1.0 - REL))
                .is_some_and(|(lo, hi)| slope_a < lo + hi)
        }
    }

    /// Switching points in `[from, until]` found by sampling the arcs: where the lower limit
    /// curve turns from backward-only to leavable forward ([`Self::backward_only`]). These
    /// are the tangent points of the acceleration limit curve, the ends of the stretches
    /// where the velocity limit curve falls too fast (also at the end of an arc), and the
    /// points where the lower curve changes from one to the other. The first one only when
    /// `first`.
    fn scan_switches(&mut self, from: f64, until: f64, first: bool) -> Result<Vec<Switch>> {
        let path = self.path;
        let mut out = Vec::new();
        // Last sample: arc length, backward-only, segment.
        let mut prev: Option<(f64, bool, usize)> = None;
        for k in self.seg_fwd(from)..self.piece.segs.end {
            let seg = &path.segs[k];
            if seg.start > until {
                break;
            }
            let (a, b) = (from.max(seg.start), until.min(seg.end()));
            if seg.is_line() {
                // Flat velocity limit curve, no acceleration one: leavable all along.
                if let Some((_, true, _)) = prev {
                    out.extend(self.switch_on_curve(k, seg.start));
                    if first && !out.is_empty() {
                        return Ok(out);
                    }
                }
                prev = Some((b, false, k));
                continue;
            }
            // Between the breaks of the arc (its kinks), not at them.
            let lo_b = path.breaks.partition_point(|&x| x <= a);
            let mut edges = vec![a];
            edges.extend(path.breaks[lo_b..].iter().take_while(|&&x| x < b).copied());
            edges.push(b);
            for w in edges.windows(2) {
                let (p, q) = (w[0], w[1]);
                if q <= p {
                    continue;
                }
                let d = self.probe(k).min(0.25 * (q - p));
                let n = self.scan_count(k, q - p);
                for j in 0..=n {
                    self.spend()?;
                    let z = p + d + (q - p - 2.0 * d) * j as f64 / n as f64;
                    let back = self.backward_only(k, z);
                    if let Some((pz, true, pk)) = prev {
                        if !back {
                            let at = if pk == k {
                                self.bisect(pz, z, |me, y| !me.backward_only(k, y)).1
                            } else {
                                seg.start
                            };
                            out.extend(self.switch_on_curve(k, at));
                            if first && !out.is_empty() {
                                return Ok(out);
                            }
                        }
                    }
                    prev = Some((z, back, k));
                }
            }
        }
        Ok(out)
    }

    /// The switching point on the lower limit curve at `s` on segment `k` (just under the
    /// acceleration limit curve, or on the velocity one when the acceleration limit curve is
    /// not under it nearby).
    fn switch_on_curve(&mut self, k: usize, s: f64) -> Option<Switch> {
        let h = self.probe(k);
        let seg = &self.path.segs[k];
        let (xv, xa) = self.limit_at(k, s);
        if xa < xv {
            return Some(Switch {
                s,
                x: xa * (1.0 - REL),
            });
        }
        let (_, xa_m) = self.limit_at(k, (s - h).max(seg.start));
        let (_, xa_p) = self.limit_at(k, (s + h).min(seg.end()));
        (xv <= xa_m.min(xa_p)).then_some(Switch { s, x: xv })
    }

    /// The profile of the piece, from rest at its start to rest at its end.
    fn run(&mut self) -> Result<Vec<Pt>> {
        let (s0, s1) = (self.piece.s0, self.piece.s1);
        let mut switches = self.accel_switches();
        switches.extend(self.scan_switches(s0, s1, false)?);
        switches.sort_by(|a, b| a.s.total_cmp(&b.s).then(a.x.total_cmp(&b.x)));
        let mut prof = vec![Pt { s: s0, x: 0.0 }];
        let mut last_switch = f64::NEG_INFINITY;
        let most_rounds = 2 * switches.len() + 1000;
        for _ in 0..most_rounds {
            let stop = self.forward(&mut prof)?;
            if stop == Stop::End {
                self.backward(&mut prof, Pt { s: s1, x: 0.0 })?;
                return Ok(prof);
            }
            let s_last = prof.last().map_or(s0, |p| p.s);
            let mut next = switches
                .iter()
                .find(|p| p.s > last_switch && p.s >= s_last - tol(s_last))
                .copied();
            if stop == Stop::VelocityLimit {
                // Where exactly the curve becomes followable again, from here.
                let until = next.map_or(s1, |p| p.s);
                let found = self.scan_switches(s_last.max(last_switch), until, true)?;
                if let Some(sw) = found.first().filter(|p| p.s > last_switch) {
                    if next.is_none_or(|n| sw.s < n.s) {
                        next = Some(*sw);
                    }
                }
            }
            let Some(sw) = next else {
                self.backward(&mut prof, Pt { s: s1, x: 0.0 })?;
                return Ok(prof);
            };
            last_switch = sw.s;
            self.backward(&mut prof, Pt { s: sw.s, x: sw.x })?;
        }
        Err(failed("too many switching points"))
    }
}

/// The profile's squared speed at `s` (linear between knots).
fn interp(prof: &[Pt], s: f64) -> f64 {
    let i = prof.partition_point(|p| p.s <= s);
    match (i.checked_sub(1).and_then(|j| prof.get(j)), prof.get(i)) {
        (Some(a), Some(b)) if b.s > a.s => a.x + (b.x - a.x) * (s - a.s) / (b.s - a.s),
        (Some(a), _) => a.x,
        (None, Some(b)) => b.x,
        (None, None) => 0.0,
    }
}

/// Where the backward step from `hi` to `lo` (lower `s`) meets the forward profile, if it
/// does: the first point, going backward, where the backward curve rises above the profile.
/// `prev` carries the last compared point (arc length, backward minus forward squared speed).
fn meet(prof: &[Pt], hi: Pt, lo: Pt, prev: &mut Option<(f64, f64)>) -> Option<Pt> {
    let last_s = prof.last()?.s;
    if lo.s > last_s {
        return None;
    }
    let xb = |s: f64| {
        if hi.s > lo.s {
            lo.x + (hi.x - lo.x) * (s - lo.s) / (hi.s - lo.s)
        } else {
            lo.x
        }
    };
    let check = |s: f64, xf: f64, prev: &mut Option<(f64, f64)>| -> Option<Pt> {
        let d = xb(s) - xf;
        if d > 0.0 {
            return Some(match *prev {
                // Above it from the first comparison: join at once.
                None => Pt { s, x: xf },
                Some((ps, pd)) => {
                    let sc = s + (ps - s) * d / (d - pd);
                    Pt { s: sc, x: xb(sc) }
                }
            });
        }
        *prev = Some((s, d));
        None
    };
    let top = hi.s.min(last_s);
    if prev.is_none() {
        if let Some(p) = check(top, interp(prof, top), prev) {
            return Some(p);
        }
    }
    let i_lo = prof.partition_point(|p| p.s <= lo.s);
    let i_hi = prof.partition_point(|p| p.s < top);
    for p in prof[i_lo..i_hi.max(i_lo)].iter().rev() {
        if let Some(q) = check(p.s, p.x, prev) {
            return Some(q);
        }
    }
    check(lo.s, interp(prof, lo.s), prev)
}

/// Replaces the profile from `p` on by `p` and the backward curve `above` (decreasing `s`).
fn splice(prof: &mut Vec<Pt>, p: Pt, above: &[Pt]) {
    let keep = prof.partition_point(|q| q.s < p.s).max(1);
    prof.truncate(keep);
    prof.push(p);
    prof.extend(above.iter().rev().filter(|q| q.s > p.s));
}

// ---------------------------------------------------------------------------------------
// The timed trajectory.

/// A knot of the timed profile; `u` and `seg` are those of the interval to the next knot.
#[derive(Debug, Clone, Copy)]
struct Knot {
    /// Time, s.
    t: f64,
    /// Arc length, rad.
    s: f64,
    /// Path speed, rad/s.
    v: f64,
    /// Path acceleration to the next knot, rad/s².
    u: f64,
    /// Segment of the interval to the next knot.
    seg: usize,
}

fn timed_knots(path: &Path, profile: &[Pt]) -> Result<Vec<Knot>> {
    // Merge knots closer than rounding (keeping the later speed: the ends of pieces are at
    // rest).
    let mut pts: Vec<Pt> = Vec::with_capacity(profile.len());
    for &p in profile {
        let n = pts.len();
        match pts.last_mut() {
            Some(q) if p.s - q.s <= 1e-13 * (1.0 + p.s.abs()) => {
                if n > 1 {
                    q.x = p.x;
                }
            }
            _ => pts.push(p),
        }
    }
    let mut knots: Vec<Knot> = Vec::with_capacity(pts.len());
    for (i, p) in pts.iter().enumerate() {
        let v = p.x.max(0.0).sqrt();
        let mut t = 0.0;
        if let (Some(prev), Some(q)) = (knots.last_mut(), i.checked_sub(1).map(|j| pts[j])) {
            let ds = p.s - q.s;
            let dt = 2.0 * ds / (prev.v + v);
            if !(dt.is_finite() && dt >= 0.0) {
                return Err(failed("the profile stops inside the path"));
            }
            prev.u = (p.x - q.x) / (2.0 * ds);
            prev.seg = path.segment_at(q.s + 0.5 * ds);
            t = prev.t + dt;
        }
        knots.push(Knot {
            t,
            s: p.s,
            v,
            u: 0.0,
            seg: path.segs.len().saturating_sub(1),
        });
    }
    Ok(knots)
}
