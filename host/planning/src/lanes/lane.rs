//! One arithmetic for one configuration (`f32`) and for [`WIDTH`] configurations at once
//! (`wide::f32x8`), so that the scalar path and the vector path give the same bits.
//!
//! Every operation is one IEEE-754 operation per lane (no fused multiply-add, no
//! approximation the two types would do differently), and [`sin_cos`] is written once over
//! [`Lane`]: a lane of the vector path holds exactly what the scalar path computes for it.

use std::ops::{Add, Mul, Sub};

use wide::f32x8;

/// Configurations evaluated at once by the vector path.
pub const WIDTH: usize = 8;

/// A number of one configuration (`f32`) or of [`WIDTH`] configurations (`f32x8`).
pub trait Lane:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Send + Sync
{
    /// Configurations per value: 1 or [`WIDTH`].
    const LANES: usize;
    /// `v` in every lane.
    fn splat(v: f32) -> Self;
    /// The lanes from `v` (`v.len()` is [`Lane::LANES`]).
    fn load(v: &[f32]) -> Self;
    /// The lanes into `out` (`out.len()` is [`Lane::LANES`]).
    fn store(self, out: &mut [f32]);
    /// Largest integer not above, per lane (|x| < 2²³).
    fn floor(self) -> Self;
    /// Square root, per lane.
    fn sqrt(self) -> Self;
    /// Absolute value, per lane.
    fn abs(self) -> Self;
    /// `self` where it is greater than `o`, else `o` (finite values), per lane.
    fn max(self, o: Self) -> Self;
    /// `self` where it is less than `o`, else `o` (finite values), per lane.
    fn min(self, o: Self) -> Self;
    /// The smallest lane.
    fn least(self) -> f32;
    /// Whether every lane is at least `v` (finite values).
    fn all_at_least(self, v: f32) -> bool;
    /// `then` in the lanes where `self` is at least `v`, `otherwise` in the others.
    fn at_least_select(self, v: f32, then: Self, otherwise: Self) -> Self;
}

