//! Switching points: where the profile can touch the lower limit curve without crossing it
//! (curvature discontinuities and kinks of the acceleration limit curve, its tangent points,
//! where the velocity limit curve falls too fast, where the lower curve changes), found on
//! the arcs by sampling and bisection.

use super::path::Shape;
use super::phase::{tol, Phase, Switch};
use super::{MAX_SCAN, MAX_TURN, REL, SCAN_TURN};
use crate::Result;

impl Phase<'_> {
    /// Switching points on the acceleration limit curve at curvature discontinuities and
    /// kinks.
    pub(super) fn accel_switches(&mut self) -> Vec<Switch> {
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
    pub(super) fn switch_at(&mut self, kb: usize, ka: usize, s: f64) -> Option<Switch> {
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
    pub(super) fn side_step(&self, k: usize, s: f64) -> f64 {
        let gap = (s - self.prev_break(s)).min(self.next_break(s) - s);
        let gap = if gap > 0.0 {
            gap
        } else {
            self.path.segs[k].len
        };
        self.probe(k).min(0.25 * gap)
    }

    /// Number of samples of the search for switching points over `len` (rad) of arc `k`.
    pub(super) fn scan_count(&self, k: usize, len: f64) -> usize {
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
    pub(super) fn max_ds(&self, k: usize) -> f64 {
        match &self.path.segs[k].shape {
            Shape::Arc { r, .. } => MAX_TURN * r,
            Shape::Line { .. } => f64::INFINITY,
        }
    }

    /// A small arc-length step for finite differences on segment `k`, rad.
    pub(super) fn probe(&self, k: usize) -> f64 {
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
    pub(super) fn backward_only(&mut self, k: usize, s: f64) -> bool {
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
    pub(super) fn scan_switches(
        &mut self,
        from: f64,
        until: f64,
        first: bool,
    ) -> Result<Vec<Switch>> {
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
    pub(super) fn switch_on_curve(&mut self, k: usize, s: f64) -> Option<Switch> {
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
}
