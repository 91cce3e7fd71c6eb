//! Informed RRT* (Gammell et al. 2014): RRT-Connect's first path, improved by a single tree
//! grown with rewiring where a shorter path can pass, for as long as it is given.

use std::time::{Duration, Instant};

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::tree::Tree;
use super::{path_length, shortcut, Plan, PlanOptions, Planner, RrtConnect};
use crate::checker::Checker;
use crate::joint_space::dist;
use crate::Result;

/// Informed RRT*: RRT-Connect's path first, then a single tree from the start grown with
/// rewiring, sampling only where a shorter path can pass (the prolate hyperspheroid whose
/// foci are start and goal), for [`PlanOptions::improve_for`]; then shortcutting.
#[derive(Debug, Clone, Copy, Default)]
pub struct InformedRrtStar;

impl Planner for InformedRrtStar {
    fn name(&self) -> &'static str {
        "informed-rrt-star"
    }

    fn plan(
        &self,
        checker: &Checker,
        start: &[f64],
        goal: &[f64],
        opts: &PlanOptions,
    ) -> Result<Plan> {
        let t0 = Instant::now();
        let (first, raw_waypoints, mut rng) =
            RrtConnect::first_path(checker, start, goal, opts, t0)?;
        let deadline = t0
            .elapsed()
            .saturating_add(opts.improve_for)
            .min(opts.time_limit);
        let best = improve(checker, start, goal, first, opts, &mut rng, t0, deadline);
        let path = shortcut(checker, best, opts, &mut rng, t0);
        Ok(Plan {
            path,
            time: t0.elapsed(),
            raw_waypoints,
        })
    }
}

/// A sample of the prolate hyperspheroid of points `x` with |x − a| + |x − b| ≤ `c`.
fn informed_sample(rng: &mut ChaCha8Rng, a: &[f64], b: &[f64], c: f64) -> Vec<f64> {
    let n = a.len();
    let cmin = dist(a, b);
    // A uniform point of the unit ball.
    let mut x: Vec<f64> = loop {
        let v: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..=1.0)).collect();
        if v.iter().map(|x| x * x).sum::<f64>() <= 1.0 {
            break v;
        }
    };
    let r1 = c / 2.0;
    let r2 = ((c * c - cmin * cmin).max(0.0)).sqrt() / 2.0;
    x[0] *= r1;
    for v in &mut x[1..] {
        *v *= r2;
    }
    // Householder reflection taking e1 onto the direction a → b.
    let mut u: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(p, q)| if cmin > 0.0 { (q - p) / cmin } else { 0.0 })
        .collect();
    if cmin > 0.0 {
        u[0] -= 1.0;
        let un: f64 = u.iter().map(|v| v * v).sum();
        if un > 1e-18 {
            let d: f64 = u.iter().zip(&x).map(|(p, q)| p * q).sum();
            for (xi, ui) in x.iter_mut().zip(&u) {
                *xi -= 2.0 * d / un * ui;
            }
        }
    }
    x.iter()
        .zip(a.iter().zip(b))
        .map(|(v, (p, q))| v + (p + q) / 2.0)
        .collect()
}

/// Informed RRT*'s improvement of the `first` path from `start` to `goal`, until `deadline`
/// (counted from `t0`): the shortest path found.
#[allow(clippy::too_many_arguments)]
fn improve(
    checker: &Checker,
    start: &[f64],
    goal: &[f64],
    first: Vec<Vec<f64>>,
    opts: &PlanOptions,
    rng: &mut ChaCha8Rng,
    t0: Instant,
    deadline: Duration,
) -> Vec<Vec<f64>> {
    let limits = checker.model().limits().to_vec();
    let range = opts.range_for(checker);
    let dof = start.len() as f64;
    let mut best_cost = path_length(&first);
    let mut best = first.clone();
    let mut star = Star::from_path(start, &first);
    while t0.elapsed() < deadline {
        let Some(target) = informed_target(rng, (start, goal), best_cost, &limits, t0, deadline)
        else {
            return best;
        };
        let tree = &star.tree;
        let near = tree.nearest(&target);
        let d = dist(tree.node(near), &target);
        let q: Vec<f64> = if d <= range {
            target
        } else {
            let s = range / d;
            tree.node(near)
                .iter()
                .zip(&target)
                .map(|(a, b)| a + (b - a) * s)
                .collect()
        };
        // Neighbours within the RRT* radius.
        let n = tree.len() as f64;
        let radius = (range * 2.0 * ((n.ln() / n).powf(1.0 / dof))).max(range * 0.5);
        let neighbours: Vec<usize> = (0..tree.len())
            .filter(|&i| dist(tree.node(i), &q) <= radius)
            .collect();
        let Some((parent, c_new)) = star.cheapest_parent(checker, &q, &neighbours, goal, best_cost)
        else {
            continue;
        };
        let new = star.tree.add(&q, parent);
        star.cost.push(c_new);
        star.rewire(checker, &q, new, c_new, &neighbours);
        // Reach the goal from the new node.
        let to_goal = c_new + dist(&q, goal);
        if to_goal + 1e-9 < best_cost && checker.motion_free(&q, goal) {
            let g = star.tree.add(goal, new);
            star.cost.push(to_goal);
            star.goal_node = Some(g);
        }
        if let Some(g) = star.goal_node {
            if star.cost[g] + 1e-9 < best_cost {
                best_cost = star.cost[g];
                best = star.tree.branch(g);
            }
        }
    }
    best
}

