//! Proving an edge free in lanes: its states measured [`WIDTH`] at a time at sphere level,
//! steps sized from the measured clearances, in the manner of conservative advancement.
//!
//! Along the edge from `a` to `b` (parameter `t` in [0, 1]) the points of body `k` (or of a
//! pair's two bodies, relative to each other) move at most `m_k` per unit of `t`
//! ([`Checker::speeds`]). If the clearances `c_i` and `c_j` at `t_i < t_j` satisfy
//! `c_i + c_j > m_k (t_j − t_i)`, nothing of `k` can touch anything between them: at any `τ` in
//! between a contact needs `c_i ≤ m_k (τ − t_i)` and `c_j ≤ m_k (t_j − τ)`. The walk measures
//! eight states spread over the edge, then splits every pair of neighbours that fails the rule
//! (into as many parts as the rule says it needs), until none fails: the edge is proven. The
//! clearances are `f32` lower bounds, each taken `EPSILON` lower in the rule for the rounding
//! of `f32` placement (measured within 2 µm of the `f64` kinematics).

use std::sync::atomic::Ordering;

use super::lanes::{Candidates, LaneChecks, LaneScratch};
use super::Checker;
use crate::lanes::{Lane, Wide, WIDTH};
use crate::{Error, Result};

/// How a checker proves edges ([`Checker::set_engine`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Engine {
    /// Conservative advancement on the checker's own stages (`edge.rs`).
    Advancement,
    /// The vectorised engine: states measured [`WIDTH`] at a time at sphere level, the
    /// advancement where the spheres are not conclusive; on AVX2 where the CPU has it
    /// (detected at run time), else as [`Engine::Baseline`].
    Lanes,
    /// [`Engine::Lanes`] on the target's baseline instructions whatever the CPU (two SSE2
    /// halves per operation on x86-64): the same answers.
    Baseline,
    /// The vectorised engine's walk one state at a time, in `f32`: the same answers as
    /// [`Engine::Lanes`] for the same edge, without SIMD.
    Scalar,
}

impl Checker {
    /// How [`Checker::motion_free`] proves edges.
    pub fn engine(&self) -> Engine {
        self.engine
    }

    /// Proves edges with `engine` from now on; an error, and nothing changed, for the
    /// vectorised engine in a scene with voxels, which it does not hold.
    pub fn set_engine(&mut self, engine: Engine) -> Result<()> {
        if engine != Engine::Advancement && self.lanes.is_none() {
            // Built when first needed: a checker on the advancement never holds them.
            self.lanes = self.lane_checks()?;
            if self.lanes.is_none() {
                return Err(Error::Invalid {
                    what: format!("engine {engine:?}"),
                    why: "the scene holds voxels, which the vectorised engine does not".into(),
                });
            }
        }
        self.engine = engine;
        Ok(())
    }

    /// The engine a new checker proves edges with: the vectorised one when every moving
    /// body's spheres are its shapes (a spherized model, as VAMP's robots are), the
    /// advancement otherwise. Where spheres only cover meshes, they are not conclusive near
    /// the robot's own parts (the LoCoBot's arm over its base, the Sawyer's `right_l1` beside
    /// its head, whose covers overlap in every configuration), and the exact stage the walk
    /// then needs made it slower than the advancement on the bundled robots' sets
    /// (`BENCHMARKS.md`).
    pub(super) fn default_engine(&self) -> Engine {
        let spherized = self
            .bodies
            .iter()
            .filter(|b| b.moving)
            .all(|b| b.spheres_exact);
        // The engine holds no voxels ([`Checker::lane_checks`]).
        if self.grid.is_none() && spherized {
            Engine::Lanes
        } else {
            Engine::Advancement
        }
    }
}

/// Room (m) the rule keeps per clearance for the rounding of `f32` placement.
const EPSILON: f32 = 1e-5;

/// Where a bounding sphere is at least this far (m) from something, its gap stands for the
/// spheres inside it, which are not measured.
const GATE: f32 = 0.05;

