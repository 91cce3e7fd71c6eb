//! The timed profile: its knots with time (s), arc length (rad), path speed (rad/s) and the
//! constant path acceleration to the next knot (rad/s²).

use super::failed;
use super::path::Path;
use super::phase::Pt;
use crate::Result;

/// A knot of the timed profile; `u` and `seg` are those of the interval to the next knot.
#[derive(Debug, Clone, Copy)]
pub(super) struct Knot {
    /// Time, s.
    pub(super) t: f64,
    /// Arc length, rad.
    pub(super) s: f64,
    /// Path speed, rad/s.
    pub(super) v: f64,
    /// Path acceleration to the next knot, rad/s².
    pub(super) u: f64,
    /// Segment of the interval to the next knot.
    pub(super) seg: usize,
}

pub(super) fn timed_knots(path: &Path, profile: &[Pt]) -> Result<Vec<Knot>> {
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
