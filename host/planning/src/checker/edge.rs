//! Proving an edge (a straight joint-space motion) free by conservative advancement: each
//! body's speed along the edge (m of point motion per unit of the edge parameter), what may
//! come near it on the edge, the rake of first states, and steps proven by the clearances at
//! their two ends.

use std::sync::atomic::Ordering;

use super::{Checker, Contact, Engine, Speeds};
use crate::spheres::Sphere;

/// Ends an edge's [`Near`] limits when dropped.
struct EdgeGuard<'a>(&'a Checker);

impl Drop for EdgeGuard<'_> {
    fn drop(&mut self) {
        self.0.scratch.borrow_mut().near.on = false;
    }
}

impl Checker {
    /// [`Checker::measure_with`] at the state `t` of the way from `a` to `b` (written into `q`),
    /// which is also the edge parameter its [`Near`] limits, if any, are read at.
    fn measure_at(
        &self,
        q: &mut [f64],
        (a, b): (&[f64], &[f64]),
        t: f64,
        speed: &Speeds,
        cap: f64,
        exact_below: f64,
    ) -> std::result::Result<f64, Contact> {
        for ((v, x), y) in q.iter_mut().zip(a).zip(b) {
            *v = x + (y - x) * t;
        }
        self.scratch.borrow_mut().near.t = t;
        self.measure_with(q, Some(speed), cap, exact_below)
    }

    /// Whether the straight joint-space edge from `a` to `b` is free, proven by the checker's
    /// [`Checker::engine`]: the planners' edge check. Every edge a planner returns passed it,
    /// so no contact hides anywhere on a returned path.
    pub fn motion_free(&self, a: &[f64], b: &[f64]) -> bool {
        match (&self.lanes, self.engine) {
            (Some(checks), Engine::Lanes) => self.motion_free_in_lanes(checks, a, b),
            (Some(checks), Engine::Baseline) => self.motion_free_in_baseline_lanes(checks, a, b),
            (Some(checks), Engine::Scalar) => self.motion_free_in_lanes_scalar(checks, a, b),
            _ => self.advanced(a, b),
        }
    }

    /// Whether the edge from `a` to `b` is free, proven by conservative advancement (see the
    /// module's documentation) with steps of `resolution` of robot-point motion where the
    /// clearance is smaller.
    pub fn advanced(&self, a: &[f64], b: &[f64]) -> bool {
        self.prove(a, b, self.opts.resolution, self.opts.resolution * 0.5)
    }

    /// Whether the straight joint-space edge from `a` to `b` is free, proven as
    /// [`Checker::motion_free`] is but with steps of `min_step` near contact and exact
    /// distances wherever the spheres are within `max_step / 2` (tighter, slower).
    pub fn motion_proven(&self, a: &[f64], b: &[f64]) -> bool {
        self.prove(
            a,
            b,
            self.opts.min_step,
            (self.opts.max_step * 0.5).max(self.opts.min_step),
        )
    }

    /// Whether no state on the edge from `a` to `b` is in contact, sampled: states at most
    /// `step` (m) of robot-point motion apart are tested for contact alone (states are skipped
    /// only where the spheres prove room). Not a proof between samples: an independent
    /// re-check of paths (at 1 mm, say), not an edge check for planning.
    pub fn motion_sampled(&self, a: &[f64], b: &[f64], step: f64) -> bool {
        if !self.within_limits(a) || !self.within_limits(b) || step.is_nan() || step <= 0.0 {
            return false;
        }
        self.counters.edges.fetch_add(1, Ordering::Relaxed);
        let total = self.motion_bound(a, b);
        let speed = self.speeds(a, b);
        let _near = self.begin_edge(a, &speed);
        let mut q = a.to_vec();
        let mut t = 0.0f64;
        let (cap, floor) = if total > 0.0 {
            (self.opts.max_step / total, step / total)
        } else {
            (1.0, 1.0)
        };
        loop {
            let Ok(dt) = self.measure_at(&mut q, (a, b), t, &speed, cap, 0.0) else {
                return false;
            };
            if t >= 1.0 {
                return true;
            }
            t = (t + dt.max(floor)).min(1.0);
        }
    }