/// States of the walk's first round, evenly spread from `a` to `b`.
const FIRST: usize = WIDTH;

/// Most parts one pair of neighbouring states is split into per round.
const MAX_SPLIT: usize = 16;

/// Most states of one edge the spheres are asked to prove before the edge goes to the
/// checker's conservative advancement instead.
const MAX_STATES: usize = 2048;

/// How a walk ended.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Walk {
    /// Every step proven.
    Free,
    /// A state in contact.
    Contact,
    /// A state too near contact for the rule to prove its steps.
    Stuck,
    /// More than [`MAX_STATES`] states.
    Long,
}

/// Buffers of the walk, kept from edge to edge.
#[derive(Debug, Default)]
pub(super) struct WalkScratch {
    buffers: Buffers,
    /// One chunk's clearances, per lane.
    lanes: Vec<[f32; WIDTH]>,
    /// The states measured: their `t` and, [`LaneChecks::count`] per state, clearances.
    ts: Vec<f64>,
    clear: Vec<f32>,
    /// The neighbouring states (indices into `ts`) the next split judges.
    pairs: Vec<(usize, usize)>,
    /// The neighbours the last split did not prove, `(i, j, first, count)`: the states
    /// `first..first + count` of `ts` lie between states `i` and `j`, in order of `t`. The
    /// neighbours it proved stay proven: only these are judged again.
    open: Vec<(usize, usize, usize, usize)>,
    next: Vec<f64>,
    /// The neighbours the rule does not prove: indices into `ts`, need, parts.
    failing: Vec<(usize, usize, f64, usize)>,
    nearest: Vec<f32>,
    limit: Vec<f32>,
    /// Per body, then per pair: the clearance beyond which nothing is measured, m.
    caps: Vec<f32>,
    /// Each joint's motion over the edge, `|b − a|` (rad or m).
    moves: Vec<f64>,
    /// Each body's and pair's motion bound over the edge, m ([`LaneChecks::motion_bounds`]).
    sums: Vec<f64>,
    motion: Vec<f32>,
    candidates: Candidates,
}

/// The buffers of each path: placement, clearances out, joint values in.
#[derive(Debug, Default)]
pub(super) struct Buffers {
    wide: (LaneScratch<Wide>, Vec<Wide>, Vec<Wide>),
    one: (LaneScratch<f32>, Vec<f32>, Vec<f32>),
    #[cfg(target_arch = "x86_64")]
    pub(super) avx: super::lanes_avx::AvxBuffers,
}

/// A [`Lane`] type with its [`Buffers`] and its measure of a state.
pub(super) trait Lanes: Lane {
    fn buffers(b: &mut Buffers) -> &mut (LaneScratch<Self>, Vec<Self>, Vec<Self>);

    /// [`LaneChecks::measure`] (a type may compile it for its instructions).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
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
        checks.measure(q, candidates, limits, scratch, out, nearest, contact)
    }
}

impl Lanes for Wide {
    fn buffers(b: &mut Buffers) -> &mut (LaneScratch<Self>, Vec<Self>, Vec<Self>) {
        &mut b.wide
    }
}

impl Lanes for f32 {
    fn buffers(b: &mut Buffers) -> &mut (LaneScratch<Self>, Vec<Self>, Vec<Self>) {
        &mut b.one
    }
}

impl Checker {
    /// Whether the straight joint-space edge from `a` to `b` is free, with `checks` (this
    /// checker's [`Checker::lane_checks`]): proven at sphere level in lanes (the module's
    /// rule); where the spheres are not conclusive, the exact check at that state refuses the
    /// edge in contact, and otherwise the checker's conservative advancement decides.
    ///
    /// On AVX2 (detected at run time) the lanes are one 256-bit register, otherwise two
    /// SSE2 halves: the same answers.
    pub fn motion_free_in_lanes(&self, checks: &LaneChecks, a: &[f64], b: &[f64]) -> bool {
        #[cfg(target_arch = "x86_64")]
        if let Some(free) = super::lanes_avx::edge(self, checks, a, b) {
            return free;
        }
        self.motion_free_in_baseline_lanes(checks, a, b)
    }

