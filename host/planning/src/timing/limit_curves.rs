//! The limit curves at the point loaded: the velocity limit curve (the largest path speed
//! the joint velocity limits allow) and the acceleration limit curve (the largest speed at
//! which some path acceleration is still possible), with the range of path accelerations
//! below them (rad/s²).

use super::phase::Phase;
use super::{REL, TINY_TANGENT};

impl Phase<'_> {
    /// Is squared speed `x` above a limit curve at the loaded point?
    pub(super) fn above(&self, x: f64) -> bool {
        x > self.vel_curve().0 || self.accel_range(x).is_none()
    }

    /// Range of path accelerations (rad/s²) at squared speed `x` at the loaded point; `None`
    /// above the acceleration limit curve (a range empty by rounding only is its midpoint).
    pub(super) fn accel_range(&self, x: f64) -> Option<(f64, f64)> {
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
    pub(super) fn vel_curve(&self) -> (f64, f64) {
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
    pub(super) fn acc_curve(&self) -> f64 {
        self.acc_curve_slope().0
    }

    /// The acceleration limit curve at the loaded point (rad²/s²) and its slope `dx/ds`
    /// (rad/s²) on an arc. Each pair of joints `(i, j)` bounds it by
    /// `(a_i |t_j| + a_j |t_i|) / |c_i t_j − c_j t_i|`, whose denominator is constant along a
    /// circle (`t' = c`, `c' = −t / r²`).
    pub(super) fn acc_curve_slope(&self) -> (f64, f64) {
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

    pub(super) fn limit_at(&mut self, k: usize, s: f64) -> (f64, f64) {
        self.load(k, s);
        (self.vel_curve().0, self.acc_curve())
    }
}