impl Lane for f32 {
    const LANES: usize = 1;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn load(v: &[f32]) -> Self {
        v[0]
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        out[0] = self;
    }
    #[inline(always)]
    fn floor(self) -> Self {
        f32::floor(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    // As the vector instructions do (`maxps`: `a > b ? a : b`), not as `f32::max`, whose
    // choice between +0 and -0 is unspecified.
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        if self > o {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        if self < o {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    fn least(self) -> f32 {
        self
    }
    #[inline(always)]
    fn all_at_least(self, v: f32) -> bool {
        self >= v
    }
    #[inline(always)]
    fn at_least_select(self, v: f32, then: Self, otherwise: Self) -> Self {
        if self >= v {
            then
        } else {
            otherwise
        }
    }
}

impl Lane for f32x8 {
    const LANES: usize = WIDTH;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        f32x8::splat(v)
    }
    #[inline(always)]
    fn load(v: &[f32]) -> Self {
        let mut a = [0.0; WIDTH];
        a.copy_from_slice(v);
        f32x8::new(a)
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        out.copy_from_slice(&self.to_array());
    }
    // The x86-64 baseline (SSE2) has no instruction for `floor`, and `wide` calls `floorf`
    // per lane there: truncation instead (exact for |x| < 2³¹, the range `Lane::floor`
    // promises), less one where it rounded up.
    #[inline(always)]
    fn floor(self) -> Self {
        let t = self.fast_trunc_int().round_float();
        t - (t.simd_gt(self) & f32x8::ONE)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32x8::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32x8::abs(self)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        f32x8::max(self, o)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        f32x8::min(self, o)
    }
    #[inline(always)]
    fn least(self) -> f32 {
        let a = self.to_array();
        a.iter().fold(a[0], |m, &x| Lane::min(x, m))
    }
    // `x − v` is exact in sign (never −0 for `x ≥ v`, never +0 for `x < v`): no lane's sign
    // bit is set exactly when every lane is at least `v`.
    #[inline(always)]
    fn all_at_least(self, v: f32) -> bool {
        (self - f32x8::splat(v)).to_bitmask() == 0
    }
    #[inline(always)]
    fn at_least_select(self, v: f32, then: Self, otherwise: Self) -> Self {
        self.simd_ge(f32x8::splat(v)).select(then, otherwise)
    }
}

/// Each of `v` in every lane. A loop rather than `map`, which would stay a call where the
/// AVX path needs every operation inlined (`checker/lanes_avx.rs`).
#[inline(always)]
pub fn splat_all<L: Lane, const N: usize>(v: &[f32; N]) -> [L; N] {
    let mut out = [L::splat(0.0); N];
    for (o, &x) in out.iter_mut().zip(v) {
        *o = L::splat(x);
    }
    out
}

/// π/2 in three parts (Cody and Waite): the first two with few enough bits that `n` times
/// them is exact for `|n| < 2¹²`.
const PIO2: [f32; 3] = [1.570_312_5, 4.837_513e-4, 7.549_79e-8];

/// Sine and cosine of `x` (rad, `|x|` ≤ 1000), per lane, within 2·10⁻⁷ of the exact values
/// for `|x|` ≤ 4π: Cephes' `sinf` and `cosf` polynomials on `[-π/4, π/4]` after a reduction by
/// π/2, the quadrant applied by arithmetic on 0 and 1 (exact), not by branches.
#[inline(always)]
pub fn sin_cos<L: Lane>(x: L) -> (L, L) {
    let one = L::splat(1.0);
    let two = L::splat(2.0);
    let half = L::splat(0.5);
    let n = (x * L::splat(std::f32::consts::FRAC_2_PI) + half).floor();
    let r = ((x - n * L::splat(PIO2[0])) - n * L::splat(PIO2[1])) - n * L::splat(PIO2[2]);
    let z = r * r;
    let s = ((L::splat(-1.951_529_6e-4) * z + L::splat(8.332_161e-3)) * z
        + L::splat(-1.666_665_5e-1))
        * z
        * r
        + r;
    let c = ((L::splat(2.443_315_7e-5) * z + L::splat(-1.388_731_6e-3)) * z
        + L::splat(4.166_664_6e-2))
        * z
        * z
        - half * z
        + one;
    // The quadrant q = n mod 4, from its two bits: odd swaps sine and cosine, the high bit
    // negates the sine, and high xor odd the cosine.
    let q = n - L::splat(4.0) * (n * L::splat(0.25)).floor();
    let high = (q * half).floor();
    let odd = q - two * high;
    let even = one - odd;
    let sin = s * even + c * odd;
    let cos = c * even + s * odd;
    let flip = high + odd;
    let flip = flip - two * (flip * half).floor();
    (sin * (one - two * high), cos * (one - two * flip))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Within 2·10⁻⁷ of `f64`'s sine and cosine over ±4π, and the vector path's lanes
    /// bit-identical to the scalar path's.
    #[test]
    fn sin_cos_is_accurate_and_the_same_in_both_paths() {
        let mut worst = 0.0f64;
        let n = 200_000;
        let xs: Vec<f32> = (0..n)
            .map(|i| (-4.0 + 8.0 * i as f64 / n as f64) as f32 * std::f32::consts::PI)
            .collect();
        for chunk in xs.chunks_exact(WIDTH) {
            let (sv, cv) = sin_cos(f32x8::load(chunk));
            let (sv, cv) = (sv.to_array(), cv.to_array());
            for (k, &x) in chunk.iter().enumerate() {
                let (s, c) = sin_cos(x);
                assert_eq!(
                    (s.to_bits(), c.to_bits()),
                    (sv[k].to_bits(), cv[k].to_bits())
                );
                let e = (f64::from(s) - f64::from(x).sin())
                    .abs()
                    .max((f64::from(c) - f64::from(x).cos()).abs());
                worst = worst.max(e);
            }
        }
        assert!(worst < 2e-7, "{worst}");
    }
}
