//! Joint-space planners behind one trait: RRT-Connect (Kuffner & LaValle 2000) with
//! shortcutting, the default; and Informed RRT* (Gammell et al. 2014), which keeps improving
//! the path RRT-Connect first found for as long as it is given.

use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::checker::Checker;
use crate::joint_space::{dist, sample_into};
use crate::{Error, Result};

mod informed;
mod smooth;
mod tree;

pub use informed::InformedRrtStar;
use tree::{extend, Domain, Grow, Tree};

/// Longest time limit of one plan, s.
pub const MAX_TIME_LIMIT: f64 = 600.0;

/// Most [`PlanOptions::shortcuts`] attempts.
pub const MAX_SHORTCUTS: usize = 100_000;

/// Most [`PlanOptions::smoothing`] rounds.
pub const MAX_SMOOTHING: usize = 100;

/// Largest [`PlanOptions::shortcut_min_gain`], rad.
pub const MAX_MIN_GAIN: f64 = 100.0;

/// Options of one plan.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOptions {
    /// Give up after this long (shortcutting included), in (0, [`MAX_TIME_LIMIT`]] s. By
    /// default 5 s, MoveIt's default allowed planning time. Wall-clock time: RRT-Connect's path
    /// depends on the seed alone when it is found within the limit, so the limit is set well
    /// above the time problems take (the LoCoBot-Lite's stow behind a tilted camera takes
    /// 0.18 s in a release build and 0.52 s in a test build; at 1 s a loaded machine ran out).
    pub time_limit: Duration,
    /// Seed of the sampler: the same seed, problem and scene give the same path.
    pub seed: u64,
    /// Longest joint-space step of a tree extension, rad; `None`: a fifth of the diagonal of
    /// the joint limits' box (OMPL's default). In (0.001, 10] rad. The API and `ferrobot bench plan` give the
    /// arm's `planning_range` (`[arm]` of its configuration) where it has one.
    pub range: Option<f64>,
    /// Shortcut attempts after a path is found (0: none), at most [`MAX_SHORTCUTS`].
    pub shortcuts: usize,
    /// Rounds of smoothing after shortcutting (0: none), at most [`MAX_SMOOTHING`]: corner
    /// cutting and the greedy pass, as VAMP simplifies (`smooth.rs`).
    pub smoothing: usize,
    /// A shortcut is checked only when it would shorten the path by at least this much, rad:
    /// once the path is nearly straight, most attempts would save little and each costs an
    /// edge check. At 0.01 rad the benchmark's sets took 14 % (LoCoBot) to 25 % (Sawyer's
    /// shelf) fewer instructions for paths 0.1–0.25 % longer on average (`BENCHMARKS.md`).
    /// In [0, [`MAX_MIN_GAIN`]] rad.
    pub shortcut_min_gain: f64,
    /// Informed RRT*: time spent improving the first path (within the time limit), at most
    /// [`MAX_TIME_LIMIT`] s.
    pub improve_for: Duration,
    /// Dynamic domains for RRT-Connect's samples (Yershova et al. 2005, on by default as in
    /// VAMP): a node whose extension was trapped keeps a domain, and a sample farther from
    /// its nearest node than that node's domain is drawn again without a check (`Domain`).
    pub dynamic_domain: bool,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            time_limit: Duration::from_secs(5),
            seed: 1,
            range: None,
            shortcuts: 60,
            smoothing: 0,
            shortcut_min_gain: 0.01,
            improve_for: Duration::from_millis(100),
            dynamic_domain: true,
        }
    }
}

/// The diagonal of `checker`'s joint limits' box, rad.
fn diagonal(checker: &Checker) -> f64 {
    checker
        .model()
        .limits()
        .iter()
        .map(|(lo, hi)| (hi - lo).powi(2))
        .sum::<f64>()
        .sqrt()
}

impl PlanOptions {
    /// The extension step for `checker`'s joint limits, rad.
    fn range_for(&self, checker: &Checker) -> f64 {
        self.range.unwrap_or_else(|| 0.2 * diagonal(checker))
    }

