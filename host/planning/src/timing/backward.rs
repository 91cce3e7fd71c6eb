//! The backward integration: from a switching point (or the end, at rest) at the smallest
//! path acceleration until it meets the forward profile, spliced in where they cross.

use super::failed;
use super::phase::{Phase, Pt};
use crate::Result;

impl Phase<'_> {
    /// Integrates backward at the smallest acceleration from `start` until the curve meets
    /// the profile, and splices it in.
    pub(super) fn backward(&mut self, prof: &mut Vec<Pt>, start: Pt) -> Result<()> {
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
}

/// The profile's squared speed at `s` (linear between knots).
pub(super) fn interp(prof: &[Pt], s: f64) -> f64 {
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
pub(super) fn meet(prof: &[Pt], hi: Pt, lo: Pt, prev: &mut Option<(f64, f64)>) -> Option<Pt> {
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
pub(super) fn splice(prof: &mut Vec<Pt>, p: Pt, above: &[Pt]) {
    let keep = prof.partition_point(|q| q.s < p.s).max(1);
    prof.truncate(keep);
    prof.push(p);
    prof.extend(above.iter().rev().filter(|q| q.s > p.s));
}
