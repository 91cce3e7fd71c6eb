//! Joint-space planners behind one trait: RRT-Connect (Kuffner & LaValle 2000) with
//! shortcutting, the default; and Informed RRT* (Gammell et al. 2014), which keeps improving
//! the path RRT-Connect first found for as long as it is given.

use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::checker::Checker;
use crate::{Error, Result};

/// Longest time limit of one plan, s.
pub const MAX_TIME_LIMIT: f64 = 600.0;

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
    /// Shortcut attempts after a path is found (0: none), at most 100,000.
    pub shortcuts: usize,
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
    /// its nearest node than that node's domain is drawn again without a check ([`Domain`]).
    pub dynamic_domain: bool,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            time_limit: Duration::from_secs(5),
            seed: 1,
            range: None,
            shortcuts: 60,
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
        if self.shortcuts > 100_000 {
            return Err(Error::Invalid {
                what: "plan options".into(),
                why: format!("{} shortcut attempts, more than 100000", self.shortcuts),
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

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
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

/// A tree of configurations.
struct Tree {
    q: Vec<Vec<f64>>,
    parent: Vec<usize>,
    /// Each node's dynamic domain, rad: infinite until an extension from it is trapped.
    domain: Vec<f64>,
}

impl Tree {
    fn new(root: &[f64]) -> Self {
        Tree {
            q: vec![root.to_vec()],
            parent: vec![usize::MAX],
            domain: vec![f64::INFINITY],
        }
    }

    fn nearest(&self, q: &[f64]) -> usize {
        let mut best = (f64::INFINITY, 0);
        for (i, n) in self.q.iter().enumerate() {
            let d: f64 = n.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum();
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }

    fn add(&mut self, q: Vec<f64>, parent: usize) -> usize {
        self.q.push(q);
        self.parent.push(parent);
        self.domain.push(f64::INFINITY);
        self.q.len() - 1
    }

    /// Configurations from the root to node `i`.
    fn branch(&self, mut i: usize) -> Vec<Vec<f64>> {
        let mut out = Vec::new();
        while i != usize::MAX {
            out.push(self.q[i].clone());
            i = self.parent[i];
        }
        out.reverse();
        out
    }
}

/// Outcome of growing a tree toward a configuration.
#[derive(Debug, PartialEq)]
enum Grow {
    Reached(usize),
    Advanced(usize),
    Trapped,
    /// The target lies outside its nearest node's [`Domain`]: nothing was checked.
    Outside,
}

/// Dynamic domains (Yershova, Jaillet, Siméon & LaValle, "Dynamic-Domain RRTs", ICRA 2005),
/// with VAMP's rules: the first trapped extension from a node gives it a domain of `radius`;
/// each later one shrinks it by the factor `1 − alpha`, down to `min`; each extension from it
/// that succeeds grows it by `1 + alpha`. Samples outside their nearest node's domain are
/// drawn again: nodes on an obstacle's boundary stop drawing the far samples whose
/// extensions would be trapped there again.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Domain {
    /// A node's first domain, rad.
    radius: f64,
    /// The smallest domain, rad.
    min: f64,
    /// Growth and shrinkage per extension.
    alpha: f64,
}

/// [`Domain::radius`] as a fraction of the joint box's diagonal (the LoCoBot's 1.76 rad,
/// Sawyer's 4.4 rad). On six problem sets (four of the LoCoBot's, Sawyer's shelf and clutter)
/// 0.25 took 12–33 % fewer instructions than no domains; 0.3 fewer on all six but less, 0.2
/// more on one set. A radius fixed in radians does not fit both arms: at VAMP's 4 rad the
/// LoCoBot gained nothing, at 1 rad Sawyer took 11–15× more (BENCHMARKS.md).
const DOMAIN_PER_DIAGONAL: f64 = 0.25;

impl Domain {
    /// Domains for `checker`'s joint limits: [`DOMAIN_PER_DIAGONAL`] of their box's diagonal,
    /// at least a quarter of that, VAMP's `alpha` (10⁻⁴).
    fn for_checker(checker: &Checker) -> Self {
        let radius = DOMAIN_PER_DIAGONAL * diagonal(checker);
        Domain {
            radius,
            min: radius / 4.0,
            alpha: 1e-4,
        }
    }

    /// A node's domain after an extension from it was trapped (`trapped`) or succeeded.
    fn after(&self, domain: f64, trapped: bool) -> f64 {
        match (trapped, domain.is_finite()) {
            (true, false) => self.radius,
            (true, true) => (domain * (1.0 - self.alpha)).max(self.min),
            (false, true) => domain * (1.0 + self.alpha),
            (false, false) => domain,
        }
    }
}

/// One step of at most `range` from the nearest node toward `target`; with `domain`, only
/// when `target` lies within that node's domain, which the outcome then updates.
fn extend(
    checker: &Checker,
    tree: &mut Tree,
    target: &[f64],
    range: f64,
    domain: Option<&Domain>,
) -> Grow {
    let near = tree.nearest(target);
    let from = &tree.q[near];
    let d = dist(from, target);
    if domain.is_some() && d > tree.domain[near] {
        return Grow::Outside;
    }
    let (q, reached) = if d <= range {
        (target.to_vec(), true)
    } else {
        let s = range / d;
        (
            from.iter()
                .zip(target)
                .map(|(a, b)| a + (b - a) * s)
                .collect(),
            false,
        )
    };
    let free = checker.motion_free(from, &q);
    if let Some(domain) = domain {
        tree.domain[near] = domain.after(tree.domain[near], !free);
    }
    if !free {
        return Grow::Trapped;
    }
    let i = tree.add(q, near);
    if reached {
        Grow::Reached(i)
    } else {
        Grow::Advanced(i)
    }
}

/// A configuration drawn uniformly within `limits` (rad).
pub(crate) fn sample(rng: &mut ChaCha8Rng, limits: &[(f64, f64)]) -> Vec<f64> {
    limits
        .iter()
        .map(|&(lo, hi)| rng.random_range(lo..=hi))
        .collect()
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
        loop {
            if t0.elapsed() > opts.time_limit {
                return Err(Error::Timeout {
                    seconds: opts.time_limit.as_secs_f64(),
                });
            }
            let target = sample(rng, &limits);
            let new = match extend(checker, &mut a, &target, range, domain.as_ref()) {
                // Drawn again, for the same tree.
                Grow::Outside => continue,
                Grow::Trapped => {
                    smaller_first(&mut a, &mut b, &mut a_is_start);
                    continue;
                }
                Grow::Reached(i) | Grow::Advanced(i) => i,
            };
            let q = a.q[new].clone();
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
    if b.q.len() <= a.q.len() {
        std::mem::swap(a, b);
        *a_is_start = !*a_is_start;
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
        opts.validate()?;
        check_ends(checker, start, goal)?;
        let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
        let raw = Self::search(checker, start, goal, opts, &mut rng, t0)?;
        let raw_waypoints = raw.len();
        let path = shortcut(checker, raw, opts, &mut rng, t0);
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
    // From each waypoint kept, the farthest later one it sees (within [`LOOK_AHEAD`]).
    let Some(first) = path.first() else {
        return path;
    };
    let mut out = Vec::with_capacity(path.len());
    out.push(first.clone());
    let mut i = 0;
    while i + 1 < path.len() {
        let mut j = (path.len() - 1).min(i + LOOK_AHEAD);
        while j > i + 1 && !(t0.elapsed() <= limit && checker.motion_free(&path[i], &path[j])) {
            j -= 1;
        }
        out.push(path[j].clone());
        i = j;
    }
    out
}

/// How many waypoints ahead shortcutting's last pass looks from each waypoint it keeps. The
/// farthest one seen first: an edge that collides is mostly refused after a few states, while
/// one proven free costs its whole walk, and dropping one waypoint at a time proved every
/// intermediate edge (1.1–1.4 % more instructions on four LoCoBot sets, 3–5 % on Sawyer's, for
/// the same paths; `BENCHMARKS.md`). Shortcut paths have a handful of waypoints; the bound
/// keeps the pass linear on a long raw path (no shortcut attempts).
const LOOK_AHEAD: usize = 12;

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
        opts.validate()?;
        check_ends(checker, start, goal)?;
        let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
        let first = RrtConnect::search(checker, start, goal, opts, &mut rng, t0)?;
        let raw_waypoints = first.len();
        let first = shortcut(checker, first, opts, &mut rng, t0);
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
    // The tree starts as the first path (a chain), so it only gets better.
    let mut tree = Tree::new(start);
    let mut cost = vec![0.0];
    let mut goal_node = None;
    for q in first.iter().skip(1) {
        let p = tree.q.len() - 1;
        let c = cost[p] + dist(&tree.q[p], q);
        let i = tree.add(q.clone(), p);
        cost.push(c);
        goal_node = Some(i);
    }
    while t0.elapsed() < deadline {
        let target = loop {
            let s = informed_sample(rng, start, goal, best_cost);
            if s.iter()
                .zip(&limits)
                .all(|(v, (lo, hi))| v >= lo && v <= hi)
            {
                break s;
            }
            if t0.elapsed() >= deadline {
                return best;
            }
        };
        let near = tree.nearest(&target);
        let d = dist(&tree.q[near], &target);
        let q: Vec<f64> = if d <= range {
            target
        } else {
            let s = range / d;
            tree.q[near]
                .iter()
                .zip(&target)
                .map(|(a, b)| a + (b - a) * s)
                .collect()
        };
        // Neighbours within the RRT* radius.
        let n = tree.q.len() as f64;
        let radius = (range * 2.0 * ((n.ln() / n).powf(1.0 / dof))).max(range * 0.5);
        let neighbours: Vec<usize> = (0..tree.q.len())
            .filter(|&i| dist(&tree.q[i], &q) <= radius)
            .collect();
        // Cheapest free parent.
        let mut parent = None;
        let mut c_new = f64::INFINITY;
        let mut order: Vec<(f64, usize)> = neighbours
            .iter()
            .map(|&i| (cost[i] + dist(&tree.q[i], &q), i))
            .collect();
        order.sort_by(|x, y| x.0.total_cmp(&y.0));
        for (c, i) in order {
            if c + dist(&q, goal) >= best_cost {
                break;
            }
            if checker.motion_free(&tree.q[i], &q) {
                parent = Some(i);
                c_new = c;
                break;
            }
        }
        let Some(parent) = parent else {
            continue;
        };
        let new = tree.add(q.clone(), parent);
        cost.push(c_new);
        // Rewire neighbours through the new node.
        for &i in &neighbours {
            let c = c_new + dist(&q, &tree.q[i]);
            if c + 1e-12 < cost[i] && checker.motion_free(&q, &tree.q[i]) {
                let delta = cost[i] - c;
                tree.parent[i] = new;
                // Lower the cost of the subtree.
                let mut stack = vec![i];
                while let Some(k) = stack.pop() {
                    cost[k] -= delta;
                    stack.extend((0..tree.q.len()).filter(|&m| tree.parent[m] == k));
                }
            }
        }
        // Reach the goal from the new node.
        let to_goal = c_new + dist(&q, goal);
        if to_goal + 1e-9 < best_cost && checker.motion_free(&q, goal) {
            let g = tree.add(goal.to_vec(), new);
            cost.push(to_goal);
            goal_node = Some(g);
        }
        if let Some(g) = goal_node {
            if cost[g] + 1e-9 < best_cost {
                best_cost = cost[g];
                best = tree.branch(g);
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smaller_tree_grows_next() {
        let tree = |n: usize| {
            let mut t = Tree::new(&[0.0]);
            for i in 1..n {
                t.add(vec![i as f64], i - 1);
            }
            t
        };
        // The tree that just grew is still the smaller: it grows again, ends unchanged.
        let (mut a, mut b, mut a_is_start) = (tree(2), tree(5), true);
        smaller_first(&mut a, &mut b, &mut a_is_start);
        assert_eq!((a.q.len(), b.q.len(), a_is_start), (2, 5, true));
        // It is now the larger: the other grows next.
        let (mut a, mut b, mut a_is_start) = (tree(6), tree(5), true);
        smaller_first(&mut a, &mut b, &mut a_is_start);
        assert_eq!((a.q.len(), b.q.len(), a_is_start), (5, 6, false));
        // A tie: the other one.
        let (mut a, mut b, mut a_is_start) = (tree(5), tree(5), false);
        smaller_first(&mut a, &mut b, &mut a_is_start);
        assert!(a_is_start);
    }

    /// A trapped node gets its domain; a sample beyond it is refused without an edge check;
    /// one within it is extended, and the domain grows by `alpha`. Repeated traps shrink it
    /// down to `min`, never below.
    #[test]
    fn a_trapped_node_keeps_its_samples_near() {
        use std::sync::atomic::Ordering;

        let checker = crate::checker::alone("locobot");
        let domain = Domain::for_checker(&checker);
        // A quarter of the LoCoBot's 7 rad diagonal.
        assert!((1.6..1.9).contains(&domain.radius), "{domain:?}");
        let edges = || checker.counters().edges.load(Ordering::Relaxed);
        let home = [0.0; 5];
        let mut tree = Tree::new(&home);
        // Joint 1 far beyond its limit: the extension is trapped.
        let out_of_limits = [50.0, 0.0, 0.0, 0.0, 0.0];
        let grow = extend(&checker, &mut tree, &out_of_limits, 100.0, Some(&domain));
        assert_eq!(grow, Grow::Trapped);
        assert_eq!(tree.domain[0], domain.radius);
        // Beyond the domain: drawn again, nothing checked.
        let checked = edges();
        // Joints 1 and 5 turned (within their ±1.57 rad), 0.05 rad beyond the domain.
        let a = (domain.radius + 0.05) / 2f64.sqrt();
        let far = [a, 0.0, 0.0, 0.0, a];
        let grow = extend(&checker, &mut tree, &far, 100.0, Some(&domain));
        assert_eq!((grow, edges()), (Grow::Outside, checked));
        // Without domains the same sample is checked (and free).
        let mut plain = Tree::new(&home);
        assert_eq!(
            extend(&checker, &mut plain, &far, 100.0, None),
            Grow::Reached(1)
        );
        assert_eq!(edges(), checked + 1);
        // Within it: extended, and the domain grows.
        let near = [0.0, 0.0, 0.0, 0.0, 0.5];
        let grow = extend(&checker, &mut tree, &near, 100.0, Some(&domain));
        assert_eq!(grow, Grow::Reached(1));
        let grown = domain.radius * (1.0 + domain.alpha);
        assert!((tree.domain[0] - grown).abs() < 1e-12, "{}", tree.domain[0]);
        // Traps shrink it by alpha each, to `min` and no further.
        let mut r = tree.domain[0];
        r = domain.after(r, true);
        assert!((r - grown * (1.0 - domain.alpha)).abs() < 1e-12);
        for _ in 0..100_000 {
            r = domain.after(r, true);
        }
        assert_eq!(r, domain.min);
    }
}
