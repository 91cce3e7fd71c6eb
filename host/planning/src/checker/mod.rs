//! State and motion validity: the robot (its moving links and what they carry) against the
//! planning scene and against itself. A state is checked in stages (a coarse bound, the
//! conservative spheres, the exact shapes where the cheaper bound is not conclusive); a
//! straight joint-space edge is proven free by conservative advancement, not sampled, so
//! every edge a planner returns is free. Distances in m, poses in the robot's root frame;
//! `docs/design/planning.md` explains the stages and the advancement.

use std::cell::RefCell;
use std::sync::atomic::AtomicU64;
use std::sync::Arc;

use nalgebra::Isometry3;

use crate::coarse::BoxSet;
use crate::convert::Exact;
use crate::model::CollisionModel;
use crate::spheres::Sphere;
use crate::{Error, Result};

mod broad;
mod build;
mod edge;
mod exact;
mod lanes;
// The crate's one `unsafe`: a call of code compiled for AVX2 after the CPU was found to have
// it (the call's note).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod lanes_avx;
mod lanes_edge;
mod measure;
mod obstacle;

pub use lanes::{LaneChecks, LaneScratch};
pub use lanes_edge::Engine;

use broad::Placed;
use obstacle::{Grid, Obstacle};

/// Largest [`CheckOptions::padding`], m.
pub const MAX_PADDING: f64 = 0.2;

/// A [`CheckOptions::padding`] finite and within `[0, MAX_PADDING]`.
fn check_padding(padding: f64) -> Result<()> {
    if padding.is_finite() && (0.0..=MAX_PADDING).contains(&padding) {
        return Ok(());
    }
    Err(Error::Invalid {
        what: "check options".into(),
        why: format!("padding {padding} m must be finite, within [0, {MAX_PADDING}]"),
    })
}

/// Options of the checker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckOptions {
    /// The planners' edge checks ([`Checker::motion_free`]): the step (in robot-point
    /// motion) where the clearance is below it, halved near contact, m.
    pub resolution: f64,
    /// Largest advance of conservative advancement (of the fastest robot point), m.
    pub max_step: f64,
    /// [`Checker::motion_proven`]'s step where the clearance is below it, halved near contact
    /// (down to `min_step / 128` in both checks), m.
    pub min_step: f64,
    /// Clearance kept from the world's objects and voxels (not from the robot's own links),
    /// m: closer counts as a contact. A planned motion keeps this much room for the arm's
    /// tracking error when it is executed.
    pub padding: f64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            resolution: 0.01,
            max_step: 0.05,
            min_step: 0.001,
            padding: 0.0,
        }
    }
}

/// Two bodies in contact: links by URDF name, objects by id.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Contact {
    /// One body.
    pub a: String,
    /// The other.
    pub b: String,
}

/// Counters of the work done.
#[derive(Debug, Default)]
pub struct Counters {
    /// States measured (a walk's, its exact stage's and the advancement's).
    pub states: AtomicU64,
    /// Sphere-level tests (a sphere against an obstacle or another sphere).
    pub sphere_checks: AtomicU64,
    /// Exact (parry3d) shape-pair queries.
    pub exact_checks: AtomicU64,
    /// Edge proofs started (by either engine: a walk handed to the advancement counts twice).
    pub edges: AtomicU64,
}

/// A body of the robot: a link's geometry or an attached object, in its link's frame.
#[derive(Debug, Clone)]
struct Body {
    name: String,
    link: usize,
    moving: bool,
    spheres: Vec<Sphere>,
    /// Whether `spheres` are its shapes themselves (every shape a sphere), not a cover.
    spheres_exact: bool,
    bound: Sphere,
    exact: Vec<(Isometry3<f64>, Exact)>,
}

/// Per-state buffers.
#[derive(Debug, Default)]
struct Scratch {
    values: Vec<f64>,
    poses: Vec<Isometry3<f64>>,
    /// World spheres of the bodies placed so far at this state.
    spheres: Placed,
    bounds: Vec<Sphere>,
    /// While an edge is checked: what may come near anything on it.
    near: Near,
    /// A body's coarse gaps to each of its obstacles, m.
    gaps: Vec<f32>,
    /// Outside an edge, where each body's candidates (all its obstacles) and the pairs write
    /// the gaps they keep: read at edge parameter NaN, they skip nothing.
    unlimited: Vec<Vec<(f64, f64)>>,
    unlimited_pairs: Vec<(f64, f64)>,
}

