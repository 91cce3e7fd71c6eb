//! Plane geometry shared by the firmware (`f32`), the simulated plants and the host (`f64`):
//! the one angle wrap and the one exact-arc step of a differential-drive base. The telemetry's
//! odometry (`ferrobot_protocol::Odometry`) is integrated with it; the protocol re-exports this
//! crate as `ferrobot_protocol::geometry`, and the host's geometry layer uses it directly.
#![no_std]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]
#![warn(missing_docs)]
// The arithmetic here is on `Real` (f32, f64) only: floating point neither overflows nor
// panics (it saturates to ±inf or gives NaN, which callers check), so the protocol's denial of
// integer arithmetic side effects does not apply; clippy cannot tell a generic float apart.

use core::ops::{Add, Div, Mul, Neg, Rem, Sub};

/// The floating-point types the geometry runs on (`f32` on the MCU, `f64` on the host), with
/// `libm`'s functions so that it stays `no_std`.
pub trait Real:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Rem<Output = Self>
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// 0.5.
    const HALF: Self;
    /// π.
    const PI: Self;
    /// 2π.
    const TAU: Self;
    /// A step whose heading changes by less than this (rad) is taken as straight: near the
    /// type's precision, where the arc's radius would divide by almost nothing.
    const STRAIGHT: Self;
    /// Sine.
    fn sin(self) -> Self;
    /// Cosine.
    fn cos(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
}

impl Real for f32 {
    const ZERO: f32 = 0.0;
    const ONE: f32 = 1.0;
    const HALF: f32 = 0.5;
    const PI: f32 = core::f32::consts::PI;
    const TAU: f32 = core::f32::consts::TAU;
    const STRAIGHT: f32 = 1e-6;
    fn sin(self) -> f32 {
        libm::sinf(self)
    }
    fn cos(self) -> f32 {
        libm::cosf(self)
    }
    fn abs(self) -> f32 {
        libm::fabsf(self)
    }
}

impl Real for f64 {
    const ZERO: f64 = 0.0;
    const ONE: f64 = 1.0;
    const HALF: f64 = 0.5;
    const PI: f64 = core::f64::consts::PI;
    const TAU: f64 = core::f64::consts::TAU;
    const STRAIGHT: f64 = 1e-9;
    fn sin(self) -> f64 {
        libm::sin(self)
    }
    fn cos(self) -> f64 {
        libm::cos(self)
    }
    fn abs(self) -> f64 {
        libm::fabs(self)
    }
}

/// Wrap an angle (rad) to (−π, π]: the one convention of the firmware, the plants and the host.
pub fn wrap<R: Real>(a: R) -> R {
    let mut a = a % R::TAU;
    if a > R::PI {
        a = a - R::TAU;
    } else if a <= -R::PI {
        a = a + R::TAU;
    }
    a
}

/// The pose `[x, y, θ]` (m, m, rad) after a differential-drive base at `pose` travels `ds`
/// (m, mean of the two wheels) while turning by `dth` (rad): on the circular arc those define,
/// a straight line when `|dth|` is below [`Real::STRAIGHT`]. Exact for constant wheel speeds
/// over the step; the heading is wrapped to (−π, π].
pub fn arc_step<R: Real>(pose: [R; 3], ds: R, dth: R) -> [R; 3] {
    let [x, y, th] = pose;
    let (nx, ny) = if dth.abs() < R::STRAIGHT {
        let mid = th + R::HALF * dth;
        (x + ds * mid.cos(), y + ds * mid.sin())
    } else {
        let r = ds / dth;
        let th1 = th + dth;
        (
            x + r * (th1.sin() - th.sin()),
            y - r * (th1.cos() - th.cos()),
        )
    };
    [nx, ny, wrap(th + dth)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_is_half_open_at_minus_pi_in_both_precisions() {
        assert_eq!(wrap(core::f64::consts::PI), core::f64::consts::PI);
        assert_eq!(wrap(-core::f64::consts::PI), core::f64::consts::PI);
        assert!((wrap(3.5f32) - (3.5 - core::f32::consts::TAU)).abs() < 1e-6);
        assert!((wrap(-3.5f32) - (-3.5 + core::f32::consts::TAU)).abs() < 1e-6);
    }

    #[test]
    fn a_quarter_circle_ends_where_geometry_says() {
        // Radius 1 m, a quarter turn left from the origin facing +x: ends at (1, 1) facing +y.
        let p = arc_step(
            [0.0f64, 0.0, 0.0],
            core::f64::consts::FRAC_PI_2,
            core::f64::consts::FRAC_PI_2,
        );
        assert!(
            (p[0] - 1.0).abs() < 1e-12 && (p[1] - 1.0).abs() < 1e-12,
            "{p:?}"
        );
        assert!((p[2] - core::f64::consts::FRAC_PI_2).abs() < 1e-12);
        // Many small steps make the same arc.
        let mut q = [0.0f64; 3];
        for _ in 0..1000 {
            q = arc_step(
                q,
                core::f64::consts::FRAC_PI_2 / 1000.0,
                core::f64::consts::FRAC_PI_2 / 1000.0,
            );
        }
        assert!(
            (q[0] - 1.0).abs() < 1e-9 && (q[1] - 1.0).abs() < 1e-9,
            "{q:?}"
        );
        // Straight, in f32.
        let s = arc_step([1.0f32, 2.0, 0.0], 0.5, 0.0);
        assert_eq!(s, [1.5, 2.0, 0.0]);
    }
}
