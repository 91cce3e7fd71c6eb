//! Integration steps in the phase plane: a step forward or backward at a path acceleration,
//! exact (constant `s̈`) on lines, of the time step on arcs, shortened where the tangent turns
//! fast; and bisection onto a limit curve.

use super::failed;
use super::phase::{Miss, Phase};
use crate::Result;

impl Phase<'_> {
    /// One forward step of `tau` (s; shorter if decelerating hard) at path acceleration `u`,
    /// ending at `s_max` at the latest.
    pub(super) fn step_fwd(
        &self,
        s: f64,
        x: f64,
        u: f64,
        s_max: f64,
        tau: f64,
    ) -> Result<(f64, f64)> {
        let v = x.max(0.0).sqrt();
        let tau = if u < 0.0 { tau.min(0.5 * v / -u) } else { tau };
        let s1 = (s + 0.5 * tau * (2.0 * v + u * tau)).min(s_max);
        if s1.is_nan() || s1 <= s {
            return Err(failed("the forward integration stalled"));
        }
        Ok((s1, (x + 2.0 * u * (s1 - s)).max(0.0)))
    }

    /// One backward step, the mirror of [`Self::step_fwd`], ending at `s_min` at the earliest.
    pub(super) fn step_bwd(
        &self,
        s: f64,
        x: f64,
        u: f64,
        s_min: f64,
        tau: f64,
    ) -> Result<(f64, f64)> {
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
    pub(super) fn step(
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
    pub(super) fn step_tau(
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
    pub(super) fn bisect(
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
    pub(super) fn inside(&self, k: usize, s: f64, toward: f64) -> f64 {
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
}
