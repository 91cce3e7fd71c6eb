//! The blended path: the waypoints cleaned of repeats and of points on a straight line, lines
//! joined by circular arcs at the corners (within the allowed deviation, rad), cut into pieces
//! where the motion must stop, and parameterised by arc length `s` (rad).

use std::f64::consts::PI;

use super::{dot, norm, MIN_LEN, REVERSAL, SAME_WAYPOINT, STRAIGHT};
use crate::joint_space::dist;

/// Is `p` within [`STRAIGHT`] of the segment from `a` to `b`, strictly between its ends?
pub(super) fn on_chord(a: &[f64], b: &[f64], p: &[f64]) -> bool {
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
pub(super) fn clean_waypoints(path: &[Vec<f64>]) -> Vec<Vec<f64>> {
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

#[derive(Debug, Clone)]
pub(super) enum Shape {
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
pub(super) struct Segment {
    /// Arc length of its start along the whole path, rad.
    pub(super) start: f64,
    /// Length, rad.
    pub(super) len: f64,
    pub(super) shape: Shape,
}

impl Segment {
    pub(super) fn end(&self) -> f64 {
        self.start + self.len
    }

    pub(super) fn is_line(&self) -> bool {
        matches!(self.shape, Shape::Line { .. })
    }

    /// Position at path arc length `s` (clamped into the segment).
    pub(super) fn position(&self, s: f64, out: &mut [f64]) {
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
    pub(super) fn derivatives(&self, s: f64, t: &mut [f64], c: &mut [f64]) {
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
pub(super) struct Piece {
    pub(super) segs: std::ops::Range<usize>,
    pub(super) s0: f64,
    pub(super) s1: f64,
}

#[derive(Debug, Clone)]
pub(super) struct Path {
    pub(super) segs: Vec<Segment>,
    pub(super) pieces: Vec<Piece>,
    /// Sorted arc lengths where the integration must put a knot: the ends of the segments, the
    /// points of the arcs where a joint's tangent component vanishes, and those where the
    /// joint that bounds the speed changes.
    pub(super) breaks: Vec<f64>,
    /// Those points of the arcs, with their segment.
    pub(super) kinks: Vec<(f64, usize)>,
    pub(super) first: Vec<f64>,
    pub(super) last: Vec<f64>,
    pub(super) length: f64,
}

pub(super) enum Corner {
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
pub(super) fn corner(prev: &[f64], p: &[f64], next: &[f64], max_dev: f64) -> Corner {
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
    pub(super) fn build(pts: &[Vec<f64>], max_dev: f64, dof: usize) -> Self {
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

    pub(super) fn line(&mut self, a: &[f64], b: &[f64]) {
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

    pub(super) fn find_breaks(&mut self) {
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
    pub(super) fn add_speed_breaks(&mut self, vmax: &[f64]) {
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
    pub(super) fn segment_at(&self, s: f64) -> usize {
        self.segs
            .partition_point(|g| g.start <= s)
            .saturating_sub(1)
    }

    pub(super) fn position(&self, s: f64, out: &mut [f64]) {
        if self.segs.is_empty() || s.is_nan() || s <= 0.0 {
            out.copy_from_slice(&self.first);
        } else if s >= self.length {
            out.copy_from_slice(&self.last);
        } else {
            self.segs[self.segment_at(s)].position(s, out);
        }
    }
}