    /// [`Checker::motion_free_in_lanes`] on the target's baseline instructions ([`Wide`]: two
    /// SSE2 halves per operation on x86-64) whatever the CPU: the same answer.
    pub fn motion_free_in_baseline_lanes(&self, checks: &LaneChecks, a: &[f64], b: &[f64]) -> bool {
        self.edge_in_lanes::<Wide>(checks, a, b)
    }

    /// [`Checker::motion_free_in_lanes`] one state at a time in `f32` (the same answer).
    pub fn motion_free_in_lanes_scalar(&self, checks: &LaneChecks, a: &[f64], b: &[f64]) -> bool {
        self.edge_in_lanes::<f32>(checks, a, b)
    }

    pub(super) fn edge_in_lanes<L: Lanes>(
        &self,
        checks: &LaneChecks,
        a: &[f64],
        b: &[f64],
    ) -> bool {
        if !self.within_limits(a) || !self.within_limits(b) {
            return false;
        }
        let exact_below = self.opts.resolution * 0.5;
        let mut q = Vec::new();
        // Where the spheres are not conclusive: the checker's own stages, first for contact
        // alone, then for a clearance in units of the edge parameter (exact shapes where the
        // spheres limit it below `cap`). What they need is computed there, the first time.
        let mut needs = None;
        let mut exact = |t: f64| {
            let (speeds, cap) = needs.get_or_insert_with(|| {
                let cap = (self.opts.max_step / self.motion_bound(a, b)).min(1.0);
                (self.speeds(a, b), cap)
            });
            q.clear();
            q.extend(a.iter().zip(b).map(|(x, y)| x + (y - x) * t));
            self.measure(&q, 0.0).ok()?;
            self.measure_with(&q, Some(speeds), *cap, exact_below).ok()
        };
        let walk = {
            let mut s = self.walk_scratch.borrow_mut();
            let s = &mut *s;
            // The walk's bodies' and pairs' motion bounds ([`Checker::speeds`]' for them),
            // rounded up into `f32`.
            s.moves.clear();
            s.moves.extend(a.iter().zip(b).map(|(x, y)| (x - y).abs()));
            checks.motion_bounds(&s.moves, &mut s.sums);
            s.motion.clear();
            s.motion
                .extend(s.sums.iter().map(|&m| (m * (1.0 + 1e-6)) as f32));
            let k = checks.count();
            let mut walker = Walker {
                s,
                k,
                exact: &mut exact,
            };
            let walk = walker.walk::<L>(checks, a, b);
            self.counters
                .states
                .fetch_add(s.ts.len() as u64, Ordering::Relaxed);
            walk
        };
        self.counters.edges.fetch_add(1, Ordering::Relaxed);
        match walk {
            Walk::Free => true,
            Walk::Contact => false,
            Walk::Stuck | Walk::Long => self.advanced(a, b),
        }
    }
}

/// A walk's buffers, its number of clearances per state, and the checker's own measure of a
/// state ([`Checker::measure_with`] at edge parameter `t`: `None` in contact).
struct Walker<'a> {
    s: &'a mut WalkScratch,
    k: usize,
    exact: &'a mut dyn FnMut(f64) -> Option<f64>,
}