/// A sample of the informed set of paths shorter than `best_cost` between `ends`, within
/// `limits`; `None` once `deadline` (from `t0`) has passed.
fn informed_target(
    rng: &mut ChaCha8Rng,
    (start, goal): (&[f64], &[f64]),
    best_cost: f64,
    limits: &[(f64, f64)],
    t0: Instant,
    deadline: Duration,
) -> Option<Vec<f64>> {
    loop {
        let s = informed_sample(rng, start, goal, best_cost);
        if s.iter().zip(limits).all(|(v, (lo, hi))| v >= lo && v <= hi) {
            return Some(s);
        }
        if t0.elapsed() >= deadline {
            return None;
        }
    }
}

/// Informed RRT*'s tree: each node's cost from the start (rad) and the node at the goal.
struct Star {
    tree: Tree,
    cost: Vec<f64>,
    goal_node: Option<usize>,
}

impl Star {
    /// The tree as the chain of `first`'s waypoints from `start`, so it only gets better.
    fn from_path(start: &[f64], first: &[Vec<f64>]) -> Self {
        let mut tree = Tree::new(start);
        let mut cost = vec![0.0];
        let mut goal_node = None;
        for q in first.iter().skip(1) {
            let p = tree.len() - 1;
            let c = cost[p] + dist(tree.node(p), q);
            let i = tree.add(q, p);
            cost.push(c);
            goal_node = Some(i);
        }
        Star {
            tree,
            cost,
            goal_node,
        }
    }

    /// The cheapest of `neighbours` with a free edge to `q` through which a path to `goal`
    /// may still beat `best_cost`, and the cost of `q` through it.
    fn cheapest_parent(
        &self,
        checker: &Checker,
        q: &[f64],
        neighbours: &[usize],
        goal: &[f64],
        best_cost: f64,
    ) -> Option<(usize, f64)> {
        let mut order: Vec<(f64, usize)> = neighbours
            .iter()
            .map(|&i| (self.cost[i] + dist(self.tree.node(i), q), i))
            .collect();
        order.sort_by(|x, y| x.0.total_cmp(&y.0));
        for (c, i) in order {
            if c + dist(q, goal) >= best_cost {
                break;
            }
            if checker.motion_free(self.tree.node(i), q) {
                return Some((i, c));
            }
        }
        None
    }

    /// Rewires `neighbours` through node `new` (at `q`, of cost `c_new`) where that is
    /// cheaper and free, lowering the cost of their subtrees.
    fn rewire(
        &mut self,
        checker: &Checker,
        q: &[f64],
        new: usize,
        c_new: f64,
        neighbours: &[usize],
    ) {
        let (tree, cost) = (&mut self.tree, &mut self.cost);
        for &i in neighbours {
            let c = c_new + dist(q, tree.node(i));
            if c + 1e-12 < cost[i] && checker.motion_free(q, tree.node(i)) {
                let delta = cost[i] - c;
                tree.parent[i] = new;
                // Lower the cost of the subtree.
                let mut stack = vec![i];
                while let Some(k) = stack.pop() {
                    cost[k] -= delta;
                    stack.extend((0..tree.len()).filter(|&m| tree.parent[m] == k));
                }
            }
        }
    }
}
