//! The sine and cosine of one angle, inlined: forward kinematics computes one pair per joint
//! and state, the planner's checker millions of them, and the C library's `sincos` behind
//! [`f64::sin_cos`] is a call of about 108 instructions there (callgrind). Inlined, the
//! LoCoBot's planning took 1.1 % fewer instructions, Sawyer's 1.4–1.8 %, for bit-identical
//! paths (`BENCHMARKS.md`). Hand-written rather than the `libm` crate's: that one reduces
//! arguments of any size (Payne–Hanek), which joint angles never need.
//!
//! The kernels are fdlibm's (`__kernel_sin`, `__kernel_cos` as in musl: under 1 ulp on
//! [−π/4, π/4]), after a Cody–Waite reduction by multiples of π/2 with fdlibm's two-part
//! constant, exact for |x| ≤ 2π. Beyond that, and for NaN or infinities, [`f64::sin_cos`].

use core::f64::consts::{FRAC_2_PI, PI};

/// π/2's first 33 bits: `k · PIO2_1` is exact for |k| ≤ 4.
const PIO2_1: f64 = 1.570_796_326_734_125_6;
/// π/2 − [`PIO2_1`].
const PIO2_1T: f64 = 6.077_100_506_506_192e-11;

const S1: f64 = -1.666_666_666_666_663_2e-1;
const S2: f64 = 8.333_333_333_322_49e-3;
const S3: f64 = -1.984_126_982_985_795e-4;
const S4: f64 = 2.755_731_370_707_006_8e-6;
const S5: f64 = -2.505_076_025_340_686_3e-8;
const S6: f64 = 1.589_690_995_211_55e-10;

const C1: f64 = 4.166_666_666_666_66e-2;
const C2: f64 = -1.388_888_888_887_411e-3;
const C3: f64 = 2.480_158_728_947_673e-5;
const C4: f64 = -2.755_731_435_139_066_3e-7;
const C5: f64 = 2.087_572_321_298_175e-9;
const C6: f64 = -1.135_964_755_778_819_5e-11;

/// sin x for |x| ≤ π/4.
#[inline(always)]
fn kernel_sin(x: f64) -> f64 {
    let z = x * x;
    let w = z * z;
    let r = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    x + z * x * (S1 + z * r)
}

/// cos x for |x| ≤ π/4.
#[inline(always)]
fn kernel_cos(x: f64) -> f64 {
    let z = x * x;
    let w = z * z;
    let r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    w + (((1.0 - w) - hz) + z * r)
}

/// `(sin x, cos x)` of `x` (rad), as [`f64::sin_cos`] within 2 ulp, inlined.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if x.is_nan() || x.abs() > 2.0 * PI {
        return x.sin_cos();
    }
    // The nearest multiple by truncation (`round` is a call without SSE4.1).
    let n = (x * FRAC_2_PI + 0.5f64.copysign(x)) as i64;
    let k = n as f64;
    let r = (x - k * PIO2_1) - k * PIO2_1T;
    let (s, c) = (kernel_sin(r), kernel_cos(r));
    match n & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place of the larger magnitude (0 when both are 0).
    fn ulps(a: f64, b: f64) -> f64 {
        let scale = a.abs().max(b.abs());
        if scale == 0.0 {
            return 0.0;
        }
        (a - b).abs() / (scale * f64::EPSILON)
    }

    #[test]
    fn agrees_with_the_c_library() {
        let mut worst: f64 = 0.0;
        let n = 200_000;
        for i in 0..=n {
            let x = -2.0 * PI + 4.0 * PI * f64::from(i) / f64::from(n);
            let (s, c) = sin_cos(x);
            let (es, ec) = x.sin_cos();
            // Near a zero of either, compare absolutely (1e-16 is below an ulp of 1).
            for (got, want) in [(s, es), (c, ec)] {
                let e = if want.abs() < 1e-3 {
                    (got - want).abs() / f64::EPSILON
                } else {
                    ulps(got, want)
                };
                worst = worst.max(e);
            }
        }
        assert!(worst <= 2.0, "worst error {worst} ulp");
    }

    #[test]
    fn edges_of_the_range_and_beyond() {
        for x in [
            0.0,
            -0.0,
            PI / 4.0,
            PI / 2.0,
            PI,
            2.0 * PI,
            -2.0 * PI,
            1e-300,
        ] {
            let (s, c) = sin_cos(x);
            let (es, ec) = x.sin_cos();
            assert!(
                (s - es).abs() <= 4.0 * f64::EPSILON && (c - ec).abs() <= 4.0 * f64::EPSILON,
                "{x}"
            );
        }
        // Beyond 2π and not finite: the C library's own.
        assert_eq!(sin_cos(100.0), 100.0f64.sin_cos());
        assert!(sin_cos(f64::NAN).0.is_nan() && sin_cos(f64::INFINITY).1.is_nan());
    }
}
