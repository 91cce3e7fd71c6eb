//! The vector path on AVX2, chosen at run time: [`WIDTH`] configurations in one 256-bit
//! register where the x86-64 baseline (SSE2) takes two 128-bit halves per operation.
//!
//! [`Avx`] is [`Wide`] (eight `f32`s operated on lane by lane in plain Rust) under another
//! name, so that its walk measures states in [`measure`], a function compiled for AVX2 into
//! which the measurement is inlined (`#[inline(always)]` down to the lane operations): there
//! the compiler turns each operation on eight lanes into one AVX instruction. The same code,
//! the same answers as the baseline. Intrinsics would not do: an intrinsic called from an
//! operator's function, which cannot carry the target feature, stays a call.

use std::ops::{Add, Mul, Sub};

use super::lanes::{Candidates, LaneChecks, LaneScratch};
use super::lanes_edge::{Buffers, Lanes};
use super::Checker;
use crate::lanes::{Lane, Wide, WIDTH};

/// [`Wide`], measured by code compiled for AVX2.
#[derive(Debug, Clone, Copy)]
struct Avx(Wide);

/// The AVX path's buffers ([`Buffers`]): placement, clearances out, joint values in.
#[derive(Debug, Default)]
pub(super) struct AvxBuffers((LaneScratch<Avx>, Vec<Avx>, Vec<Avx>));

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
        &mut b.avx.0
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

impl Add for Avx {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Avx(self.0 + o.0)
    }
}

impl Sub for Avx {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Avx(self.0 - o.0)
    }
}

impl Mul for Avx {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Avx(self.0 * o.0)
    }
}

impl Lane for Avx {
    const LANES: usize = WIDTH;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Avx(Wide::splat(v))
    }
    #[inline(always)]
    fn load(v: &[f32]) -> Self {
        Avx(Wide::load(v))
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        self.0.store(out)
    }
    // `f32::floor`, one `vroundps` here, where the baseline's truncation takes several.
    #[inline(always)]
    fn floor(self) -> Self {
        let mut r = self.0 .0;
        for v in &mut r {
            *v = v.floor();
        }
        Avx(Wide(r))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Avx(self.0.sqrt())
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Avx(self.0.abs())
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        Avx(self.0.max(o.0))
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        Avx(self.0.min(o.0))
    }
    #[inline(always)]
    fn least(self) -> f32 {
        self.0.least()
    }
    #[inline(always)]
    fn all_at_least(self, v: f32) -> bool {
        self.0.all_at_least(v)
    }
    #[inline(always)]
    fn at_least_select(self, v: f32, then: Self, otherwise: Self) -> Self {
        Avx(self.0.at_least_select(v, then.0, otherwise.0))
    }
}