    fn validate(&self) -> Result<()> {
        let t = self.time_limit.as_secs_f64();
        let range = self.range.unwrap_or(1.0);
        if !(t > 0.0 && t <= MAX_TIME_LIMIT && range > 1e-3 && range <= 10.0) {
            return Err(Error::Invalid {
                what: "plan options".into(),
                why: format!(
                    "time limit {t} s must be in (0, {MAX_TIME_LIMIT}] and range {} rad in (0.001, 10]",
                    range
                ),
            });
        }
        if !(0.0..=MAX_MIN_GAIN).contains(&self.shortcut_min_gain) {
            return Err(Error::Invalid {
                what: "plan options".into(),
                why: format!(
                    "shortcut_min_gain {} rad must be in [0, {MAX_MIN_GAIN}]",
                    self.shortcut_min_gain
                ),
            });
        }
        if self.improve_for.as_secs_f64() > MAX_TIME_LIMIT {
            return Err(Error::Invalid {
                what: "plan options".into(),
                why: format!(
                    "improve_for {} s must be at most {MAX_TIME_LIMIT} s",
                    self.improve_for.as_secs_f64()
                ),
            });
        }
        if self.smoothing > MAX_SMOOTHING {
            return Err(Error::Invalid {
                what: "plan options".into(),
                why: format!(
                    "{} smoothing rounds, more than {MAX_SMOOTHING}",
                    self.smoothing
                ),
            });
        }
        if self.shortcuts > MAX_SHORTCUTS {
            return Err(Error::Invalid {
                what: "plan options".into(),
                why: format!(
                    "{} shortcut attempts, more than {MAX_SHORTCUTS}",
                    self.shortcuts
                ),
            });
        }
        Ok(())
    }
}

/// A collision-free joint-space path.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Waypoints from start to goal, rad; consecutive ones joined by free straight edges.
    pub path: Vec<Vec<f64>>,
    /// Time spent, planning and shortcutting.
    pub time: Duration,
    /// Waypoints before shortcutting.
    pub raw_waypoints: usize,
}

impl Plan {
    /// Joint-space length (sum of Euclidean edge lengths), rad.
    pub fn length(&self) -> f64 {
        path_length(&self.path)
    }
}

/// Sum of Euclidean edge lengths of a joint-space path, rad.
pub fn path_length(path: &[Vec<f64>]) -> f64 {
    path.windows(2).map(|w| dist(&w[0], &w[1])).sum()
}

/// A joint-space planner.
pub trait Planner: Send + Sync {
    /// Its name, as `--planner` takes it.
    fn name(&self) -> &'static str;

    /// A free path from `start` to `goal` (rad) for `checker`'s model in its scene.
    fn plan(
        &self,
        checker: &Checker,
        start: &[f64],
        goal: &[f64],
        opts: &PlanOptions,
    ) -> Result<Plan>;
}

/// The planners by name.
pub const PLANNERS: [&str; 2] = ["rrt-connect", "informed-rrt-star"];

/// A planner by name ([`PLANNERS`]).
pub fn by_name(name: &str) -> Option<Box<dyn Planner>> {
    match name {
        "rrt-connect" => Some(Box::new(RrtConnect)),
        "informed-rrt-star" => Some(Box::new(InformedRrtStar)),
        _ => None,
    }
}

/// Checks start and goal: joint counts, limits, collisions.
fn check_ends(checker: &Checker, start: &[f64], goal: &[f64]) -> Result<()> {
    let dof = checker.model().dof();
    for (what, q) in [("start", start), ("goal", goal)] {
        if q.len() != dof {
            return Err(Error::Invalid {
                what: what.into(),
                why: format!("{} joint values for {dof} joints", q.len()),
            });
        }
        if !checker.within_limits(q) {
            return Err(Error::Invalid {
                what: what.into(),
                why: format!("{q:?} is not finite or not within the joint limits"),
            });
        }
    }
    if let Some(c) = checker.contact(start) {
        return Err(Error::StartInCollision { a: c.a, b: c.b });
    }
    if let Some(c) = checker.contact(goal) {
        return Err(Error::GoalInCollision { a: c.a, b: c.b });
    }
    Ok(())
}

/// RRT-Connect: two trees, one from each end, grown toward random samples and toward each
/// other; then shortcutting.
#[derive(Debug, Clone, Copy, Default)]
pub struct RrtConnect;