    /// Limits the checks of the states that follow, until the guard drops, to what may come
    /// near some body on the edge that starts at `a` and moves each body's points at most
    /// `speed` (m) along it ([`Near`]).
    fn begin_edge(&self, a: &[f64], speed: &Speeds) -> EdgeGuard<'_> {
        let mut s = self.scratch.borrow_mut();
        let s = &mut *s;
        self.model.link_poses_into(a, &mut s.values, &mut s.poses);
        let step = self.opts.max_step;
        s.bounds.clear();
        s.bounds.extend(self.bodies.iter().map(|b| Sphere {
            centre: s.poses[b.link] * b.bound.centre,
            radius: b.bound.radius,
        }));
        s.near.obstacles.resize_with(self.bodies.len(), Vec::new);
        for (bi, list) in s.near.obstacles.iter_mut().enumerate() {
            list.clear();
            let bound = &s.bounds[bi];
            let c = bound.centre;
            self.all_boxes[bi].gaps(
                [c.x as f32, c.y as f32, c.z as f32],
                bound.radius as f32,
                &mut s.gaps,
            );
            let within = speed.body[bi] + step + 1e-6;
            list.extend(
                self.all_of[bi]
                    .iter()
                    .zip(&s.gaps)
                    .filter(|&(&k, &g)| f64::from(g) - self.padding_of(k) < within)
                    .map(|(&k, _)| k),
            );
        }
        s.near.pairs.clear();
        s.near.pairs.extend((0..self.pairs.len()).filter(|&p| {
            let (i, j) = self.pairs[p];
            let (bi, bj) = (&s.bounds[i], &s.bounds[j]);
            let gap = (bi.centre - bj.centre).norm() - bi.radius - bj.radius;
            gap < speed.pair[p] + 2.0 * step + 1e-6
        }));
        s.near.obstacle_far.resize_with(self.bodies.len(), Vec::new);
        for (far, list) in s.near.obstacle_far.iter_mut().zip(&s.near.obstacles) {
            far.clear();
            far.resize(list.len(), (0.0, -1.0));
        }
        s.near.pair_far.clear();
        s.near.pair_far.resize(s.near.pairs.len(), (0.0, -1.0));
        // Each moving body's bound against each of its obstacles, each pair's two bounds.
        let checks = self.all_of.iter().map(Vec::len).sum::<usize>() + self.pairs.len();
        self.counters
            .sphere_checks
            .fetch_add(checks as u64, Ordering::Relaxed);
        s.near.t = 0.0;
        s.near.on = true;
        EdgeGuard(self)
    }

    /// Each body's largest point motion (m) over the edge from `a` to `b`, and each moving
    /// pair's largest relative motion.
    pub(super) fn speeds(&self, a: &[f64], b: &[f64]) -> Speeds {
        let along = |r: &Vec<f64>| -> f64 {
            r.iter()
                .zip(a.iter().zip(b))
                .map(|(r, (x, y))| r * (x - y).abs())
                .sum()
        };
        Speeds {
            body: self.body_reach.iter().map(along).collect(),
            pair: self.pair_reach.iter().map(along).collect(),
        }
    }

    /// Whether the edge from `a` to `b` is free ([`Checker::advance`]).
    fn prove(&self, a: &[f64], b: &[f64], min_step: f64, exact_below: f64) -> bool {
        if !self.within_limits(a) || !self.within_limits(b) {
            return false;
        }
        self.counters.edges.fetch_add(1, Ordering::Relaxed);
        let total = self.motion_bound(a, b);
        self.advance(a, b, total, min_step, exact_below)
    }

    /// Conservative advancement from `a` to `b` (`total` m of motion, within limits): first
    /// the clearances at the [`rake`]'s states (a contact there refuses the edge, as any
    /// would: an edge that collides is mostly refused after a few states rather than after a
    /// walk up to its contact, which took about 70 % of the LoCoBot's states), then steps
    /// proven by the clearances at both ends, tried at three times the clearance or `min_step`
    /// (m of the fastest point) and halved; exact distances where the spheres' bound is below
    /// `exact_below` (m).
    fn advance(&self, a: &[f64], b: &[f64], total: f64, min_step: f64, exact_below: f64) -> bool {
        let speed = self.speeds(a, b);
        let mut q = a.to_vec();
        let (cap, min_dt) = if total > 0.0 {
            (self.opts.max_step / total, min_step / total)
        } else {
            (1.0, 1.0)
        };
        // How far along the edge (in t) nothing can be reached from `t`, or `None` at a
        // contact.
        let mut clearance = |t: f64| {
            self.measure_at(&mut q, (a, b), t, &speed, cap, exact_below)
                .ok()
        };
        // States measured ahead (the nearest on top once sorted): the rake's next `n` into
        // `ahead`, false at a contact.
        let mut ahead: Vec<(f64, f64)> = Vec::new();
        let mut states = rake(total, self.rake_spacing);
        let mut measure = |n: usize, ahead: &mut Vec<(f64, f64)>| {
            for t in states.by_ref().take(n) {
                let Some(c) = clearance(t) else {
                    return false;
                };
                ahead.push((t, c));
            }
            true
        };
        // The rake's first states (its end, middle and quarters) before the edge's limits are
        // set up (they cost more than a state): most edges that collide are in contact there.
        if !measure(BEFORE_LIMITS, &mut ahead) {
            return false;
        }
        let _near = self.begin_edge(a, &speed);
        if !measure(usize::MAX, &mut ahead) {
            return false;
        }
        ahead.sort_by(|x, y| y.0.total_cmp(&x.0));
        let Some(clear) = clearance(0.0) else {
            return false;
        };
        if total <= 0.0 {
            return true;
        }
        // About 8 µm of point motion with the default `min_step`.
        let smallest = self.opts.min_step / total / 128.0;
        walk(&mut clearance, ahead, clear, min_dt, smallest)
    }
}

