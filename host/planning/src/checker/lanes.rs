//! This checker's checks for the vectorised engine ([`crate::lanes`]): its moving bodies'
//! spheres (each body's bounding sphere first, then its own), each body's obstacles (the
//! world's, padded, and the robot's parts that do not move), and its moving pairs, at sphere
//! level. The edge proof built on them is in `lanes_edge.rs`.

use super::Checker;
use crate::lanes::{Environment, Frame, Lane, SphereProgram};
use crate::spheres::Sphere;
use crate::Result;

/// A state's checks at sphere level for many configurations at once.
#[derive(Debug, Clone)]
pub struct LaneChecks {
    /// Each body's spheres: its bounding sphere (covering the rest), then its own.
    program: SphereProgram,
    /// For each body of `program`, what it is checked against.
    world: Vec<Environment>,
    /// Moving pairs, as bodies of `program`.
    pairs: Vec<(usize, usize)>,
    /// Every obstacle of each body and every pair.
    all: Candidates,
    /// Where each body's obstacles, then the pairs, start in [`LaneChecks::measure`]'s
    /// `nearest`.
    slots: Vec<usize>,
    /// For each body, then each pair: whether its spheres and what it is checked against are
    /// the shapes themselves (spheres and primitives), so that spheres in contact are shapes
    /// in contact.
    pub(super) exact: Vec<bool>,
    /// The checker's reach (m per rad or m) of each body, then each pair, joint by joint:
    /// [`LaneChecks::count`] values per planned joint, for [`LaneChecks::motion_bounds`].
    reach: Vec<f64>,
}

/// Buffers of [`LaneChecks::clearance`].
#[derive(Debug, Clone)]
pub struct LaneScratch<L> {
    frames: Vec<Frame<L>>,
    centres: Vec<[L; 3]>,
    /// Per body, whether its own spheres are placed in `centres` ([`LaneChecks::measure`]
    /// places them only where its bounding sphere is not conclusive).
    placed: Vec<bool>,
    /// The body that met something last: [`LaneChecks::measure`] measures it first.
    first: usize,
}

impl<L> Default for LaneScratch<L> {
    fn default() -> Self {
        LaneScratch {
            frames: Vec::new(),
            centres: Vec::new(),
            placed: Vec::new(),
            first: 0,
        }
    }
}

/// For one edge, what each body and each pair is measured against: the rest stays farther
/// than its cap on the whole edge ([`LaneChecks::measure`]).
#[derive(Debug, Clone, Default)]
pub(super) struct Candidates {
    /// For each body, indices into its [`Environment`].
    pub obstacles: Vec<Vec<u32>>,
    /// Indices into the moving pairs.
    pub pairs: Vec<u32>,
}

impl Candidates {
    /// Everything: each body's every obstacle and every pair.
    fn all(checks: &LaneChecks) -> Self {
        Candidates {
            obstacles: checks
                .world
                .iter()
                .map(|env| (0..env.len() as u32).collect())
                .collect(),
            pairs: (0..checks.pairs.len() as u32).collect(),
        }
    }
}

