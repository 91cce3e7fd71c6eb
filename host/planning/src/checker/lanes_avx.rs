//! The vector path on AVX2, chosen at run time: [`WIDTH`] configurations in one 256-bit
//! register where the x86-64 baseline (SSE2, which `wide` compiles for unless the whole build
//! targets a newer CPU) takes two 128-bit halves per operation.
//!
//! [`Avx`] is eight `f32`s operated on lane by lane in plain Rust, the same IEEE-754 operation
//! per lane as [`f32`] and [`Wide`](crate::lanes::Wide) (no fused multiply-add: Rust never
//! contracts `a * b + c`), so the answers are the same bits. The clearances are measured in
//! [`measure`], a function compiled for AVX2, into which the measurement is inlined
//! (`#[inline(always)]` down to these operations): there the compiler turns each operation
//! on eight lanes into one AVX instruction. Intrinsics would not do: an intrinsic called from
//! an operator's function, which cannot carry the target feature, stays a call.

use std::ops::{Add, Mul, Sub};

use super::lanes::{Candidates, LaneChecks, LaneScratch};
use super::lanes_edge::{Buffers, Lanes};
use super::Checker;
use crate::lanes::{Lane, WIDTH};

/// [`WIDTH`] configurations, one AVX register where compiled for it.
#[derive(Debug, Clone, Copy)]
struct Avx([f32; WIDTH]);

/// The AVX path's buffers ([`Buffers`]): placement, clearances out, joint values in.
#[derive(Debug, Default)]
pub(super) struct AvxBuffers(Option<(LaneScratch<Avx>, Vec<Avx>, Vec<Avx>)>);

/// Whether the edge from `a` to `b` is free ([`Checker::motion_free_in_lanes`]) on the AVX2
/// path; `None` on a CPU without AVX2.
pub(super) fn edge(checker: &Checker, checks: &LaneChecks, a: &[f64], b: &[f64]) -> Option<bool> {
    if !std::arch::is_x86_feature_detected!("avx2") {
        return None;
    }
    Some(checker.edge_in_lanes::<Avx>(checks, a, b))
}

impl Lanes for Avx {
    fn buffers(b: &mut Buffers) -> &mut (LaneScratch<Self>, Vec<Self>, Vec<Self>) {
        b.avx.0.get_or_insert_with(Default::default)
    }

    #[allow(clippy::too_many_arguments)]
    fn measure(
        checks: &LaneChecks,
        q: &[Self],
        candidates: &Candidates,
        limits: (f32, &[f32]),
        scratch: &mut LaneScratch<Self>,
        out: &mut [Self],
        nearest: Option<&mut [f32]>,
        contact: f32,
    ) -> bool {
        // SAFETY: `measure` only needs the CPU to have AVX2. A walk on `Avx` lanes, the only
        // caller of this method, starts only in `edge`, after
        // `is_x86_feature_detected!("avx2")` (the type is private to this module).
        unsafe {
            measure(
                checks, q, candidates, limits, scratch, out, nearest, contact,
            )
        }
    }
}

/// [`LaneChecks::measure`] compiled for AVX2.
#[target_feature(enable = "avx,avx2")]
#[allow(clippy::too_many_arguments)]
fn measure(
    checks: &LaneChecks,
    q: &[Avx],
    candidates: &Candidates,
    limits: (f32, &[f32]),
    scratch: &mut LaneScratch<Avx>,
    out: &mut [Avx],
    nearest: Option<&mut [f32]>,
    contact: f32,
) -> bool {
    checks.measure(q, candidates, limits, scratch, out, nearest, contact)
}

/// `f` lane by lane.
#[inline(always)]
fn each(a: Avx, f: impl Fn(f32) -> f32) -> Avx {
    let mut r = a.0;
    for v in &mut r {
        *v = f(*v);
    }
    Avx(r)
}

