//! The forward integration: from the profile's last point at the largest path acceleration,
//! following the velocity limit curve where it can, until the end of the piece or a limit
//! curve.

use super::phase::{tol, At, Follow, Pass, Phase, Pt, Stop};
use super::{failed, FOLLOW_TRIES, REL};
use crate::Result;

impl Phase<'_> {
    /// Integrates forward from the profile's last point at the largest acceleration,
    /// following the velocity limit curve where possible, until the end or a limit curve.
    pub(super) fn forward(&mut self, prof: &mut Vec<Pt>) -> Result<Stop> {
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
    pub(super) fn at(&mut self, s: f64, x: f64) -> Option<At> {
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
    pub(super) fn along_curve(&mut self, prof: &mut Vec<Pt>, at: &At) -> Result<Option<Pass>> {
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
    pub(super) fn under_curves(&mut self, prof: &mut Vec<Pt>, at: &At) -> Result<Pass> {
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
    pub(super) fn goes_over(&mut self, at: &At, u: f64, s1: f64, x1: f64) -> Option<f64> {
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
    pub(super) fn follow_step(&mut self, at: &At) -> Result<Follow> {
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
    pub(super) fn raised_knot(&mut self, at: &At, s1: f64, xv1: f64, lo1: f64) -> Option<Pt> {
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
}