impl Walker<'_> {
    /// The walk over the edge from `a` to `b`, `s.motion` holding each body's and pair's
    /// motion bound along it (m).
    fn walk<L: Lanes>(&mut self, checks: &LaneChecks, a: &[f64], b: &[f64]) -> Walk {
        let s = &mut *self.s;
        s.caps.clear();
        // No clearance is needed beyond this: two such states prove the whole edge,
        // 2 (m/2 + 3ε) > m + 2ε.
        let ceilings = s.motion.iter().map(|m| 0.5 * m + 3.0 * EPSILON);
        s.caps.extend(ceilings);
        s.ts.clear();
        s.clear.clear();
        s.open.clear();
        s.nearest.clear();
        s.nearest.resize(checks.nearest_len(), f32::MAX);
        s.next.clear();
        s.next
            .extend((0..FIRST).map(|i| i as f64 / (FIRST - 1) as f64));
        if let Some(end) = self.measure::<L>(checks, a, b, checks.all_candidates(), true) {
            return end;
        }
        // Between the first states a point moves at most m / (2 (FIRST − 1)) to the nearest
        // one.
        let s = &mut *self.s;
        s.limit.clear();
        let slack = s
            .motion
            .iter()
            .map(|m| m * (0.5 / (FIRST - 1) as f32) + EPSILON);
        s.limit.extend(slack);
        let (candidates, floors) = checks.near(&s.nearest, &s.limit, GATE);
        s.candidates = candidates;
        for (cap, floor) in s.caps.iter_mut().zip(floors) {
            *cap = cap.min(floor);
        }
        loop {
            self.split();
            if self.s.next.is_empty() {
                return Walk::Free;
            }
            if self.s.ts.len() + self.s.next.len() > MAX_STATES {
                return Walk::Long;
            }
            let candidates = std::mem::take(&mut self.s.candidates);
            let end = self.measure::<L>(checks, a, b, &candidates, false);
            self.s.candidates = candidates;
            if let Some(end) = end {
                return end;
            }
        }
    }

    /// Measures the states `s.next` against `candidates` (recording the nearest bounding
    /// distances with `record`), [`WIDTH`] at a time, and keeps them; how the walk ends if it
    /// does. Of each group of [`WIDTH`] states: if a body or pair that is
    /// [`LaneChecks::exact`] comes within `2 EPSILON` of something at one of them, a contact;
    /// otherwise each state whose clearances are not all above `2 EPSILON` is measured again
    /// by the checker's own stages (each clearance at least that many units of the edge
    /// parameter times its motion), and the walk ends if it is in contact or still not above.
    fn measure<L: Lanes>(
        &mut self,
        checks: &LaneChecks,
        a: &[f64],
        b: &[f64],
        candidates: &Candidates,
        record: bool,
    ) -> Option<Walk> {
        let next = std::mem::take(&mut self.s.next);
        let mut end = None;
        for group in next.chunks(WIDTH) {
            if self.measure_group::<L>(checks, (a, b), group, candidates, record) {
                end = Some(Walk::Contact);
                break;
            }
            end = self.decide(group);
            if end.is_some() {
                break;
            }
        }
        self.s.next = next;
        self.s.next.clear();
        end
    }

    /// Measures the states `group` (at most [`WIDTH`]) into `s.lanes`, [`Lane::LANES`] at a
    /// time; true at a contact of an exact body or pair (`s.lanes` is then incomplete).
    fn measure_group<L: Lanes>(
        &mut self,
        checks: &LaneChecks,
        (a, b): (&[f64], &[f64]),
        group: &[f64],
        candidates: &Candidates,
        record: bool,
    ) -> bool {
        let s = &mut *self.s;
        s.lanes.clear();
        s.lanes.resize(self.k, [0f32; WIDTH]);
        let mut values = [0f32; WIDTH];
        for (n, chunk) in group.chunks(L::LANES).enumerate() {
            let t = |l: usize| chunk[l.min(chunk.len() - 1)];
            let (scratch, out, q) = L::buffers(&mut s.buffers);
            q.clear();
            for (x, y) in a.iter().zip(b) {
                for (l, v) in values.iter_mut().take(L::LANES).enumerate() {
                    *v = (x + (y - x) * t(l)) as f32;
                }
                q.push(L::load(&values[..L::LANES]));
            }
            out.clear();
            out.resize(self.k, L::splat(0.0));
            let nearest = record.then_some(s.nearest.as_mut_slice());
            let contact = 2.0 * EPSILON;
            let limits = (GATE, s.caps.as_slice());
            if L::measure(
                checks, q, candidates, limits, scratch, out, nearest, contact,
            ) {
                return true;
            }
            let at = n * L::LANES;
            for (lanes, v) in s.lanes.iter_mut().zip(out.iter()) {
                v.store(&mut values[..L::LANES]);
                lanes[at..at + L::LANES].copy_from_slice(&values[..L::LANES]);
            }
        }
        false
    }

    /// Keeps the states `group` measured into `s.lanes`, in order, each not conclusive one
    /// measured again by the checker; how the walk ends if it does there.
    fn decide(&mut self, group: &[f64]) -> Option<Walk> {
        let s = &mut *self.s;
        for (l, &t) in group.iter().enumerate() {
            s.ts.push(t);
            let from = s.clear.len();
            s.clear.extend(s.lanes.iter().map(|v| v[l]));
            let state = &mut s.clear[from..];
            if state.iter().all(|&c| c > 2.0 * EPSILON) {
                continue;
            }
            let Some(tau) = (self.exact)(t) else {
                return Some(Walk::Contact);
            };
            // Below `tau · m` by more than `m`'s rounding up.
            for (c, &m) in state.iter_mut().zip(&s.motion) {
                *c = c.max((tau * f64::from(m) * (1.0 - 1e-5)) as f32);
            }
            if !state.iter().all(|&c| c > 2.0 * EPSILON) {
                return Some(Walk::Stuck);
            }
        }
        None
    }

    /// Fills `s.next` with the states that split each pair of neighbouring states the rule
    /// does not prove, into as many equal parts as their clearances need (at most
    /// [`MAX_SPLIT`]).
    fn split(&mut self) {
        let (s, k) = (&mut *self.s, self.k);
        // Every neighbour in order of `t`: the first states' (measured in that order), then
        // within each neighbour the last split did not prove, the states measured in it.
        s.pairs.clear();
        if s.open.is_empty() {
            s.pairs.extend((1..s.ts.len()).map(|j| (j - 1, j)));
        }
        for &(i, j, first, count) in &s.open {
            let mut prev = i;
            for n in first..first + count {
                s.pairs.push((prev, n));
                prev = n;
            }
            s.pairs.push((prev, j));
        }
        s.next.clear();
        s.failing.clear();
        for &(i, j) in &s.pairs {
            let dt = s.ts[j] - s.ts[i];
            let (ci, cj) = (&s.clear[i * k..(i + 1) * k], &s.clear[j * k..(j + 1) * k]);
            let need = ci
                .iter()
                .zip(cj)
                .zip(&s.motion)
                .map(|((&x, &y), &m)| {
                    let need = f64::from(m) * dt + 2.0 * f64::from(EPSILON);
                    need / (f64::from(x) + f64::from(y))
                })
                .fold(0.0f64, f64::max);
            if need >= 1.0 {
                let parts = (need.ceil() as usize).clamp(2, MAX_SPLIT);
                s.failing.push((i, j, need, parts));
            }
        }
        // States that would leave the last group's lanes empty go to the neediest parts.
        let mut total: usize = s.failing.iter().map(|f| f.3 - 1).sum();
        while total > 0 && !total.is_multiple_of(WIDTH) {
            let Some(f) = s
                .failing
                .iter_mut()
                .filter(|f| f.3 < MAX_SPLIT)
                .max_by(|a, b| (a.2 / a.3 as f64).total_cmp(&(b.2 / b.3 as f64)))
            else {
                break;
            };
            f.3 += 1;
            total += 1;
        }
        // The new states go to `ts` in this order ([`Walker::decide`]).
        s.open.clear();
        let mut at = s.ts.len();
        for &(i, j, _, parts) in &s.failing {
            let (t0, dt) = (s.ts[i], s.ts[j] - s.ts[i]);
            s.next
                .extend((1..parts).map(|p| t0 + dt * p as f64 / parts as f64));
            s.open.push((i, j, at, parts - 1));
            at += parts - 1;
        }
    }
}