/// What may come within reach on one edge: for each body, the obstacles (numbered as
/// `Checker::all_of`) and the moving pairs (indices into `Checker::pairs`). Everything else is
/// farther from the body at the edge's start than the body moves along the whole edge plus
/// the largest step, so it can never limit a step.
///
/// Along the edge, a body's points move at most its speed times the change of the edge
/// parameter `t`, so a gap measured at `t₀` holds (shrunk by that motion) at every `t`: each
/// candidate keeps its last gap over its speed, `g` (in units of `t`), and is not measured
/// again at a state while `g − |t − t₀|` is no less than the state's clearance found so far
/// (which only shrinks as the state's candidates are measured).
#[derive(Debug, Default)]
struct Near {
    on: bool,
    /// The edge parameter of the state being checked.
    t: f64,
    obstacles: Vec<Vec<usize>>,
    /// For each body's candidate obstacle: `(t₀, g)`.
    obstacle_far: Vec<Vec<(f64, f64)>>,
    pairs: Vec<usize>,
    /// For each candidate pair: `(t₀, g)`.
    pair_far: Vec<(f64, f64)>,
}

/// Whether a candidate of an edge's [`Near`] list that kept `(t₀, g)` is known not to limit
/// the step at edge parameter `t` below `clear` (in units of `t`); never at `t` NaN.
#[inline(always)]
fn still_far((t0, g): (f64, f64), t: f64, clear: f64) -> bool {
    g - (t - t0).abs() >= clear
}

/// How far (m) each body's points, and each moving pair's points relative to each other, move
/// at most along one edge.
#[derive(Debug)]
struct Speeds {
    body: Vec<f64>,
    pair: Vec<f64>,
}

/// An object id may not be the name of one of `model`'s links: a contact names its two
/// bodies, and could not tell them apart.
pub fn check_not_a_link(model: &CollisionModel, id: &str) -> Result<()> {
    if model.link_index(id).is_some() {
        return Err(Error::Invalid {
            what: format!("object id {id:?}"),
            why: format!("it is the name of a link of {}", model.name()),
        });
    }
    Ok(())
}

/// Checks states and motions of one model in one scene.
#[derive(Debug)]
pub struct Checker {
    model: Arc<CollisionModel>,
    bodies: Vec<Body>,
    obstacles: Vec<Obstacle>,
    grid: Option<Grid>,
    /// Moving body pairs checked against each other.
    pairs: Vec<(usize, usize)>,
    /// The shapes of bodies that do not move, at their fixed poses.
    robot_obstacles: Vec<Obstacle>,
    /// For each body, the robot obstacles it is checked against.
    fixed_of: Vec<Vec<usize>>,
    /// For each body, every obstacle it is checked against: world obstacles by index, then
    /// robot obstacles after them.
    all_of: Vec<Vec<usize>>,
    /// The bounding boxes of each body's obstacles, in `all_of`'s order.
    all_boxes: Vec<BoxSet>,
    /// All moving pairs, by index into `pairs`.
    all_pairs: Vec<usize>,
    /// Where each body's world spheres go in [`Placed`]: `lo..hi`, padded to `lo..end`.
    layout: Vec<(usize, usize, usize)>,
    reach: Vec<f64>,
    /// [`edge::rake`]'s spacing, m ([`edge::RAKE_SPACING_PER_REACH`]).
    rake_spacing: f64,
    /// Each body's reach per planned joint ([`CollisionModel::link_reach`]); 0 when fixed.
    body_reach: Vec<Vec<f64>>,
    /// Each moving pair's reach per planned joint: a joint that moves both moves them
    /// together, so it counts 0; one that moves one of them, that one's reach.
    pair_reach: Vec<Vec<f64>>,
    opts: CheckOptions,
    scratch: RefCell<Scratch>,
    counters: Counters,
    /// The vectorised engine's checks, built when an engine first needs them (never with
    /// voxels).
    lanes: Option<LaneChecks>,
    /// How [`Checker::motion_free`] proves edges.
    engine: Engine,
    walk_scratch: RefCell<lanes_edge::WalkScratch>,
}

impl Checker {
    /// The model.
    pub fn model(&self) -> &CollisionModel {
        &self.model
    }

    /// The options.
    pub fn options(&self) -> CheckOptions {
        self.opts
    }

    /// Work done so far.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// The link pairs (and attached objects) checked against each other, by name.
    pub fn self_pairs(&self) -> Vec<(String, String)> {
        let mut out: Vec<(String, String)> = self
            .pairs
            .iter()
            .map(|&(a, b)| (self.bodies[a].name.clone(), self.bodies[b].name.clone()))
            .collect();
        for (i, list) in self.fixed_of.iter().enumerate() {
            for &o in list {
                let pair = (
                    self.bodies[i].name.clone(),
                    self.robot_obstacles[o].id.clone(),
                );
                if !out.contains(&pair) {
                    out.push(pair);
                }
            }
        }
        out
    }

