//! This checker's checks for the vectorised engine ([`crate::lanes`]): its moving bodies'
//! spheres, each body's obstacles (the world's, padded, and the robot's parts that do not
//! move), and its moving pairs, at sphere level.

use std::sync::atomic::Ordering;

use super::Checker;
use crate::lanes::{Environment, Frame, Lane, SphereProgram, Wide, WIDTH};
use crate::Result;

/// A state's checks at sphere level for many configurations at once.
#[derive(Debug, Clone)]
pub struct LaneChecks {
    program: SphereProgram,
    /// For each body of `program`, what it is checked against.
    world: Vec<Environment>,
    /// Moving pairs, as bodies of `program`.
    pairs: Vec<(usize, usize)>,
    /// The checker's body behind each of `program`'s.
    bodies: Vec<usize>,
    /// The checker's pair behind each of `pairs`.
    pair_of: Vec<usize>,
}

/// How far each body's points and each pair's points relative to each other move between
/// two neighbouring states of an edge, halved, m: what each clearance must exceed at every
/// state for the spheres to prove every step free.
#[derive(Debug, Clone, Default)]
struct Slack {
    body: Vec<f32>,
    pair: Vec<f32>,
}

/// Buffers of [`LaneChecks::clearance`].
#[derive(Debug, Clone)]
pub struct LaneScratch<L> {
    frames: Vec<Frame<L>>,
    centres: Vec<[L; 3]>,
}

impl<L> Default for LaneScratch<L> {
    fn default() -> Self {
        LaneScratch {
            frames: Vec::new(),
            centres: Vec::new(),
        }
    }
}

impl Checker {
    /// This checker's state checks for the vectorised engine; `None` when the scene holds
    /// voxels, which the engine does not.
    pub fn lane_checks(&self) -> Result<Option<LaneChecks>> {
        if self.grid.is_some() {
            return Ok(None);
        }
        let moving: Vec<usize> = (0..self.bodies.len())
            .filter(|&b| self.bodies[b].moving && !self.bodies[b].spheres.is_empty())
            .collect();
        let bodies: Vec<(usize, &[crate::spheres::Sphere])> = moving
            .iter()
            .map(|&b| (self.bodies[b].link, self.bodies[b].spheres.as_slice()))
            .collect();
        let program = SphereProgram::with_bodies(&self.model, &bodies)?;
        let world = moving
            .iter()
            .map(|&b| {
                let mut env = Environment::default();
                for &k in &self.all_of[b] {
                    let o = self.obstacle(k);
                    // The padding keeps room from the world, not from the robot's own parts.
                    let padding = if k < self.obstacles.len() {
                        self.opts.padding
                    } else {
                        0.0
                    };
                    env.push_sdf(&o.id, o.inv, o.sdf, false, padding);
                }
                env
            })
            .collect();
        let index = |b: usize| moving.iter().position(|&m| m == b);
        let (mut pairs, mut pair_of) = (Vec::new(), Vec::new());
        for (p, &(a, b)) in self.pairs.iter().enumerate() {
            if let (Some(a), Some(b)) = (index(a), index(b)) {
                pairs.push((a, b));
                pair_of.push(p);
            }
        }
        Ok(Some(LaneChecks {
            program,
            world,
            pairs,
            bodies: moving,
            pair_of,
        }))
    }
}

impl LaneChecks {
    /// The program placing the spheres.
    pub fn program(&self) -> &SphereProgram {
        &self.program
    }

    /// The smallest clearance (m) at the configurations `q` (one value per planned joint,
    /// each holding [`Lane::LANES`] configurations), per lane: of every moving sphere from its
    /// body's obstacles, and of every moving pair's spheres from each other. Positive: the
    /// spheres, which hold the robot, prove the configuration free; otherwise the spheres are
    /// not conclusive (the exact check decides).
    pub fn clearance<L: Lane>(&self, q: &[L], scratch: &mut LaneScratch<L>) -> L {
        self.least(q, None, scratch)
    }

    /// [`LaneChecks::clearance`], each body's clearances less its `slack.body` and each
    /// pair's less its `slack.pair` (none without `slack`).
    fn least<L: Lane>(&self, q: &[L], slack: Option<&Slack>, scratch: &mut LaneScratch<L>) -> L {
        self.program
            .place(q, &mut scratch.frames, &mut scratch.centres);
        let c = &scratch.centres;
        let spheres = self.program.spheres();
        let mut least = L::splat(f32::MAX);
        for (b, env) in self.world.iter().enumerate() {
            let less = slack.map_or(0.0, |s| s.body[b]);
            for i in self.program.body(b) {
                least = least.min(env.distance(&c[i]) - L::splat(spheres[i].radius + less));
            }
        }
        for (p, &(a, b)) in self.pairs.iter().enumerate() {
            let less = slack.map_or(0.0, |s| s.pair[p]);
            for i in self.program.body(a) {
                for k in self.program.body(b) {
                    let d = [0, 1, 2].map(|x| c[i][x] - c[k][x]);
                    let gap = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
                        - L::splat(spheres[i].radius + spheres[k].radius + less);
                    least = least.min(gap);
                }
            }
        }
        least
    }
}