impl RrtConnect {
    /// The raw path (not shortcut) and the sampler, or a timeout.
    fn search(
        checker: &Checker,
        start: &[f64],
        goal: &[f64],
        opts: &PlanOptions,
        rng: &mut ChaCha8Rng,
        t0: Instant,
    ) -> Result<Vec<Vec<f64>>> {
        if checker.motion_free(start, goal) {
            return Ok(vec![start.to_vec(), goal.to_vec()]);
        }
        let limits = checker.model().limits().to_vec();
        let range = opts.range_for(checker);
        let mut a = Tree::new(start);
        let mut b = Tree::new(goal);
        let mut a_is_start = true;
        let domain = opts.dynamic_domain.then(|| Domain::for_checker(checker));
        let mut target = Vec::with_capacity(limits.len());
        // Draws refused outside a domain since the clock was read: most rounds are only a
        // draw and a nearest node, and the clock is read after an edge or 16 such rounds.
        let mut refused = 0usize;
        loop {
            if refused.is_multiple_of(16) && t0.elapsed() > opts.time_limit {
                return Err(Error::Timeout {
                    seconds: opts.time_limit.as_secs_f64(),
                });
            }
            sample_into(rng, &limits, &mut target);
            let grow = extend(checker, &mut a, &target, range, domain.as_ref());
            refused = match grow {
                Grow::Outside => refused + 1,
                _ => 0,
            };
            let new = match grow {
                // Drawn again, for the same tree.
                Grow::Outside => continue,
                Grow::Trapped => {
                    smaller_first(&mut a, &mut b, &mut a_is_start);
                    continue;
                }
                Grow::Reached(i) | Grow::Advanced(i) => i,
            };
            let q = a.node(new).to_vec();
            // Connect the other tree to the new node, step after step.
            loop {
                match extend(checker, &mut b, &q, range, None) {
                    Grow::Reached(j) => {
                        let (mut from_a, from_b) = (a.branch(new), b.branch(j));
                        let mut path = Vec::with_capacity(from_a.len() + from_b.len());
                        // The meeting configuration is in both branches: keep one.
                        from_a.pop();
                        if a_is_start {
                            path.extend(from_a);
                            path.extend(from_b.into_iter().rev());
                        } else {
                            path.extend(from_b);
                            path.extend(from_a.into_iter().rev());
                        }
                        return Ok(path);
                    }
                    Grow::Advanced(_) => {
                        if t0.elapsed() > opts.time_limit {
                            break;
                        }
                    }
                    Grow::Trapped | Grow::Outside => break,
                }
            }
            smaller_first(&mut a, &mut b, &mut a_is_start);
        }
    }
}

/// Makes `a` the tree that grows next: the smaller one (on a tie, the one that did not grow
/// last), LaValle's balanced bidirectional search (*Planning Algorithms*, §5.5: "new
/// exploration is always performed for the smaller tree", by its number of vertices).
/// Plain alternation let one tree grow far larger where the other was mostly trapped: balanced,
/// four sets of the LoCoBot's took 17–25 % fewer instructions, Sawyer's shelf 22 % and its
/// clutter 74 % (its hardest problem's 1.5 s became 62 ms), for paths as long (BENCHMARKS).
fn smaller_first(a: &mut Tree, b: &mut Tree, a_is_start: &mut bool) {
    if b.len() <= a.len() {
        std::mem::swap(a, b);
        *a_is_start = !*a_is_start;
    }
}

impl RrtConnect {
    /// The start of every plan from RRT-Connect: `opts` validated and the ends checked, the
    /// generator seeded with `opts.seed`, the search's path (its waypoint count) shortcut;
    /// the generator is returned for what comes after.
    fn first_path(
        checker: &Checker,
        start: &[f64],
        goal: &[f64],
        opts: &PlanOptions,
        t0: Instant,
    ) -> Result<(Vec<Vec<f64>>, usize, ChaCha8Rng)> {
        opts.validate()?;
        check_ends(checker, start, goal)?;
        let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
        let raw = Self::search(checker, start, goal, opts, &mut rng, t0)?;
        let raw_waypoints = raw.len();
        let path = shortcut(checker, raw, opts, &mut rng, t0);
        Ok((path, raw_waypoints, rng))
    }
}

impl Planner for RrtConnect {
    fn name(&self) -> &'static str {
        "rrt-connect"
    }

    fn plan(
        &self,
        checker: &Checker,
        start: &[f64],
        goal: &[f64],
        opts: &PlanOptions,
    ) -> Result<Plan> {
        let t0 = Instant::now();
        let (path, raw_waypoints, _) = Self::first_path(checker, start, goal, opts, t0)?;
        Ok(Plan {
            path,
            time: t0.elapsed(),
            raw_waypoints,
        })
    }
}