/// The steps of conservative advancement from the edge's start (of clearance `clear`) to its
/// end, given `clearance` (how far along the edge, in its parameter, nothing can be reached
/// from a state, or `None` at a contact) and the states measured `ahead` (the nearest last):
/// whether every step is proven free, none shorter than `2 · smallest` needed.
fn walk(
    clearance: &mut impl FnMut(f64) -> Option<f64>,
    mut ahead: Vec<(f64, f64)>,
    mut clear: f64,
    min_dt: f64,
    smallest: f64,
) -> bool {
    // A step from `t` to `u` is free when the clearances at its ends add up to more than
    // its length: a point x into it is at least max(c − x, cᵤ − (u − t − x)) > 0 from
    // anything (for each body, as each clearance is the smallest over bodies). A step
    // that is not proven is halved, keeping its far end.
    let mut t = 0.0f64;
    while t < 1.0 {
        let (u, cu) = match ahead.last() {
            Some(&p) => p,
            None => {
                // Nothing measured ahead: guess that the clearance grows (a step of three
                // times it; two and four were slower), and at least `min_step` near
                // contact.
                let u = (t + (3.0 * clear).max(min_dt)).min(1.0);
                let Some(cu) = clearance(u) else {
                    return false;
                };
                ahead.push((u, cu));
                (u, cu)
            }
        };
        if clear + cu > u - t {
            ahead.pop();
            t = u;
            clear = cu;
            continue;
        }
        if u - t < 2.0 * smallest {
            return false;
        }
        let m = 0.5 * (t + u);
        let Some(cm) = clearance(m) else {
            return false;
        };
        ahead.push((m, cm));
    }
    true
}

/// How many of the [`rake`]'s states are measured before an edge's [`Near`] limits are set
/// up: 4 (end, middle, quarters) took 4.8 % fewer instructions than 1 on the LoCoBot's sets,
/// as many as the whole rake, and 0.3–0.9 % more on Sawyer's, where the whole rake cost 3 %
/// more (BENCHMARKS).
const BEFORE_LIMITS: usize = 4;

/// Spacing below which [`rake`] stops adding states, as a fraction of the arm's reach
/// ([`CollisionModel::span`]: the largest bound on a moving point's distance from a planned
/// joint's origin; m of the fastest point's motion), and at least [`CheckOptions::max_step`].
/// Obstacles and links scale with the arm: at a fixed 0.3 m, the LoCoBot (0.62 m of reach)
/// was fastest at 0.15–0.2 m and Sawyer (1.40 m) at 0.4–0.6 m, for the same paths; this
/// fraction falls on both plateaus (BENCHMARKS).
pub(super) const RAKE_SPACING_PER_REACH: f64 = 0.3;