/// `f` lane by lane over two.
#[inline(always)]
fn pair(a: Avx, b: Avx, f: impl Fn(f32, f32) -> f32) -> Avx {
    let mut r = a.0;
    for (v, &o) in r.iter_mut().zip(&b.0) {
        *v = f(*v, o);
    }
    Avx(r)
}

impl Add for Avx {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        pair(self, o, |a, b| a + b)
    }
}

impl Sub for Avx {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        pair(self, o, |a, b| a - b)
    }
}

impl Mul for Avx {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        pair(self, o, |a, b| a * b)
    }
}

// Each operation is `f32`'s own, lane by lane: the same bits as the scalar path.
impl Lane for Avx {
    const LANES: usize = WIDTH;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Avx([v; WIDTH])
    }
    #[inline(always)]
    fn load(v: &[f32]) -> Self {
        Avx(v.try_into().expect("WIDTH values"))
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        out.copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn floor(self) -> Self {
        each(self, f32::floor)
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
        Avx(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::{sin_cos, Wide};

    /// Every operation of the AVX lanes gives the bits of `f32` and the values of the SSE2
    /// lanes, on values around the cases that differ between instructions (zeros of both
    /// signs, halves, exact integers, large and tiny values). Compiled for AVX2 in the engine,
    /// the same edges and plans: `tests/integration/lanes.rs`.
    #[test]
    fn avx_lanes_give_the_bits_of_the_other_paths() {
        let values: Vec<f32> = [
            0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 1.5, -2.5, 3.0, 7.25, -1e-7, 1e-30, 123.456, -987.6,
            0.785, 1e6,
        ]
        .into_iter()
        .chain((0..48).map(|i| (i as f32 * 0.37).sin() * 40.0))
        .collect();
        for x in values.chunks(WIDTH) {
            for y in values.chunks(WIDTH).rev() {
                same(x, y);
            }
        }
    }

    /// The lanes of each operation on `x` and `y` against `Wide` and `f32`.
    fn same(x: &[f32], y: &[f32]) {
        type Op<L> = fn(L, L) -> L;
        fn apply<L: Lane>(op: Op<L>, x: &[f32], y: &[f32]) -> Vec<u32> {
            let mut out = [0f32; WIDTH];
            for (n, (a, b)) in x.chunks(L::LANES).zip(y.chunks(L::LANES)).enumerate() {
                op(L::load(a), L::load(b)).store(&mut out[n * L::LANES..(n + 1) * L::LANES]);
            }
            out.iter().map(|v| v.to_bits()).collect()
        }
        fn ops<L: Lane>() -> Vec<Op<L>> {
            vec![
                |a, b| a + b,
                |a, b| a - b,
                |a, b| a * b,
                |a, b| a.max(b),
                |a, b| a.min(b),
                |a, _| a.abs().sqrt(),
                |a, _| (a * L::splat(1e-3)).floor(),
                |a, b| a.at_least_select(0.5, a, b),
                |a, _| sin_cos(a * L::splat(0.01)).0,
                |a, _| sin_cos(a * L::splat(0.01)).1,
            ]
        }
        // The same bits as `f32`, the scalar path; the same values as `Wide` (whose `floor`
        // gives +0 for -0).
        let value = |bits: Vec<u32>| bits.into_iter().map(f32::from_bits).collect::<Vec<_>>();
        for ((avx, wide), one) in ops::<Avx>()
            .into_iter()
            .zip(ops::<Wide>())
            .zip(ops::<f32>())
        {
            let a = apply(avx, x, y);
            assert_eq!(a, apply(one, x, y), "{x:?} {y:?}");
            assert_eq!(value(a), value(apply(wide, x, y)), "{x:?} {y:?}");
        }
        let (a, w) = (Avx::load(x), Wide::load(x));
        assert_eq!(a.least().to_bits(), w.least().to_bits());
        for v in [0.0, 0.5, -1.0] {
            assert_eq!(a.all_at_least(v), w.all_at_least(v));
        }
    }
}