/// Most states of one edge the spheres are asked to prove before the edge goes to the
/// checker's conservative advancement instead.
const MAX_STATES: usize = 4096;

impl Checker {
    /// Whether the straight joint-space edge from `a` to `b` is free, as
    /// [`Checker::motion_free`] answers it, with `checks` (this checker's
    /// [`Checker::lane_checks`]) first: the edge is cut into equal steps of at most
    /// `resolution` of the fastest point's motion, and its states are measured
    /// [`crate::lanes::WIDTH`] at a time. When every state's sphere clearances exceed half
    /// what their points can move in a step, each step's two ends together exceed the whole
    /// step: the spheres, which hold the robot, prove the edge free. The first state where they
    /// do not is checked exactly; in contact, the edge is refused; free, the checker's own
    /// advancement decides.
    pub fn motion_free_in_lanes(&self, checks: &LaneChecks, a: &[f64], b: &[f64]) -> bool {
        if !self.within_limits(a) || !self.within_limits(b) {
            return false;
        }
        let speeds = self.speeds(a, b);
        let fastest = checks
            .bodies
            .iter()
            .map(|&b| speeds.body[b])
            .chain(checks.pair_of.iter().map(|&p| speeds.pair[p]))
            .fold(0.0f64, f64::max);
        let steps = (fastest / self.opts.resolution).ceil().max(1.0);
        if !steps.is_finite() || steps as usize > MAX_STATES {
            return self.motion_free(a, b);
        }
        let n = steps as usize;
        let half = |s: f64| (s / steps * 0.5) as f32;
        let slack = Slack {
            body: checks
                .bodies
                .iter()
                .map(|&b| half(speeds.body[b]))
                .collect(),
            pair: checks
                .pair_of
                .iter()
                .map(|&p| half(speeds.pair[p]))
                .collect(),
        };
        match first_unproven(checks, &slack, a, b, n) {
            None => {
                self.counters.edges.fetch_add(1, Ordering::Relaxed);
                true
            }
            Some(t) => {
                let q: Vec<f64> = a.iter().zip(b).map(|(x, y)| x + (y - x) * t).collect();
                self.is_free(&q) && self.motion_free(a, b)
            }
        }
    }
}

/// The edge parameter of the first state (in the rake's order: the ends, the middle, the
/// quarters…) of the `n + 1` equally spaced on the edge from `a` to `b` whose clearance less
/// `slack` is not positive; `None` when every state's is.
fn first_unproven(
    checks: &LaneChecks,
    slack: &Slack,
    a: &[f64],
    b: &[f64],
    n: usize,
) -> Option<f64> {
    let order = rake_order(n);
    let mut scratch = LaneScratch::<Wide>::default();
    let dof = a.len();
    let mut lanes = vec![Wide::splat(0.0); dof];
    let mut values = [0f32; WIDTH];
    for batch in order.chunks(WIDTH) {
        let t = |k: usize| batch[k.min(batch.len() - 1)] as f64 / n as f64;
        for (j, lane) in lanes.iter_mut().enumerate() {
            for (k, v) in values.iter_mut().enumerate() {
                *v = (a[j] + (b[j] - a[j]) * t(k)) as f32;
            }
            *lane = Wide::load(&values);
        }
        let least = checks.least(&lanes, Some(slack), &mut scratch).to_array();
        if let Some(k) = (0..batch.len()).find(|&k| least[k] <= 0.0) {
            return Some(t(k));
        }
    }
    None
}

/// `0..=n` in the rake's order: 0 and `n`, then the middle, then the quarters, and so on,
/// each index once.
fn rake_order(n: usize) -> Vec<usize> {
    let mut seen = vec![false; n + 1];
    let mut out = Vec::with_capacity(n + 1);
    let mut push = |k: usize, out: &mut Vec<usize>| {
        if !seen[k] {
            seen[k] = true;
            out.push(k);
        }
    };
    push(0, &mut out);
    push(n, &mut out);
    let mut parts = 2;
    while out.len() < n + 1 {
        for i in (1..parts).step_by(2) {
            push(i * n / parts, &mut out);
        }
        parts *= 2;
        if parts > 2 * (n + 1) {
            for k in 0..=n {
                push(k, &mut out);
            }
        }
    }
    out
}