/// The configuration at arc length `s` (rad) along `path`, and the edge it is on.
fn at_length(path: &[Vec<f64>], mut s: f64) -> (Vec<f64>, usize) {
    for i in 0..path.len().saturating_sub(1) {
        let l = dist(&path[i], &path[i + 1]);
        if s <= l || i + 2 == path.len() {
            let f = if l > 0.0 {
                (s / l).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q = path[i]
                .iter()
                .zip(&path[i + 1])
                .map(|(a, b)| a + (b - a) * f)
                .collect();
            return (q, i);
        }
        s -= l;
    }
    (path[0].clone(), 0)
}

/// Shortcutting: [`PlanOptions::shortcuts`] times, join two random points of the path by a
/// straight edge when it is free and shortens the path by at least
/// [`PlanOptions::shortcut_min_gain`]; then, from each waypoint kept, go straight to the
/// farthest later one it sees. Stops at the time limit (counted from `t0`).
pub fn shortcut(
    checker: &Checker,
    mut path: Vec<Vec<f64>>,
    opts: &PlanOptions,
    rng: &mut ChaCha8Rng,
    t0: Instant,
) -> Vec<Vec<f64>> {
    let limit = opts.time_limit;
    for _ in 0..opts.shortcuts {
        if path.len() < 3 || t0.elapsed() > limit {
            break;
        }
        let total = path_length(&path);
        let mut s1 = rng.random_range(0.0..total);
        let mut s2 = rng.random_range(0.0..total);
        if s1 > s2 {
            std::mem::swap(&mut s1, &mut s2);
        }
        let (p1, i1) = at_length(&path, s1);
        let (p2, i2) = at_length(&path, s2);
        // The path from p1 to p2 is s2 − s1 long; the edge replacing it, their distance.
        if i1 == i2 || (s2 - s1) - dist(&p1, &p2) < opts.shortcut_min_gain {
            continue;
        }
        if !checker.motion_free(&p1, &p2) {
            continue;
        }
        let mut next = Vec::with_capacity(path.len());
        next.extend_from_slice(&path[..=i1]);
        next.push(p1);
        next.push(p2);
        next.extend_from_slice(&path[i2 + 1..]);
        next.dedup_by(|a, b| dist(a, b) < 1e-9);
        if path_length(&next) < total - 1e-9 {
            path = next;
        }
    }
    let path = smooth::greedy(checker, path, t0, limit);
    smooth::smooth(checker, path, opts.smoothing, t0, limit)
}

/// How many waypoints ahead shortcutting's last pass looks from each waypoint it keeps. The
/// farthest one seen first: an edge that collides is mostly refused after a few states, while
/// one proven free costs its whole walk, and dropping one waypoint at a time proved every
/// intermediate edge (1.1–1.4 % more instructions on four LoCoBot sets, 3–5 % on Sawyer's, for
/// the same paths; `BENCHMARKS.md`). Shortcut paths have a handful of waypoints; the bound
/// keeps the pass linear on a long raw path (no shortcut attempts).
const LOOK_AHEAD: usize = 12;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smaller_tree_grows_next() {
        let tree = |n: usize| {
            let mut t = Tree::new(&[0.0]);
            for i in 1..n {
                t.add(&[i as f64], i - 1);
            }
            t
        };
        // The tree that just grew is still the smaller: it grows again, ends unchanged.
        let (mut a, mut b, mut a_is_start) = (tree(2), tree(5), true);
        smaller_first(&mut a, &mut b, &mut a_is_start);
        assert_eq!((a.len(), b.len(), a_is_start), (2, 5, true));
        // It is now the larger: the other grows next.
        let (mut a, mut b, mut a_is_start) = (tree(6), tree(5), true);
        smaller_first(&mut a, &mut b, &mut a_is_start);
        assert_eq!((a.len(), b.len(), a_is_start), (5, 6, false));
        // A tie: the other one.
        let (mut a, mut b, mut a_is_start) = (tree(5), tree(5), false);
        smaller_first(&mut a, &mut b, &mut a_is_start);
        assert!(a_is_start);
    }
}