/// The edge parameters of states spread over an edge of `total` m of motion, in the order
/// they are measured: its end, its middle, its quarters and so on while they are more than
/// `spacing` (m) apart.
fn rake(total: f64, spacing: f64) -> impl Iterator<Item = f64> {
    let levels = (0..16u32)
        .take_while(move |&l| total / f64::from(2u32 << l) > spacing)
        .count() as u32;
    std::iter::once(1.0).chain((0..levels).flat_map(|l| {
        let n = 2u32 << l;
        (1..n).step_by(2).map(move |k| f64::from(k) / f64::from(n))
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::CollisionModel;
    use crate::scene::PlanningScene;
    use crate::CheckOptions;
    use ferrobot_description::RobotConfig;
    use nalgebra::Isometry3;
    use rand::{Rng, SeedableRng};
    use std::sync::Arc;

    /// The rake's states: the end, then each level's odd multiples while they are more than
    /// the spacing apart.
    #[test]
    fn the_rake_spreads_states_coarse_to_fine() {
        let got = |total: f64| rake(total, 0.3).collect::<Vec<f64>>();
        assert_eq!(got(0.0), [1.0]);
        assert_eq!(got(0.5), [1.0]);
        assert_eq!(got(0.7), [1.0, 0.5]);
        assert_eq!(got(1.3), [1.0, 0.5, 0.25, 0.75]);
        assert_eq!(got(1e9).len(), 1 << 16);
        assert_eq!(rake(0.7, 0.1).count(), 4);
    }

    /// Over random edges of Sawyer (seven links that fold onto each other), no sphere centre
    /// of a body moves farther than the body's speed, and the distance between any two sphere
    /// centres of a moving pair changes by no more than the pair's speed: the bounds every
    /// step relies on.
    #[test]
    fn speeds_bound_every_point_motion() {
        let cfg = RobotConfig::bundled("sawyer").expect("sawyer");
        let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
        let c = Checker::new(
            model.clone(),
            &PlanningScene::new(),
            CheckOptions::default(),
        )
        .expect("checker");
        assert!(c.pairs.len() > 5);
        let limits = model.limits().to_vec();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let sample = |rng: &mut rand_chacha::ChaCha8Rng| crate::joint_space::sample(rng, &limits);
        let (mut tight_pair, mut tight_body) = (0.0f64, 0.0f64);
        for _ in 0..300 {
            let (a, b) = (sample(&mut rng), sample(&mut rng));
            let speed = c.speeds(&a, &b);
            let t = rng.random_range(0.0..1.0);
            let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect();
            let (pa, pq) = (model.link_poses(&a), model.link_poses(&q));
            for (bi, body) in c.bodies.iter().enumerate() {
                for s in &body.spheres {
                    let moved = (pq[body.link] * s.centre - pa[body.link] * s.centre).norm();
                    assert!(moved <= t * speed.body[bi] + 1e-9, "{}", body.name);
                    tight_body = tight_body.max(moved / (t * speed.body[bi]).max(1e-12));
                }
            }
            for (p, &(i, j)) in c.pairs.iter().enumerate() {
                let (li, lj) = (c.bodies[i].link, c.bodies[j].link);
                for si in &c.bodies[i].spheres {
                    for sj in &c.bodies[j].spheres {
                        let apart = |poses: &[Isometry3<f64>]| {
                            (poses[li] * si.centre - poses[lj] * sj.centre).norm()
                        };
                        let moved = (apart(&pq) - apart(&pa)).abs();
                        assert!(
                            moved <= t * speed.pair[p] + 1e-9,
                            "{} and {}: {moved} m, bound {}",
                            c.bodies[i].name,
                            c.bodies[j].name,
                            t * speed.pair[p]
                        );
                        tight_pair = tight_pair.max(moved / (t * speed.pair[p]).max(1e-12));
                    }
                }
            }
        }
        // Not vacuous: somewhere the motion comes within a factor of three of each bound.
        assert!(
            tight_body > 0.33 && tight_pair > 0.33,
            "{tight_body} {tight_pair}"
        );
    }
}