/// The smallest sphere about `bound`'s centre that holds every sphere of `spheres` (and
/// `bound`), in `f32`, a micrometre over.
fn cover(bound: &Sphere, spheres: &[Sphere]) -> Sphere {
    let radius = spheres
        .iter()
        .map(|s| (s.centre - bound.centre).norm() + s.radius)
        .fold(bound.radius, f64::max);
    Sphere {
        centre: bound.centre,
        radius: radius + 1e-6,
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
        let spheres: Vec<Vec<Sphere>> = moving
            .iter()
            .map(|&b| {
                let body = &self.bodies[b];
                let mut list = vec![cover(&body.bound, &body.spheres)];
                list.extend_from_slice(&body.spheres);
                list
            })
            .collect();
        let bodies: Vec<(usize, &[Sphere])> = moving
            .iter()
            .zip(&spheres)
            .map(|(&b, s)| (self.bodies[b].link, s.as_slice()))
            .collect();
        let program = SphereProgram::with_bodies(&self.model, &bodies)?;
        let world = moving.iter().map(|&b| self.environment_of(b)).collect();
        let index = |b: usize| moving.iter().position(|&m| m == b);
        let (mut pairs, mut pair_of) = (Vec::new(), Vec::new());
        for (p, &(a, b)) in self.pairs.iter().enumerate() {
            if let (Some(a), Some(b)) = (index(a), index(b)) {
                pairs.push((a, b));
                pair_of.push(p);
            }
        }
        let own_exact = |b: usize| self.bodies[b].spheres_exact;
        let exact = moving
            .iter()
            .zip(&world)
            .map(|(&b, env): (&usize, &Environment)| own_exact(b) && env.exact())
            .chain(pair_of.iter().map(|&p| {
                let (a, b) = self.pairs[p];
                own_exact(a) && own_exact(b)
            }))
            .collect();
        let rows: Vec<&Vec<f64>> = moving
            .iter()
            .map(|&b| &self.body_reach[b])
            .chain(pair_of.iter().map(|&p| &self.pair_reach[p]))
            .collect();
        let reach = (0..self.model.dof())
            .flat_map(|j| rows.iter().map(move |r| r[j]))
            .collect();
        let mut checks = LaneChecks {
            program,
            world,
            pairs,
            all: Candidates::default(),
            exact,
            slots: Vec::new(),
            reach,
        };
        checks.all = Candidates::all(&checks);
        let mut slot = 0;
        for env in &checks.world {
            checks.slots.push(slot);
            slot += env.len();
        }
        checks.slots.push(slot);
        Ok(Some(checks))
    }

    /// Body `b`'s obstacles as the engine holds them.
    fn environment_of(&self, b: usize) -> Environment {
        let mut env = Environment::default();
        for &k in &self.all_of[b] {
            let o = self.obstacle(k);
            env.push_sdf(&o.id, o.inv, o.sdf, o.exact, self.padding_of(k));
        }
        env
    }
}

impl LaneChecks {
    /// The program placing the spheres: each body's bounding sphere, then its own.
    pub fn program(&self) -> &SphereProgram {
        &self.program
    }

    /// Bodies (the program's) and moving pairs: the number of values
    /// [`LaneChecks::measure`] gives.
    pub(super) fn count(&self) -> usize {
        self.world.len() + self.pairs.len()
    }

    /// Body `b`'s own spheres, without its bounding sphere.
    fn own(&self, b: usize) -> std::ops::Range<usize> {
        let r = self.program.body(b);
        r.start + 1..r.end
    }

    /// The smallest clearance (m) at the configurations `q` (one value per planned joint,
    /// each holding [`Lane::LANES`] configurations), per lane: of every moving sphere from its
    /// body's obstacles, and of every moving pair's spheres from each other. Positive: the
    /// spheres, which hold the robot, prove the configuration free; otherwise the spheres are
    /// not conclusive (the exact check decides).
    pub fn clearance<L: Lane>(&self, q: &[L], scratch: &mut LaneScratch<L>) -> L {
        self.program
            .place(q, &mut scratch.frames, &mut scratch.centres);
        let c = &scratch.centres;
        let spheres = self.program.spheres();
        let mut least = L::splat(f32::MAX);
        for (b, env) in self.world.iter().enumerate() {
            for i in self.own(b) {
                least = least.min(env.distance(&c[i]) - L::splat(spheres[i].radius));
            }
        }
        for &(a, b) in &self.pairs {
            for i in self.own(a) {
                for k in self.own(b) {
                    least = least.min(gap(&c[i], &c[k], spheres[i].radius + spheres[k].radius));
                }
            }
        }
        least
    }