    /// Names of the links that move with the planned joints.
    pub fn moving_links(&self) -> Vec<String> {
        self.bodies
            .iter()
            .filter(|b| b.moving && self.model.link_index(&b.name) == Some(b.link))
            .map(|b| b.name.clone())
            .collect()
    }

    /// Obstacle `k` as [`Checker::all_of`] numbers them: the world's, then the robot's.
    fn obstacle(&self, k: usize) -> &Obstacle {
        match k.checked_sub(self.obstacles.len()) {
            None => &self.obstacles[k],
            Some(r) => &self.robot_obstacles[r],
        }
    }

    /// Keeps `padding` (m) from the world's objects and voxels from now on
    /// ([`CheckOptions::padding`]); an error, and nothing changed, outside `[0, MAX_PADDING]`.
    pub fn set_padding(&mut self, padding: f64) -> Result<()> {
        check_padding(padding)?;
        self.opts.padding = padding;
        // The engine's distances hold the padding.
        if self.lanes.is_some() {
            self.lanes = self.lane_checks()?;
        }
        Ok(())
    }

    /// The padding (m) kept from obstacle `k` ([`Checker::obstacle`]'s numbering): the
    /// options' for the world's objects, none for the robot's own links.
    fn padding_of(&self, k: usize) -> f64 {
        if k < self.obstacles.len() {
            self.opts.padding
        } else {
            0.0
        }
    }

    /// A bound on how far any robot point moves from `a` to `b` (rad), m.
    pub fn motion_bound(&self, a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .zip(&self.reach)
            .map(|((x, y), r)| (x - y).abs() * r)
            .sum()
    }

    /// Whether `q` is within the joint limits (with 1e-9 of slack).
    pub fn within_limits(&self, q: &[f64]) -> bool {
        q.len() == self.model.dof()
            && q.iter()
                .zip(self.model.limits())
                .all(|(v, (lo, hi))| v.is_finite() && *v >= lo - 1e-9 && *v <= hi + 1e-9)
    }

    /// The first contact of the robot at `q` (exact shapes), or `None` when free. A `q`
    /// outside the limits (or of the wrong length) is reported as a contact with "joint
    /// limits".
    pub fn contact(&self, q: &[f64]) -> Option<Contact> {
        if !self.within_limits(q) {
            return Some(Contact {
                a: "joint limits".into(),
                b: format!("{q:?}"),
            });
        }
        self.measure(q, 0.0).err()
    }

    /// Whether some link at `q` comes within `distance` (m) of the scene or the robot.
    pub fn near_world(&self, q: &[f64], distance: f64) -> bool {
        self.within_limits(q) && self.measure(q, distance).map_or(true, |c| c < distance)
    }

    /// Whether `q` is within limits and free of collision.
    pub fn is_free(&self, q: &[f64]) -> bool {
        self.contact(q).is_none()
    }
}

/// A bundled robot's checker with no scene and the default options, for the crate's tests.
#[cfg(test)]
pub(crate) fn alone(robot: &str) -> Checker {
    let cfg = ferrobot_description::RobotConfig::bundled(robot).expect("robot");
    let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
    let scene = crate::scene::PlanningScene::new();
    Checker::new(model, &scene, CheckOptions::default()).expect("checker")
}

#[cfg(test)]
mod tests {
    use super::obstacle::Occupancy;
    use super::*;
    use crate::scene::PlanningScene;
    use crate::shape::Shape;
    use ferrobot_description::RobotConfig;
    use rand::SeedableRng;
    use std::sync::atomic::Ordering;

    /// The rake's spacing follows the arm's size: the LoCoBot's and Sawyer's on the plateaus
    /// measured for each (BENCHMARKS), and never below the step cap.
    #[test]
    fn the_rake_spacing_follows_the_arm() {
        let spacing = |robot: &str| alone(robot).rake_spacing;
        let (locobot, sawyer) = (spacing("locobot"), spacing("sawyer"));
        assert!((0.15..=0.2).contains(&locobot), "LoCoBot {locobot} m");
        assert!((0.4..=0.6).contains(&sawyer), "Sawyer {sawyer} m");
    }

