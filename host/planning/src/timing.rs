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
//!    the switching point, and so on; the end is reached backward from rest. Switching points are
//!    the curvature discontinuities (ends of the arcs) and the points where a joint's tangent
//!    vanishes on an arc (where the acceleration limit curve has a kink), when the profile can
//!    pass through them, and the tangent points of the velocity limit curve, where it becomes
//!    followable again. Integration uses steps of [`TimingOptions::time_step`] on the arcs and
//!    is exact (constant `s̈`) on the lines.
//! 3. **Sampling.** Between the knots of the profile `s̈` is constant; a sample at time `t` is
//!    `q = c(s)`, `q̇ = c'(s) ṡ`, `q̈ = c'(s) s̈ + c''(s) ṡ²`.
//!
//! Internally the profile is kept as `x = ṡ²`, in which a constant `s̈` is a straight line
//! (`dx/ds = 2 s̈`), so the meeting point of a backward and a forward profile is exact.
//!
//! Units: joint positions in rad (or m for a prismatic joint; everything below says rad),
//! velocities rad/s, accelerations rad/s², times s.

// Negated comparisons are meant: they are true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

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
/// Sampling step (rad of path) of the search for velocity switching points on arcs.
const SCAN_STEP: f64 = 1e-3;
/// Most samples of one arc in that search.
const MAX_SCAN: usize = 100_000;

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
/// Consecutive waypoints within [`SAME_WAYPOINT`] of each other are taken as one (the first
/// and last waypoints are kept exactly); a path of one point gives a trajectory of zero
/// duration. Waypoints on the straight line between their neighbours are passed without
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
    let path = Path::build(&points, opts.max_deviation, dof);
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
        let (mut tan, mut curv) = (vec![0.0; n], vec![0.0; n]);
        seg.derivatives(s, &mut tan, &mut curv);
        seg.position(s, &mut point.position);
        for i in 0..n {
            point.velocity[i] = tan[i] * v;
            point.acceleration[i] = tan[i] * a.u + curv[i] * v * v;
        }
        if t >= self.duration {
            point.position.copy_from_slice(&self.path.last);
            point.velocity.iter_mut().for_each(|q| *q = 0.0);
        }
        point
    }

    /// Samples every `dt` (s) from 0, and the end. A `dt` that is not a positive number gives
    /// the two ends only; at most 10 000 001 samples are made (a smaller `dt` is widened).
    pub fn samples(&self, dt: f64) -> Vec<TrajectoryPoint> {
        const MOST: f64 = 1e7;
        let mut out = Vec::new();
        if dt > 0.0 && dt.is_finite() {
            let dt = dt.max(self.duration / MOST);
            let mut k = 0u64;
            loop {
                let t = k as f64 * dt;
                if t >= self.duration {
                    break;
                }
                out.push(self.sample(t));
                k += 1;
            }
        } else {
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
    /// Sorted arc lengths where the integration must put a knot: the ends of the segments and
    /// the points of the arcs where a joint's tangent component vanishes.
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
    if !(angle > 0.0) {
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

    /// Index of the segment at arc length `s`: the one starting there when `s` is a boundary.
    fn segment_at(&self, s: f64) -> usize {
        self.segs
            .partition_point(|g| g.start <= s)
            .saturating_sub(1)
    }

    fn position(&self, s: f64, out: &mut [f64]) {
        if self.segs.is_empty() || !(s > 0.0) {
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
    budget: &'a mut usize,
}

fn dbg_on() -> bool {
    std::env::var_os("TIMING_DEBUG").is_some()
}

fn tol(a: f64) -> f64 {
    REL * (1.0 + a.abs())
}

impl Phase<'_> {
    fn spend(&mut self) -> Result<()> {
        if *self.budget == 0 {
            return Err(invalid(
                "path",
                format!("timing it would take more than {MAX_STEPS} integration steps (limits too slow for the time step?)"),
            ));
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
        let path = self.path;
        path.segs[k].derivatives(s, &mut self.t, &mut self.c);
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
        let mut best = f64::INFINITY;
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
                    best = best.min((ai * tj.abs() + aj * ti.abs()) / den);
                }
            }
        }
        best
    }

    fn limit_at(&mut self, k: usize, s: f64) -> (f64, f64) {
        self.load(k, s);
        (self.vel_curve().0, self.acc_curve())
    }

    /// One forward step of `dt` (shorter if decelerating hard) at path acceleration `u`,
    /// ending at `s_max` at the latest.
    fn step_fwd(&self, s: f64, x: f64, u: f64, s_max: f64) -> Result<(f64, f64)> {
        let v = x.max(0.0).sqrt();
        let tau = if u < 0.0 {
            self.dt.min(0.5 * v / -u)
        } else {
            self.dt
        };
        let s1 = (s + 0.5 * tau * (2.0 * v + u * tau)).min(s_max);
        if !(s1 > s) {
            return Err(failed("the forward integration stalled"));
        }
        Ok((s1, (x + 2.0 * u * (s1 - s)).max(0.0)))
    }

    /// One backward step, the mirror of [`Self::step_fwd`], ending at `s_min` at the earliest.
    fn step_bwd(&self, s: f64, x: f64, u: f64, s_min: f64) -> Result<(f64, f64)> {
        let v = x.max(0.0).sqrt();
        let tau = if u > 0.0 {
            self.dt.min(0.5 * v / u)
        } else {
            self.dt
        };
        let s0 = (s - 0.5 * tau * (2.0 * v - u * tau)).max(s_min);
        if !(s0 < s) {
            return Err(failed("the backward integration stalled"));
        }
        Ok((s0, (x - 2.0 * u * (s - s0)).max(0.0)))
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
        let end = self.piece.s1;
        loop {
            self.spend()?;
            let Some(&Pt { s, x }) = prof.last() else {
                return Err(failed("empty profile"));
            };
            if s >= end {
                return Ok(Stop::End);
            }
            let k = self.seg_fwd(s);
            let line = self.path.segs[k].is_line();
            let nb = self.next_break(s);
            let se = self.inside(k, s, nb);
            self.load(k, s);
            let (xv, _) = self.vel_curve();
            self.load(k, se);
            let (_, slope) = self.vel_curve();
            if x > self.acc_curve() * (1.0 + REL) {
                return Ok(Stop::AccelLimit);
            }
            let Some((lo, hi)) = self.accel_range(x) else {
                return Ok(Stop::AccelLimit);
            };
            if x >= xv * (1.0 - REL) {
                // On the velocity limit curve: follow it while the limits allow.
                let want = 0.5 * slope;
                if want < lo - tol(lo) {
                    return Ok(Stop::VelocityLimit);
                }
                if want <= hi {
                    if line {
                        prof.push(Pt { s: nb, x: xv });
                        continue;
                    }
                    let s1 = (s + xv.sqrt() * self.dt).min(nb);
                    let (xv1, xa1) = self.limit_at(k, s1);
                    if xv1 > xa1 {
                        // The acceleration limit curve comes under the velocity one.
                        let (sc, _) = self.bisect(s, s1, |me, q| {
                            let (v, a) = me.limit_at(k, q);
                            v > a
                        });
                        let (xvc, _) = self.limit_at(k, sc);
                        prof.push(Pt { s: sc, x: xvc });
                        return Ok(Stop::AccelLimit);
                    }
                    let u = (xv1 - x) / (2.0 * (s1 - s));
                    self.load(k, s1);
                    match self.accel_range(xv1) {
                        Some((lo1, _)) if u < lo1 - tol(lo1) => return Ok(Stop::VelocityLimit),
                        Some((_, hi1)) if u <= hi1 + tol(hi1) => {
                            prof.push(Pt { s: s1, x: xv1 });
                            continue;
                        }
                        // Rising faster than the profile may: accelerate below it instead.
                        _ => {}
                    }
                }
            }
            if line {
                // No curvature: the acceleration range is the same all along the line.
                let x_end = x + 2.0 * hi * (nb - s);
                if x_end > xv && hi > 0.0 {
                    let sh = (s + (xv - x) / (2.0 * hi)).clamp(s, nb);
                    prof.push(Pt { s: sh, x: xv });
                } else {
                    prof.push(Pt {
                        s: nb,
                        x: x_end.max(0.0),
                    });
                }
                continue;
            }
            let mut u = hi;
            let (mut s1, mut x1) = self.step_fwd(s, x, u, nb)?;
            self.load(k, s1);
            if let Some((_, hi1)) = self.accel_range(x1) {
                if hi1 < u {
                    u = hi1.max(lo);
                    (s1, x1) = self.step_fwd(s, x, u, nb)?;
                }
            }
            let (xv1, xa1) = self.limit_at(k, s1);
            if x1 > xv1.min(xa1) {
                let (sc, _) = self.bisect(s, s1, |me, q| {
                    let (v, a) = me.limit_at(k, q);
                    x + 2.0 * u * (q - s) > v.min(a)
                });
                let (xvc, xac) = self.limit_at(k, sc);
                if xvc <= xac {
                    // On the velocity limit curve: whether it can be followed is seen next.
                    prof.push(Pt { s: sc, x: xvc });
                    continue;
                }
                prof.push(Pt {
                    s: sc,
                    x: x + 2.0 * u * (sc - s),
                });
                return Ok(Stop::AccelLimit);
            }
            prof.push(Pt { s: s1, x: x1 });
        }
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
                if dbg_on() {
                    eprintln!("backward from {start:?} above the curve at {cur:?}");
                }
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
                let mut u = lo;
                let (mut s0, mut x0) = self.step_bwd(cur.s, cur.x, u, pb)?;
                self.load(k, s0);
                if let Some((lo0, _)) = self.accel_range(x0) {
                    if lo0 > u {
                        u = lo0.min(hi);
                        (s0, x0) = self.step_bwd(cur.s, cur.x, u, pb)?;
                    }
                }
                Pt { s: s0, x: x0 }
            };
            if let Some(p) = meet(prof, cur, next, &mut prev) {
                splice(prof, p, &above);
                return Ok(());
            }
            if next.s > last.s {
                let (xv, xa) = self.limit_at(k, next.s);
                if next.x > xv.min(xa) * (1.0 + 1e-6) + 1e-12 {
                    if dbg_on() {
                        eprintln!("backward from {start:?} crossed at {next:?} xv {xv} xa {xa}, forward ends {last:?}");
                    }
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
        if dbg_on() {
            eprintln!("switch_at {kb} {ka} {s}: xa {xa_b} {xa_a} xv {xv_b} {xv_a} ok {before_ok} {after_ok}");
        }
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

    /// Tangent switching points of the acceleration limit curve on the piece's arcs, between
    /// their kinks: where the curve's slope, from below the profile's on the curve, rises
    /// above it (going backward from there and forward from there both stay under the curve).
    fn accel_tangents(&mut self) -> Result<Vec<Switch>> {
        let path = self.path;
        let mut out = Vec::new();
        for k in self.piece.segs.clone() {
            let seg = &path.segs[k];
            if seg.is_line() {
                continue;
            }
            let first = path.breaks.partition_point(|&b| b <= seg.start);
            let mut edges = vec![seg.start];
            edges.extend(
                path.breaks[first..]
                    .iter()
                    .take_while(|&&b| b < seg.end())
                    .copied(),
            );
            edges.push(seg.end());
            for w in edges.windows(2) {
                let (a, b) = (w[0], w[1]);
                let d = self.probe(k).min(0.25 * (b - a));
                let n = (((b - a) / SCAN_STEP).ceil() as usize).clamp(8, MAX_SCAN);
                let mut prev: Option<(f64, f64)> = None;
                for j in 0..=n {
                    self.spend()?;
                    let q = a + d + (b - a - 2.0 * d) * j as f64 / n as f64;
                    let gap = self.tangent_gap(k, q, d);
                    if dbg_on()
                        && std::env::var("DBG_SEG")
                            .ok()
                            .and_then(|v| v.parse::<usize>().ok())
                            == Some(k)
                    {
                        let (xv, xa) = self.limit_at(k, q);
                        self.load(k, q);
                        eprintln!(
                            "  scan s={q:.9} xa={xa:.9} xv={xv:.5} gap={gap:?} range={:?} t={:?}",
                            self.accel_range(xa * (1.0 - REL)),
                            self.t
                        );
                    }
                    if let (Some((pq, pg)), Some(g)) = (prev, gap) {
                        if pg < 0.0 && g >= 0.0 {
                            let (_, at) = self.bisect(pq, q, |me, z| {
                                me.tangent_gap(k, z, d).is_some_and(|g| g >= 0.0)
                            });
                            let (xv, xa) = self.limit_at(k, at);
                            if xa <= xv {
                                out.push(Switch {
                                    s: at,
                                    x: xa * (1.0 - REL),
                                });
                            }
                        }
                    }
                    prev = gap.map(|g| (q, g));
                }
            }
        }
        Ok(out)
    }

    /// Slope of the acceleration limit curve at `s` on segment `k` minus the profile's slope
    /// `2 s̈` on the curve there, rad/s²; `None` where the curve is above the velocity limit
    /// curve. `room` bounds the finite-difference step.
    fn tangent_gap(&mut self, k: usize, s: f64, room: f64) -> Option<f64> {
        let (xv, xa) = self.limit_at(k, s);
        if !(xa <= xv) {
            return None;
        }
        let (lo, hi) = self.accel_range(xa * (1.0 - REL))?;
        let h = self.probe(k).min(room);
        let (_, xm) = self.limit_at(k, s - h);
        let (_, xp) = self.limit_at(k, s + h);
        Some((xp - xm) / (2.0 * h) - (lo + hi))
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

    /// Is the velocity limit curve at `s` on segment `k` binding and falling faster than the
    /// profile may decelerate?
    fn unfollowable(&mut self, k: usize, s: f64) -> bool {
        self.load(k, s);
        let (xv, slope) = self.vel_curve();
        if xv > self.acc_curve() {
            return false;
        }
        self.accel_range(xv)
            .is_some_and(|(lo, _)| 0.5 * slope < lo - tol(lo))
    }

    /// Velocity switching points in `[from, until]`, where the velocity limit curve becomes
    /// followable again; the first one only when `first`.
    fn velocity_switches(&mut self, from: f64, until: f64, first: bool) -> Result<Vec<Switch>> {
        let mut out = Vec::new();
        let path = self.path;
        let mut prev: Option<(f64, bool, usize)> = None;
        for k in self.seg_fwd(from)..self.piece.segs.end {
            let seg = &path.segs[k];
            if seg.start > until {
                break;
            }
            let a = from.max(seg.start);
            let b = until.min(seg.end());
            let n = if seg.is_line() {
                0
            } else {
                (((b - a) / SCAN_STEP).ceil() as usize).clamp(8, MAX_SCAN)
            };
            for j in 0..=n {
                self.spend()?;
                let s = if j == n {
                    b
                } else {
                    a + (b - a) * j as f64 / n as f64
                };
                // Lines: the curve is flat, always followable.
                let bad = !seg.is_line() && self.unfollowable(k, s);
                if let Some((ps, true, pk)) = prev {
                    if !bad {
                        let at = if pk == k {
                            // The followable end of the bracket.
                            self.bisect(ps, s, |me, q| !me.unfollowable(k, q)).1
                        } else {
                            seg.start
                        };
                        if let Some(sw) = self.velocity_switch(k, at) {
                            out.push(sw);
                            if first {
                                return Ok(out);
                            }
                        }
                    }
                }
                prev = Some((s, bad, k));
            }
        }
        Ok(out)
    }

    /// The velocity switching point at `s` on segment `k`, unless the acceleration limit
    /// curve is below the velocity one there.
    fn velocity_switch(&mut self, k: usize, s: f64) -> Option<Switch> {
        let h = self.probe(k);
        let seg = &self.path.segs[k];
        let (xv, xa) = self.limit_at(k, s);
        let (_, xa_m) = self.limit_at(k, (s - h).max(seg.start));
        let (_, xa_p) = self.limit_at(k, (s + h).min(seg.end()));
        (xv <= xa.min(xa_m).min(xa_p)).then_some(Switch { s, x: xv })
    }

    /// The profile of the piece, from rest at its start to rest at its end.
    fn run(&mut self) -> Result<Vec<Pt>> {
        let (s0, s1) = (self.piece.s0, self.piece.s1);
        let mut switches = self.accel_switches();
        switches.extend(self.accel_tangents()?);
        switches.extend(self.velocity_switches(s0, s1, false)?);
        switches.sort_by(|a, b| a.s.total_cmp(&b.s));
        if dbg_on() {
            eprintln!(
                "segments: {:?}",
                self.path.segs[self.piece.segs.clone()]
                    .iter()
                    .map(|g| (g.start, g.end(), g.is_line()))
                    .collect::<Vec<_>>()
            );
            eprintln!("switches: {switches:?}");
        }
        let mut prof = vec![Pt { s: s0, x: 0.0 }];
        let mut last_switch = f64::NEG_INFINITY;
        let most_rounds = 2 * switches.len() + 1000;
        for _ in 0..most_rounds {
            let stop = self.forward(&mut prof)?;
            if dbg_on() {
                let l = prof.last().unwrap();
                eprintln!(
                    "forward stop {stop:?} at s={} x={} (piece {}..{})",
                    l.s, l.x, s0, s1
                );
            }
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
                let found = self.velocity_switches(s_last, until, true)?;
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
            if dbg_on() {
                eprintln!("switch {sw:?}");
            }
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
