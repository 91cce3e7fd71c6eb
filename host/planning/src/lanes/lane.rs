//! One arithmetic for one configuration (`f32`) and for [`WIDTH`] configurations at once
//! ([`Wide`]), so that the scalar path and the vector path give the same values.
//!
//! Every operation is one IEEE-754 operation per lane (no fused multiply-add, no
//! approximation the two types would do differently), and [`sin_cos`] is written once over
//! [`Lane`]: a lane of the vector path holds exactly what the scalar path computes for it.

use std::ops::{Add, Mul, Sub};

/// Configurations evaluated at once by the vector path.
pub const WIDTH: usize = 8;

/// A number of one configuration (`f32`) or of [`WIDTH`] configurations ([`Wide`]).
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

/// [`WIDTH`] configurations: eight `f32`s operated on lane by lane in plain Rust, which the
/// compiler turns into vector instructions: two SSE2 halves per operation on the x86-64
/// baseline, one AVX register where compiled for AVX2 (`checker/lanes_avx.rs`), NEON on
/// aarch64. One type for every instruction set rather than a SIMD crate's, whose choice of
/// instructions is fixed when it is compiled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wide(pub [f32; WIDTH]);

/// `f` lane by lane.
#[inline(always)]
fn each(a: Wide, f: impl Fn(f32) -> f32) -> Wide {
    let mut r = a.0;
    for v in &mut r {
        *v = f(*v);
    }
    Wide(r)
}

/// `f` lane by lane over two.
#[inline(always)]
fn pair(a: Wide, b: Wide, f: impl Fn(f32, f32) -> f32) -> Wide {
    let mut r = a.0;
    for (v, &o) in r.iter_mut().zip(&b.0) {
        *v = f(*v, o);
    }
    Wide(r)
}

impl Add for Wide {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        pair(self, o, |a, b| a + b)
    }
}

impl Sub for Wide {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        pair(self, o, |a, b| a - b)
    }
}

impl Mul for Wide {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        pair(self, o, |a, b| a * b)
    }
}

// Each operation is `f32`'s own lane by lane (its `Lane` impl's), except `floor`.
impl Lane for Wide {
    const LANES: usize = WIDTH;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Wide([v; WIDTH])
    }
    #[inline(always)]
    fn load(v: &[f32]) -> Self {
        Wide(v.try_into().expect("WIDTH values"))
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        out.copy_from_slice(&self.0);
    }
    // The x86-64 baseline (SSE2) has no instruction for `floor` (`f32::floor` is a call per
    // lane there): truncation instead, which vectorises (exact for |x| < 2³¹, the range
    // `Lane::floor` promises), less one where it rounded up. The same value as `f32::floor`;
    // +0 where that gives −0.
    #[inline(always)]
    fn floor(self) -> Self {
        each(self, |x| {
            let t = (x as i32) as f32;
            if t > x {
                t - 1.0
            } else {
                t
            }
        })
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        each(self, f32::sqrt)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        each(self, f32::abs)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        pair(self, o, Lane::max)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        pair(self, o, Lane::min)
    }
    #[inline(always)]
    fn least(self) -> f32 {
        self.0.iter().fold(self.0[0], |m, &x| Lane::min(x, m))
    }
    #[inline(always)]
    fn all_at_least(self, v: f32) -> bool {
        // Without a branch per lane: one comparison of eight.
        let mut all = true;
        for x in self.0 {
            all &= x >= v;
        }
        all
    }
    #[inline(always)]
    fn at_least_select(self, v: f32, then: Self, otherwise: Self) -> Self {
        let mut r = otherwise.0;
        for ((o, &x), &t) in r.iter_mut().zip(&self.0).zip(&then.0) {
            *o = if x >= v { t } else { *o };
        }
        Wide(r)
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
            let (sv, cv) = sin_cos(Wide::load(chunk));
            let (sv, cv) = (sv.0, cv.0);
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

    /// Every operation of [`Wide`] gives `f32`'s value in each lane, and its bits but for
    /// `floor`'s +0 where `f32::floor` gives −0, on values around the cases that differ
    /// between instructions (zeros of both signs, halves, exact integers, large and tiny
    /// values).
    #[test]
    fn wide_lanes_give_the_values_of_f32() {
        let values: Vec<f32> = [
            0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 1.5, -2.5, 3.0, 7.25, -1e-7, 1e-30, 123.456, -987.6,
            0.785, 1e6,
        ]
        .into_iter()
        .chain((0..48).map(|i| (i as f32 * 0.37).sin() * 40.0))
        .collect();
        type Op<L> = fn(L, L) -> L;
        fn ops<L: Lane>() -> Vec<(Op<L>, bool)> {
            vec![
                (|a, b| a + b, true),
                (|a, b| a - b, true),
                (|a, b| a * b, true),
                (|a, b| a.max(b), true),
                (|a, b| a.min(b), true),
                (|a, _| a.abs().sqrt(), true),
                (|a, _| (a * L::splat(1e-3)).floor(), false),
                (|a, b| a.at_least_select(0.5, a, b), true),
                (|a, _| sin_cos(a * L::splat(0.01)).0, true),
                (|a, _| sin_cos(a * L::splat(0.01)).1, true),
            ]
        }
        for x in values.chunks(WIDTH) {
            for y in values.chunks(WIDTH).rev() {
                let (a, b) = (Wide::load(x), Wide::load(y));
                for ((wide, bits), (one, _)) in ops::<Wide>().into_iter().zip(ops::<f32>()) {
                    let w = wide(a, b).0;
                    for k in 0..WIDTH {
                        let o = one(x[k], y[k]);
                        assert_eq!(w[k], o, "{x:?} {y:?}");
                        assert!(!bits || w[k].to_bits() == o.to_bits(), "{x:?} {y:?}");
                    }
                }
                let least = x.iter().fold(x[0], |m, &v| Lane::min(v, m));
                assert_eq!(a.least().to_bits(), least.to_bits());
                for v in [0.0, 0.5, -1.0] {
                    assert_eq!(a.all_at_least(v), x.iter().all(|&e| e >= v));
                }
            }
        }
    }
}