    /// The LoCoBot's model, and a scene of a table before it and a post over the table.
    fn locobot_table_and_post() -> (Arc<CollisionModel>, PlanningScene) {
        let cfg = RobotConfig::bundled("locobot").expect("locobot");
        let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
        let mut scene = PlanningScene::new();
        scene
            .add_object(
                "table",
                Shape::Box([0.45, 0.8, 0.1]),
                Isometry3::translation(0.5, 0.0, 0.05),
            )
            .expect("table");
        scene
            .add_object(
                "post",
                Shape::Cylinder {
                    radius: 0.02,
                    length: 0.3,
                },
                Isometry3::translation(0.35, 0.1, 0.25),
            )
            .expect("post");
        (model, scene)
    }

    /// With a padding, a state is free only where the world is farther than the padding
    /// ([`Checker::world_gap`], unpadded, says how far), and every edge proven free keeps it:
    /// states 1 mm apart along it are all at least the padding from the world.
    #[test]
    fn padding_keeps_room_from_the_world() {
        let (model, scene) = locobot_table_and_post();
        let pad = 0.02;
        let plain = Checker::new(model.clone(), &scene, CheckOptions::default()).expect("plain");
        let padded = Checker::new(
            model.clone(),
            &scene,
            CheckOptions {
                padding: pad,
                ..CheckOptions::default()
            },
        )
        .expect("padded");
        let limits = model.limits().to_vec();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut sample = || crate::joint_space::sample(&mut rng, &limits);
        let (mut within, mut beyond) = (0, 0);
        while within < 30 || beyond < 30 {
            let q = sample();
            if !plain.is_free(&q) {
                continue;
            }
            let g = plain.world_gap(&q, 0.1);
            if g < pad - 1e-4 {
                within += 1;
                assert!(!padded.is_free(&q), "{g} m from the world: {q:?}");
            } else if g > pad + 1e-4 {
                beyond += 1;
                assert!(padded.is_free(&q), "{g} m from the world: {q:?}");
            }
        }
        // Set on a built checker, the same padding gives the same answers; hostile values
        // are refused and change nothing.
        let mut reset =
            Checker::new(model.clone(), &scene, CheckOptions::default()).expect("reset");
        for bad in [f64::NAN, f64::INFINITY, -0.01, MAX_PADDING + 0.01] {
            assert!(reset.set_padding(bad).is_err(), "{bad}");
            assert_eq!(reset.options().padding, 0.0);
        }
        reset.set_padding(pad).expect("padding");
        for _ in 0..200 {
            let q = sample();
            assert_eq!(reset.is_free(&q), padded.is_free(&q), "{q:?}");
        }
        let mut proven = 0;
        while proven < 15 {
            let (a, b) = (sample(), sample());
            if !(padded.is_free(&a) && padded.is_free(&b) && padded.motion_free(&a, &b)) {
                continue;
            }
            proven += 1;
            let n = (plain.motion_bound(&a, &b) / 1e-3).ceil().max(1.0) as usize;
            for k in 0..=n {
                let t = k as f64 / n as f64;
                let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect();
                let g = plain.world_gap(&q, pad);
                assert!(
                    g >= pad - 1e-4,
                    "{g} m from the world at {t} of {a:?} → {b:?}"
                );
            }
        }
    }