    /// Lower bounds of the clearances at `q`, per lane, into `out`: for each body (the
    /// program's), of its spheres from its `candidates` obstacles, then for each moving pair,
    /// of its two bodies' spheres, each at most its `ceilings` value (m): one bound per body
    /// and per pair. Where a bounding sphere is at least `gate` from an obstacle (or from the
    /// other body's bounding sphere, or one sphere from the other body's bounding sphere), that
    /// gap is the bound and the spheres inside are not measured.
    ///
    /// With `nearest`, each body's bounding sphere's least distance to each of its
    /// obstacles, then each pair's bounding spheres' gap, over the lanes, is lowered into it
    /// (in [`Candidates::all`]'s order; `candidates` must be all of them).
    ///
    /// Stops, and returns true, at the first body or pair that is [`LaneChecks::exact`] whose
    /// bound is at most `contact` in some lane: a contact (`out` is then incomplete).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn measure<L: Lane>(
        &self,
        q: &[L],
        candidates: &Candidates,
        (gate, ceilings): (f32, &[f32]),
        scratch: &mut LaneScratch<L>,
        out: &mut [L],
        mut nearest: Option<&mut [f32]>,
        contact: f32,
    ) -> bool {
        // The frames, and each body's bounding sphere; its own spheres when they are needed.
        self.program.frames(q, &mut scratch.frames);
        let bodies = self.world.len();
        scratch
            .centres
            .resize(self.program.spheres().len(), [L::splat(0.0); 3]);
        scratch.placed.clear();
        scratch.placed.resize(bodies, false);
        for b in 0..bodies {
            let bound = self.program.body(b).start;
            self.program
                .place_range(&scratch.frames, bound..bound + 1, &mut scratch.centres);
        }
        // The body that met something last first (a group in contact mostly meets it there
        // again, and ends before the others are measured), then the bodies farthest along the
        // chain: they move most, and meet things first. The order changes no answer.
        let first = scratch.first.min(bodies.saturating_sub(1));
        let rest = (0..bodies).rev().filter(|&b| b != first);
        for b in (0..bodies.min(1)).map(|_| first).chain(rest) {
            let record = nearest.as_deref_mut().map(|n| {
                let slot = self.slots[b];
                &mut n[slot..slot + candidates.obstacles[b].len()]
            });
            let obstacles = &candidates.obstacles[b];
            let stop = self.exact[b].then(|| contact.next_up());
            let limits = (gate, ceilings[b]);
            out[b] = self.body_bound(b, scratch, obstacles, limits, record, stop);
            if stop.is_some_and(|c| !out[b].all_at_least(c)) {
                scratch.first = b;
                return true;
            }
        }
        // A pair that is not a candidate stays at least its ceiling away.
        for (o, &ceiling) in out[bodies..].iter_mut().zip(&ceilings[bodies..]) {
            *o = L::splat(ceiling);
        }
        for &p in &candidates.pairs {
            let p = p as usize;
            let (value, far) = self.pair_bound(p, scratch, (gate, ceilings[bodies + p]));
            if let Some(n) = nearest.as_deref_mut() {
                let slot = self.slots[bodies] + p;
                n[slot] = n[slot].min(far);
            }
            out[bodies + p] = value;
            if self.exact[bodies + p] && !value.all_at_least(contact.next_up()) {
                return true;
            }
        }
        false
    }

    /// Body `b`'s clearance bound (at most `ceiling`) from its `obstacles`, its spheres
    /// placed at `c`; each obstacle's bounding gap, over the lanes, lowered into `record`.
    /// With `stop`, returns as soon as the bound is below it in some lane (a contact).
    #[inline(always)]
    fn body_bound<L: Lane>(
        &self,
        b: usize,
        scratch: &mut LaneScratch<L>,
        obstacles: &[u32],
        (gate, ceiling): (f32, f32),
        mut record: Option<&mut [f32]>,
        stop: Option<f32>,
    ) -> L {
        let env = &self.world[b];
        let spheres = self.program.spheres();
        let bound = self.program.body(b).start;
        let own = self.own(b);
        let mut least = L::splat(ceiling);
        for (k, &o) in obstacles.iter().enumerate() {
            let o = o as usize;
            let c = &scratch.centres;
            let far = env.spheres_gap(o, &c[bound..=bound], &spheres[bound..=bound]);
            if let Some(n) = record.as_deref_mut() {
                n[k] = n[k].min(far.least());
            }
            if far.all_at_least(gate) {
                least = least.min(far);
                continue;
            }
            self.place_own(b, scratch);
            let c = &scratch.centres;
            let near = env.spheres_gap(o, &c[own.clone()], &spheres[own.clone()]);
            least = least.min(far.at_least_select(gate, far, near.max(far)));
            if stop.is_some_and(|c| !least.all_at_least(c)) {
                return least;
            }
        }
        least
    }

    /// Pair `p`'s clearance bound (at most `ceiling`), its spheres placed at `c`, and its
    /// bounding spheres' least gap over the lanes.
    #[inline(always)]
    fn pair_bound<L: Lane>(
        &self,
        p: usize,
        scratch: &mut LaneScratch<L>,
        (gate, ceiling): (f32, f32),
    ) -> (L, f32) {
        let (a, b) = self.pairs[p];
        let spheres = self.program.spheres();
        let (ba, bb) = (self.program.body(a).start, self.program.body(b).start);
        let c = &scratch.centres;
        let far = gap(&c[ba], &c[bb], spheres[ba].radius + spheres[bb].radius);
        let ceiling = L::splat(ceiling);
        if far.all_at_least(gate) {
            return (far.min(ceiling), far.least());
        }
        self.place_own(a, scratch);
        self.place_own(b, scratch);
        let c = &scratch.centres;
        // Each of `a`'s spheres against `b`'s bounding sphere first, then its own.
        let mut own = L::splat(f32::MAX);
        for i in self.own(a) {
            let near = gap(&c[i], &c[bb], spheres[i].radius + spheres[bb].radius);
            if near.all_at_least(gate) {
                own = own.min(near);
                continue;
            }
            let mut least = L::splat(f32::MAX);
            for k in self.own(b) {
                least = least.min(gap(&c[i], &c[k], spheres[i].radius + spheres[k].radius));
            }
            own = own.min(near.at_least_select(gate, near, least.max(near)));
        }
        let value = far.at_least_select(gate, far, own.max(far));
        (value.min(ceiling), far.least())
    }

    /// Places body `b`'s own spheres into `scratch.centres` unless they are.
    #[inline(always)]
    fn place_own<L: Lane>(&self, b: usize, scratch: &mut LaneScratch<L>) {
        if !scratch.placed[b] {
            self.program
                .place_range(&scratch.frames, self.own(b), &mut scratch.centres);
            scratch.placed[b] = true;
        }
    }

    /// The candidates that may come within `gate` of their body or pair on an edge, from the
    /// least bounding gaps `nearest` ([`LaneChecks::measure`] with every candidate) less
    /// `slack` (per body, then per pair, m: how far they can close between the states
    /// measured); and for each body and pair, the least such bound of the others (m; `MAX`
    /// when none is dropped), which its clearance never goes below on the edge.
    pub(super) fn near(&self, nearest: &[f32], slack: &[f32], gate: f32) -> (Candidates, Vec<f32>) {
        let mut floors = vec![f32::MAX; self.count()];
        let obstacles = (0..self.world.len())
            .map(|b| {
                let slot = self.slots[b];
                let mut kept = Vec::new();
                for (&o, &n) in self.all.obstacles[b].iter().zip(&nearest[slot..]) {
                    let bound = n - slack[b];
                    if bound < gate {
                        kept.push(o);
                    } else {
                        floors[b] = floors[b].min(bound);
                    }
                }
                kept
            })
            .collect();
        let bodies = self.world.len();
        let mut pairs = Vec::new();
        for &p in &self.all.pairs {
            let k = bodies + p as usize;
            let bound = nearest[self.slots[bodies] + p as usize] - slack[k];
            if bound < gate {
                pairs.push(p);
            } else {
                floors[k] = floors[k].min(bound);
            }
        }
        (Candidates { obstacles, pairs }, floors)
    }

    /// Each body's, then each pair's, largest point motion (m) over an edge on which the
    /// planned joints move by `moves` (`|b − a|`, rad or m), into `sums`: the checker's speeds
    /// of them, the same sums in the same order, all bodies and pairs a joint at a time.
    pub(super) fn motion_bounds(&self, moves: &[f64], sums: &mut Vec<f64>) {
        let k = self.count();
        sums.clear();
        sums.resize(k, 0.0);
        for (row, &d) in self.reach.chunks_exact(k.max(1)).zip(moves) {
            for (sum, &r) in sums.iter_mut().zip(row) {
                *sum += r * d;
            }
        }
    }

    /// Slots of [`LaneChecks::measure`]'s `nearest`.
    pub(super) fn nearest_len(&self) -> usize {
        self.world.iter().map(Environment::len).sum::<usize>() + self.pairs.len()
    }

    /// Every candidate ([`Candidates::all`]).
    pub(super) fn all_candidates(&self) -> &Candidates {
        &self.all
    }
}

/// The gap (m) between spheres about `a` and `b` whose radii sum to `radii`, per lane.
#[inline(always)]
fn gap<L: Lane>(a: &[L; 3], b: &[L; 3], radii: f32) -> L {
    let (x, y, z) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    (x * x + y * y + z * z).sqrt() - L::splat(radii)
}