    /// Voxels spread over a kilometre in 5 mm cubes (a box of 10¹⁷ cells, which a dense grid
    /// could not allocate) are kept as a sorted list and answer as the same voxels near the
    /// arm do alone in a dense grid: the same contacts, gaps and edge verdicts at random
    /// states.
    #[test]
    fn voxels_spread_far_answer_as_a_dense_grid_does() {
        use crate::scene::Voxels;
        let cfg = RobotConfig::bundled("locobot").expect("locobot");
        let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
        // A slab of points in front of the arm, 5 mm apart.
        let mut near = Vec::new();
        for i in 0..20 {
            for j in 0..40 {
                near.push(nalgebra::Point3::new(
                    0.3 + 0.005 * f64::from(i),
                    -0.1 + 0.005 * f64::from(j),
                    0.25,
                ));
            }
        }
        let mut far = near.clone();
        far.push(nalgebra::Point3::new(999.0, -999.0, 999.0));
        far.push(nalgebra::Point3::new(-999.0, 999.0, -999.0));
        let checker = |points: &[nalgebra::Point3<f64>]| {
            let mut scene = PlanningScene::new();
            scene
                .set_voxels(Some(Voxels::from_points(points, 0.005).expect("voxels")))
                .expect("valid");
            Checker::new(model.clone(), &scene, CheckOptions::default()).expect("checker")
        };
        let (dense, sparse) = (checker(&near), checker(&far));
        assert!(matches!(
            dense.grid.as_ref().map(|g| &g.occupancy),
            Some(Occupancy::Dense { .. })
        ));
        assert!(matches!(
            sparse.grid.as_ref().map(|g| &g.occupancy),
            Some(Occupancy::Sorted(_))
        ));
        let limits = model.limits().to_vec();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (mut hits, mut free) = (0, 0);
        for _ in 0..300 {
            let q = crate::joint_space::sample(&mut rng, &limits);
            let c = dense.contact(&q);
            assert_eq!(c, sparse.contact(&q), "{q:?}");
            if c.is_some() {
                hits += 1;
            } else {
                free += 1;
                assert_eq!(dense.world_gap(&q, 0.2), sparse.world_gap(&q, 0.2), "{q:?}");
            }
        }
        assert!(hits >= 5 && free >= 5, "{hits} contacts, {free} free");
        // Edges between free states: the same verdicts, some through the slab.
        let (mut refused, mut proven) = (0, 0);
        while refused < 3 || proven < 3 {
            let (a, b) = (
                crate::joint_space::sample(&mut rng, &limits),
                crate::joint_space::sample(&mut rng, &limits),
            );
            if !(dense.is_free(&a) && dense.is_free(&b)) {
                continue;
            }
            let ok = dense.motion_free(&a, &b);
            assert_eq!(ok, sparse.motion_free(&a, &b), "{a:?} → {b:?}");
            if ok {
                proven += 1;
            } else {
                refused += 1;
            }
        }
    }

    /// One test is counted per test run: an obstacle far from every body adds exactly one
    /// bounding-sphere test per moving body to a state's count, and nothing else.
    #[test]
    fn sphere_checks_count_the_tests_run() {
        let cfg = RobotConfig::bundled("locobot").expect("locobot");
        let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
        let checker = |scene: &PlanningScene| {
            Checker::new(model.clone(), scene, CheckOptions::default()).expect("checker")
        };
        let empty = checker(&PlanningScene::new());
        let mut scene = PlanningScene::new();
        scene
            .add_object(
                "far",
                Shape::Box([0.2, 0.2, 0.2]),
                Isometry3::translation(10.0, 0.0, 0.0),
            )
            .expect("far box");
        let far = checker(&scene);
        let bodies = empty.moving_links().len() as u64;
        assert_eq!(bodies, 8, "{:?}", empty.moving_links());
        let checks = |c: &Checker| c.counters().sphere_checks.load(Ordering::Relaxed);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut states = 0;
        while states < 5 {
            let q = crate::joint_space::sample(&mut rng, model.limits());
            let (e0, f0) = (checks(&empty), checks(&far));
            if !empty.is_free(&q) {
                continue;
            }
            assert!(far.is_free(&q));
            states += 1;
            let (e, f) = (checks(&empty) - e0, checks(&far) - f0);
            assert!(e > bodies, "{e} tests");
            assert_eq!(f, e + bodies, "{q:?}");
        }
    }

    /// Edges that collide are refused after a few states (the rake's), not after a walk up to
    /// their contact: LoCoBot edges among a table and a post, the arm folding onto its own
    /// camera mast. Every refused edge the 1 mm samples find in contact counts.
    #[test]
    fn colliding_edges_are_refused_after_a_few_states() {
        let (model, scene) = locobot_table_and_post();
        let c = Checker::new(model.clone(), &scene, CheckOptions::default()).expect("checker");
        let limits = model.limits().to_vec();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let states = || c.counters().states.load(Ordering::Relaxed);
        let (mut refused, mut refused_states, mut free, mut free_states) = (0, 0, 0, 0);
        while refused < 60 || free < 20 {
            let q: Vec<Vec<f64>> = (0..2)
                .map(|_| crate::joint_space::sample(&mut rng, &limits))
                .collect();
            let (a, b) = (&q[0], &q[1]);
            if !c.is_free(a) || !c.is_free(b) {
                continue;
            }
            let before = states();
            let ok = c.motion_free(a, b);
            let used = states() - before;
            if ok {
                free += 1;
                free_states += used;
            } else if !c.motion_sampled(a, b, 0.001) {
                refused += 1;
                refused_states += used;
            }
        }
        let (per_refused, per_free) = (
            refused_states as f64 / f64::from(refused),
            free_states as f64 / f64::from(free),
        );
        assert!(
            per_refused < 6.0 && per_refused < 0.5 * per_free,
            "{per_refused} states per refused edge, {per_free} per free one"
        );
    }
}
