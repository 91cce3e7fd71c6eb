//! State and motion validity: the robot (its moving links and what they carry) against the
//! planning scene and against itself.
//!
//! A state is checked in stages. A coarse stage measures each body's bounding sphere against
//! each obstacle's bounding box. The broad stage tests the body's conservative spheres against
//! the obstacle's signed distance (in `f32`, padded structure-of-arrays loops the compiler
//! vectorises); spheres found clear prove their body clear. Only where the spheres are not
//! conclusive (they would limit a step, or they touch) does the exact stage run on the body's
//! real shapes: the separating-axis bound of their bounding boxes ([`crate::boxes`]), exact
//! for two boxes and often enough for others, then GJK (parry3d) where it is not.
//!
//! A motion (a straight joint-space edge) is proven free by conservative advancement, not
//! sampled: a joint step Δq moves no point of a body more than `Σ |Δqᵢ|·reachᵢ` with the
//! body's own reach ([`CollisionModel::link_reach`]: its points' distance from each joint's
//! axis; links near the base move slowly, and a wrist's roll turns the gripper little). At each
//! state the checker finds a lower bound of each body's clearance (from the spheres where they
//! are far, exact distances where they are near) over its speed (a pair of moving bodies: over
//! their relative speed, from the joints that move one of them and not the other), capped at
//! `max_step` of the fastest point. A step between two states is free when the clearances at
//! its two ends add up to more than the step: no point of the robot can then reach an
//! obstacle from either end. Advancement tries a step of three times the clearance (at least `h`:
//! `resolution` for the planners' edges, `min_step` for [`Checker::motion_proven`]) and halves
//! it, keeping the states measured ahead, until the rule holds; an edge that would need a step
//! below `min_step / 128` (about 8 µm by default) is not proven. Nothing can hide between two
//! checked states, however thin or short the contact, so every edge a planner returns is
//! free. Advancement starts with a few states spread over the edge ([`rake`]: its end, its
//! middle, its quarters…), which refuse most colliding edges after a few states; on a free
//! edge their clearances are states measured ahead.
//!
//! Along one edge, what was far at one state stays far for a while: each body's candidates
//! are those that may come near it anywhere on the edge, and each keeps its last gap, which
//! bounds its gap at every other state of the edge ([`Near`]).

use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use nalgebra::Isometry3;
use parry3d::query;

use crate::boxes;
use crate::coarse::{BoxSet, FAR, LANES};
use crate::convert::{self, Exact};
use crate::model::{bounding_sphere, CollisionModel};
use crate::scene::PlanningScene;
use crate::segments;
use crate::shape::{self, Sdf, Shape};
use crate::spheres::{self, Sphere};
use crate::{Error, Result};

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
    /// States checked.
    pub states: AtomicU64,
    /// Sphere-level tests (a sphere against an obstacle or another sphere).
    pub sphere_checks: AtomicU64,
    /// Exact (parry3d) shape-pair queries.
    pub exact_checks: AtomicU64,
    /// Edges checked.
    pub edges: AtomicU64,
}

/// A body of the robot: a link's geometry or an attached object, in its link's frame.
#[derive(Debug, Clone)]
struct Body {
    name: String,
    link: usize,
    moving: bool,
    spheres: Vec<Sphere>,
    bound: Sphere,
    exact: Vec<(Isometry3<f64>, Exact)>,
}

/// A world object (or voxel) as the checker sees it.
#[derive(Debug, Clone)]
struct Obstacle {
    id: String,
    sdf: Sdf,
    /// World to object frame: rotation rows and translation, `f32`.
    inv: [f32; 12],
    /// The exact shape and the pose of its frame.
    placed: [(Isometry3<f64>, Exact); 1],
    /// Bounding box in the object frame: centre and half-extents, m.
    bbox: ([f32; 3], [f32; 3]),
}

impl Obstacle {
    /// A lower bound (m) of the gap between the obstacle and the sphere at `c` (world) of
    /// radius `r`: the signed distance of the obstacle's bounding box.
    fn coarse_gap(&self, c: &nalgebra::Point3<f64>, r: f64) -> f64 {
        let (lx, ly, lz) = shape::to_local(&self.inv, c.x as f32, c.y as f32, c.z as f32);
        let (centre, half) = self.bbox;
        f64::from(shape::box_distance(centre, half, lx, ly, lz)) - r
    }

    fn new(id: &str, shape: &Shape, pose: &Isometry3<f64>) -> Result<Self> {
        let exact = shape.to_parry()?;
        let inv = pose.inverse();
        let r = inv.rotation.to_rotation_matrix();
        let m = r.matrix();
        let t = inv.translation.vector;
        Ok(Obstacle {
            id: id.to_string(),
            sdf: shape.sdf(),
            inv: [
                m[(0, 0)] as f32,
                m[(0, 1)] as f32,
                m[(0, 2)] as f32,
                m[(1, 0)] as f32,
                m[(1, 1)] as f32,
                m[(1, 2)] as f32,
                m[(2, 0)] as f32,
                m[(2, 1)] as f32,
                m[(2, 2)] as f32,
                t.x as f32,
                t.y as f32,
                t.z as f32,
            ],
            placed: [(pose * exact.correction, exact)],
            bbox: {
                let (lo, hi) = shape.bounds();
                let (c, h) = ((lo + hi) / 2.0, (hi - lo) / 2.0);
                (
                    [c.x as f32, c.y as f32, c.z as f32],
                    [h.x as f32, h.y as f32, h.z as f32],
                )
            },
        })
    }
}

/// Most cells of the box round the voxels that [`Grid`] keeps as a dense bit grid (16 MiB);
/// voxels spread wider (a room-sized scan in small cubes) are looked up in their sorted list.
const DENSE_CELLS: u64 = 1 << 27;

/// Voxels as the checker sees them: a dense bit grid over their bounds, or their sorted cells
/// where that grid would be too large ([`DENSE_CELLS`]).
#[derive(Debug, Clone)]
struct Grid {
    size: f64,
    /// The cells' smallest and largest coordinates along each axis.
    lo: [i32; 3],
    hi: [i32; 3],
    occupancy: Occupancy,
    /// A voxel, at the origin.
    cube: [(Isometry3<f64>, Exact); 1],
}

#[derive(Debug, Clone)]
enum Occupancy {
    Dense { dims: [usize; 3], bits: Vec<u64> },
    Sorted(Vec<[i32; 3]>),
}

impl Grid {
    /// `cells` sorted without repeats, not empty.
    fn new(size: f64, cells: &[[i32; 3]]) -> Self {
        let mut lo = [i32::MAX; 3];
        let mut hi = [i32::MIN; 3];
        for c in cells {
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        let dims = [0, 1, 2].map(|a| (i64::from(hi[a]) - i64::from(lo[a]) + 1) as u64);
        let total = dims
            .iter()
            .try_fold(1u64, |n, &d| n.checked_mul(d))
            .filter(|&n| n <= DENSE_CELLS);
        let occupancy = match total {
            Some(n) => {
                let dims = dims.map(|d| d as usize);
                let mut bits = vec![0u64; (n as usize).div_ceil(64)];
                for c in cells {
                    let mut idx = 0usize;
                    for a in 0..3 {
                        idx = idx * dims[a] + (c[a] - lo[a]) as usize;
                    }
                    bits[idx / 64] |= 1 << (idx % 64);
                }
                Occupancy::Dense { dims, bits }
            }
            None => Occupancy::Sorted(cells.to_vec()),
        };
        Grid {
            size,
            lo,
            hi,
            occupancy,
            cube: [(
                Isometry3::identity(),
                Shape::Box([size; 3]).to_parry().expect("a cube has a hull"),
            )],
        }
    }

    fn occupied(&self, c: [i32; 3]) -> bool {
        if (0..3).any(|a| c[a] < self.lo[a] || c[a] > self.hi[a]) {
            return false;
        }
        match &self.occupancy {
            Occupancy::Dense { dims, bits } => {
                let mut idx = 0usize;
                for a in 0..3 {
                    idx = idx * dims[a] + (c[a] - self.lo[a]) as usize;
                }
                bits[idx / 64] >> (idx % 64) & 1 == 1
            }
            Occupancy::Sorted(cells) => cells.binary_search(&c).is_ok(),
        }
    }

    /// The occupied cells `[i, j, k]` for `k` in `ks`: each tested in a dense grid; in a
    /// sorted list, found by a binary search for the column's first and read in order.
    fn column(
        &self,
        i: i32,
        j: i32,
        ks: std::ops::RangeInclusive<i32>,
    ) -> impl Iterator<Item = i32> + '_ {
        let (dense, sorted) = match &self.occupancy {
            Occupancy::Dense { .. } => (Some(ks.filter(move |&k| self.occupied([i, j, k]))), None),
            Occupancy::Sorted(cells) => {
                let (lo, hi) = (*ks.start(), *ks.end());
                let from = cells.partition_point(|c| *c < [i, j, lo]);
                let run = cells[from..]
                    .iter()
                    .take_while(move |c| c[0] == i && c[1] == j && c[2] <= hi)
                    .map(|c| c[2]);
                (None, Some(run))
            }
        };
        dense
            .into_iter()
            .flatten()
            .chain(sorted.into_iter().flatten())
    }

    /// The cells along axis `a` that a span `[from, to]` (m) meets, clipped to the voxels'
    /// bounds (empty when it misses them).
    fn span(&self, a: usize, from: f32, to: f32) -> std::ops::RangeInclusive<i32> {
        let size = self.size as f32;
        // Saturating casts: a span far outside is clipped below.
        let first = ((from / size).floor() as i32).max(self.lo[a]);
        let last = ((to / size).floor() as i32).min(self.hi[a]);
        first..=last
    }
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

/// World spheres of every body: x, y, z, radius (`f32`), at the checker's layout (each
/// body's spheres padded to [`LANES`] with far spheres of no radius, whose gaps are huge and
/// never the smallest); a body's are placed the first time a state needs them.
#[derive(Debug, Default)]
struct Placed {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    r: Vec<f32>,
    ready: Vec<bool>,
}

impl Placed {
    /// Forgets every placement: a new state.
    fn reset(&mut self, layout: &[(usize, usize, usize)]) {
        let n = layout.last().map_or(0, |l| l.2);
        if self.x.len() != n {
            for v in [&mut self.x, &mut self.y, &mut self.z] {
                v.clear();
                v.resize(n, FAR);
            }
            self.r.clear();
            self.r.resize(n, 0.0);
        }
        self.ready.clear();
        self.ready.resize(layout.len(), false);
    }

    /// Places body `bi`'s spheres (`spheres` in its link's frame, the link at `pose`) at
    /// `range`, unless they are already.
    fn place(
        &mut self,
        bi: usize,
        spheres: &[Sphere],
        pose: &Isometry3<f64>,
        range: (usize, usize, usize),
    ) {
        if self.ready[bi] {
            return;
        }
        self.ready[bi] = true;
        let m = pose.rotation.to_rotation_matrix();
        let m = m.matrix();
        let t = pose.translation.vector;
        for (k, sp) in (range.0..range.1).zip(spheres) {
            let c = m * sp.centre.coords + t;
            self.x[k] = c.x as f32;
            self.y[k] = c.y as f32;
            self.z[k] = c.z as f32;
            self.r[k] = sp.radius as f32;
        }
    }
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

/// Ends an edge's [`Near`] limits when dropped.
struct EdgeGuard<'a>(&'a Checker);

impl Drop for EdgeGuard<'_> {
    fn drop(&mut self) {
        self.0.scratch.borrow_mut().near.on = false;
    }
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
    /// [`rake`]'s spacing, m ([`RAKE_SPACING_PER_REACH`]).
    rake_spacing: f64,
    /// Each body's reach per planned joint ([`CollisionModel::link_reach`]); 0 when fixed.
    body_reach: Vec<Vec<f64>>,
    /// Each moving pair's reach per planned joint: a joint that moves both moves them
    /// together, so it counts 0; one that moves one of them, that one's reach.
    pair_reach: Vec<Vec<f64>>,
    opts: CheckOptions,
    scratch: RefCell<Scratch>,
    counters: Counters,
}

/// Whether links `a` and `b` of `model` at `pa`, `pb` (root frame) touch (exact shapes).
pub(crate) fn links_touch(
    model: &CollisionModel,
    a: usize,
    pa: &Isometry3<f64>,
    b: usize,
    pb: &Isometry3<f64>,
) -> bool {
    let la = &model.links()[a];
    let lb = &model.links()[b];
    let ca = pa * la.bound.centre;
    let cb = pb * lb.bound.centre;
    if (ca - cb).norm() > la.bound.radius + lb.bound.radius {
        return false;
    }
    model.exact_at(a, pa).any(|(posa, ea)| {
        model.exact_at(b, pb).any(|(posb, eb)| {
            query::intersection_test(&posa, ea.shape.as_ref(), &posb, eb.shape.as_ref())
                .map_or(true, |i| i.intersecting)
        })
    })
}

/// A lower bound (m; 0 when they may touch) of the distance between convex shapes `a` at `pa`
/// and `b` at `pb`. GJK (parry3d) only proposes directions: the distance it returns is that
/// of the closest points it found, too large when it stalls (3.8 mm for two of Sawyer's link
/// cylinders 0.7 mm apart) and 0 when it does not converge, and parry's own cuboid–cuboid
/// distance can be centimetres too large for nearly parallel faces. Conservative advancement
/// needs a distance that is never too large, so the bound is the gap between the two shapes'
/// projections on the best of those directions and of `extra` ones (world frame), from their
/// support points, which no direction can overstate, less a micrometre for `f32` rounding.
/// Where none of them separates the shapes but GJK found them apart, the direction is
/// improved by ascent (for two of Sawyer's cylinders 1.57 mm apart, GJK's line left them
/// overlapping by 2 mm; 1.569 mm after the ascent, against 1.575 mm by brute force); 0 when
/// still none separates them.
fn shape_distance(
    pa: &parry3d::math::Pose,
    a: &dyn parry3d::shape::Shape,
    pb: &parry3d::math::Pose,
    b: &dyn parry3d::shape::Shape,
    extra: &[nalgebra::Vector3<f64>],
) -> f64 {
    use parry3d::math::Vector;
    use parry3d::query::gjk::{self, CsoPoint, GJKResult, VoronoiSimplex};
    let (Some(sa), Some(sb)) = (a.as_support_map(), b.as_support_map()) else {
        // Every shape of ours is convex; a non-convex one would get parry's distance.
        return query::distance(pa, a, pb, b).map_or(0.0, |d| f64::from(d.distance));
    };
    // In `a`'s frame.
    let pos12 = pa.inv_mul(pb);
    let centres = pos12.translation;
    let start = if centres.length_squared() > 1e-12 {
        -centres.normalize()
    } else {
        Vector::X
    };
    let mut simplex = VoronoiSimplex::new();
    simplex.reset(CsoPoint::from_shapes(&pos12, sa, sb, start));
    let mut dirs = [centres, Vector::ZERO, Vector::ZERO];
    match gjk::closest_points(&pos12, sa, sb, f32::MAX, true, &mut simplex) {
        GJKResult::Intersection => return 0.0,
        GJKResult::ClosestPoints(p1, p2, n) => {
            dirs[1] = n;
            dirs[2] = p2 - p1;
        }
        GJKResult::Proximity(n) | GJKResult::NoIntersection(n) => dirs[1] = n,
    }
    let mut best = f32::NEG_INFINITY;
    // Directions given in the world: into `a`'s frame.
    let rot = pa.rotation.inverse();
    let extra = extra
        .iter()
        .map(|v| rot * Vector::new(v.x as f32, v.y as f32, v.z as f32));
    // `b` beyond `a` along n: the gap and the witness points' difference.
    let gap = |n: Vector| {
        let w = sb.support_point(&pos12, -n) - sa.local_support_point(n);
        (w.dot(n), w)
    };
    let mut along = Vector::ZERO;
    for n in dirs.into_iter().chain(extra) {
        if !(n.length_squared() > 1e-20 && n.is_finite()) {
            continue;
        }
        let n = n.normalize();
        // Both ways round.
        for n in [n, -n] {
            let (g, _) = gap(n);
            if g > best {
                best = g;
                along = n;
            }
        }
    }
    // Where no direction separates them yet: ascend the gap over directions (a concave
    // function whose supergradient is the witness points' difference), in damped steps.
    if best <= 0.0 && along != Vector::ZERO {
        let mut n = along;
        let mut step = 0.5f32;
        for _ in 0..64 {
            let (g, w) = gap(n);
            let tangent = w - n * w.dot(n);
            let len = tangent.length();
            if !(len > 1e-12 && len.is_finite()) {
                break;
            }
            let m = (n + tangent * (step / len)).normalize();
            let (gm, _) = gap(m);
            if gm > g {
                n = m;
                best = best.max(gm);
            } else if step < 1e-3 {
                break;
            } else {
                step *= 0.5;
            }
        }
    }
    (f64::from(best) - 1e-6).max(0.0)
}

/// A lower bound (m; 0 when touching) of the distance between the exact shapes `a` (on
/// their link at `pose_a`) and `b` (on theirs at `pose_b`). Each pair is first bounded by the
/// separating-axis test of the shapes' bounding boxes (exact when both are boxes) and, for
/// capsules, spheres and cylinders, by the distance of the axes of the capsules that hold them
/// (exact for capsules and spheres); GJK runs only where no bound is exact and the best is
/// below `exact_below` (m) or not positive, so contacts are always decided on the real shapes.
fn exact_gap(
    a: &[(Isometry3<f64>, Exact)],
    pose_a: &Isometry3<f64>,
    b: &[(Isometry3<f64>, Exact)],
    pose_b: &Isometry3<f64>,
    exact_below: f64,
    counters: &Counters,
) -> f64 {
    let mut gap = f64::INFINITY;
    for (o, ea) in a {
        let pa = pose_a * o;
        for (ob, eb) in b {
            let pb = &(pose_b * ob);
            counters.exact_checks.fetch_add(1, Ordering::Relaxed);
            let mut bound = boxes::gap(
                &(pa * nalgebra::Translation3::from(ea.bbox.0)),
                &ea.bbox.1,
                &(pb * nalgebra::Translation3::from(eb.bbox.0)),
                &eb.bbox.1,
            );
            let mut exact = ea.is_box && eb.is_box;
            // A tighter bound, `true` when it is the exact distance.
            let mut take = |d: f64, is_exact: bool| {
                bound = if is_exact { d } else { bound.max(d) }.max(0.0);
                exact = is_exact;
            };
            let axis = |p: &Isometry3<f64>, h: &nalgebra::Vector3<f64>| {
                (
                    p * nalgebra::Point3::from(*h),
                    p * nalgebra::Point3::from(-h),
                )
            };
            // Where both have axes (cylinders, capsules), directions for GJK's stage below:
            // the line of the axes' closest points, and each axis (a cap's normal).
            let mut directions = None;
            if let (Some((ha, ra, ca)), Some((hb, rb, cb))) = (&ea.capsule, &eb.capsule) {
                // The capsules that hold them: exact for capsules and spheres.
                let ((a0, a1), (b0, b1)) = (axis(&pa, ha), axis(pb, hb));
                let (x, y) = segments::closest(&a0, &a1, &b0, &b1);
                take((y - x).norm() - ra - rb, *ca && *cb);
                directions = Some([y - x, a1 - a0, b1 - b0]);
            }
            // A box and a capsule (or what one holds): the capsule's axis against the box.
            for ((pbox, ebox), (pcap, ecap)) in [((&pa, ea), (pb, eb)), ((pb, eb), (&pa, ea))] {
                if let (true, Some((h, r, is_capsule))) = (ebox.is_box, &ecap.capsule) {
                    let (p, q) = axis(pcap, h);
                    take(
                        segments::box_distance(&p, &q, pbox, &ebox.bbox.1) - r,
                        *is_capsule,
                    );
                }
            }
            let d = if exact || bound > 0.0 && bound >= exact_below {
                bound
            } else {
                shape_distance(
                    &convert::pose(&pa),
                    ea.shape.as_ref(),
                    &convert::pose(pb),
                    eb.shape.as_ref(),
                    directions.as_ref().map_or(&[][..], |d| &d[..]),
                )
            };
            gap = gap.min(d);
            if gap <= 0.0 {
                return 0.0;
            }
        }
    }
    gap
}

impl Checker {
    /// A checker of `model` in `scene`. Attached objects must name a link of the model;
    /// objects overlapping each other are fine.
    pub fn new(
        model: Arc<CollisionModel>,
        scene: &PlanningScene,
        opts: CheckOptions,
    ) -> Result<Self> {
        if !(opts.max_step.is_finite()
            && opts.min_step.is_finite()
            && opts.resolution.is_finite()
            && opts.min_step >= 1e-4
            && opts.max_step >= opts.min_step
            && opts.max_step <= 0.5
            && (opts.min_step..=opts.max_step).contains(&opts.resolution))
        {
            return Err(Error::Invalid {
                what: "check options".into(),
                why: format!(
                    "min_step {} m, resolution {} m and max_step {} m must satisfy 1e-4 ≤ min_step ≤ resolution ≤ max_step ≤ 0.5",
                    opts.min_step, opts.resolution, opts.max_step
                ),
            });
        }
        check_padding(opts.padding)?;
        let ids = scene
            .objects()
            .map(|o| &o.id)
            .chain(scene.attached().map(|a| &a.id));
        for id in ids {
            check_not_a_link(&model, id)?;
        }
        let mut bodies: Vec<Body> = model
            .links()
            .iter()
            .enumerate()
            .filter(|(_, l)| !l.is_empty())
            .map(|(i, l)| Body {
                name: l.name.clone(),
                link: i,
                moving: model.is_moving(i),
                spheres: l.spheres.clone(),
                bound: l.bound,
                exact: l
                    .shapes
                    .iter()
                    .zip(&l.exact)
                    .map(|(_, (o, e))| (*o, e.clone()))
                    .collect(),
            })
            .collect();
        let links = bodies.len();
        let mut touch: Vec<Vec<usize>> = Vec::new();
        for a in scene.attached() {
            let link = model.link_index(&a.link).ok_or_else(|| Error::Invalid {
                what: format!("attached object {:?}", a.id),
                why: format!("{:?} is no link of {}", a.link, model.name()),
            })?;
            let mut allowed = vec![link];
            for t in &a.touch_links {
                allowed.push(model.link_index(t).ok_or_else(|| Error::Invalid {
                    what: format!("attached object {:?}", a.id),
                    why: format!("touch link {t:?} is no link of {}", model.name()),
                })?);
            }
            let e = a.shape.to_parry()?;
            let spheres = spheres::cover(&a.shape, &a.pose);
            bodies.push(Body {
                name: a.id.clone(),
                link,
                moving: model.is_moving(link),
                bound: bounding_sphere(&spheres),
                spheres,
                exact: vec![(a.pose * e.correction, e)],
            });
            touch.push(allowed);
        }
        // Bodies that do not move are obstacles to the ones that do, in their fixed poses.
        let fixed = model.link_poses(&vec![0.0; model.dof()]);
        let mut robot_obstacles = Vec::new();
        let mut fixed_of: Vec<Vec<usize>> = vec![Vec::new(); bodies.len()];
        let mut pairs = Vec::new();
        for i in 0..bodies.len() {
            for j in 0..bodies.len() {
                if i == j || !bodies[i].moving || (bodies[j].moving && j < i) {
                    continue;
                }
                let (a, b) = (&bodies[i], &bodies[j]);
                let allowed = match (i >= links, j >= links) {
                    (false, false) => model.acm().is_disabled(&a.name, &b.name),
                    (true, false) => touch[i - links].contains(&b.link),
                    (false, true) => touch[j - links].contains(&a.link),
                    (true, true) => a.link == b.link,
                };
                if allowed {
                    continue;
                }
                if b.moving {
                    pairs.push((i, j));
                } else {
                    let pose = fixed[b.link];
                    let shapes: Vec<&Shape> = if j < links {
                        model.links()[b.link]
                            .shapes
                            .iter()
                            .map(|(_, s)| s)
                            .collect()
                    } else {
                        scene
                            .attached()
                            .nth(j - links)
                            .map(|a| vec![&a.shape])
                            .unwrap_or_default()
                    };
                    let origins: Vec<Isometry3<f64>> = if j < links {
                        model.links()[b.link]
                            .shapes
                            .iter()
                            .map(|(o, _)| *o)
                            .collect()
                    } else {
                        scene
                            .attached()
                            .nth(j - links)
                            .map(|a| vec![a.pose])
                            .unwrap_or_default()
                    };
                    for (shape, o) in shapes.into_iter().zip(origins) {
                        fixed_of[i].push(robot_obstacles.len());
                        robot_obstacles.push(Obstacle::new(&b.name, shape, &(pose * o))?);
                    }
                }
            }
        }
        let obstacles = scene
            .objects()
            .map(|o| Obstacle::new(&o.id, &o.shape, &o.pose))
            .collect::<Result<Vec<_>>>()?;
        let grid = scene
            .voxels()
            .filter(|v| !v.cells.is_empty())
            .map(|v| Grid::new(v.size, &v.cells));
        let extra: Vec<(usize, Vec<Sphere>)> = bodies[links..]
            .iter()
            .map(|b| (b.link, b.spheres.clone()))
            .collect();
        let reach = model.reach(&extra);
        let span = model.span(&extra);
        let body_reach = bodies
            .iter()
            .map(|b| {
                if b.moving {
                    model.link_reach(b.link, &b.spheres)
                } else {
                    vec![0.0; model.dof()]
                }
            })
            .collect::<Vec<Vec<f64>>>();
        let pair_reach = pairs
            .iter()
            .map(|&(i, j)| {
                body_reach[i]
                    .iter()
                    .zip(&body_reach[j])
                    .map(|(&a, &b)| if a > 0.0 && b > 0.0 { 0.0 } else { a + b })
                    .collect()
            })
            .collect();
        let all_of: Vec<Vec<usize>> = bodies
            .iter()
            .zip(&fixed_of)
            .map(|(b, fixed)| {
                if b.moving {
                    (0..obstacles.len())
                        .chain(fixed.iter().map(|&o| obstacles.len() + o))
                        .collect()
                } else {
                    Vec::new()
                }
            })
            .collect();
        let all_pairs = (0..pairs.len()).collect();
        let scratch = Scratch {
            unlimited: all_of
                .iter()
                .map(|list| vec![(f64::NAN, 0.0); list.len()])
                .collect(),
            unlimited_pairs: vec![(f64::NAN, 0.0); pairs.len()],
            ..Scratch::default()
        };
        let mut layout = Vec::with_capacity(bodies.len());
        let mut at = 0;
        for b in &bodies {
            let n = if b.moving { b.spheres.len() } else { 0 };
            let end = at + n.div_ceil(LANES) * LANES;
            layout.push((at, at + n, end));
            at = end;
        }
        let mut checker = Checker {
            pair_reach,
            layout,
            all_of,
            all_boxes: Vec::new(),
            all_pairs,
            body_reach,
            model,
            bodies,
            obstacles,
            robot_obstacles,
            fixed_of,
            grid,
            pairs,
            rake_spacing: (RAKE_SPACING_PER_REACH * span).max(opts.max_step),
            reach,
            opts,
            scratch: RefCell::new(scratch),
            counters: Counters::default(),
        };
        // Through `Checker::obstacle`, which numbers them as `all_of` does.
        checker.all_boxes = checker
            .all_of
            .iter()
            .map(|list| {
                BoxSet::new(list.iter().map(|&k| {
                    let o = checker.obstacle(k);
                    (&o.inv, &o.bbox)
                }))
            })
            .collect();
        Ok(checker)
    }

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

    /// The gap (m) between the robot at `q` and the nearest of the world's objects and voxels
    /// (not its own links), without the padding: exact (GJK's certified bound) where below
    /// `cap`, at most `cap`; 0 at a contact and for a `q` outside the limits.
    pub fn world_gap(&self, q: &[f64], cap: f64) -> f64 {
        if !self.within_limits(q) || cap.is_nan() {
            return 0.0;
        }
        let mut s = self.scratch.borrow_mut();
        let s = &mut *s;
        self.model.link_poses_into(q, &mut s.values, &mut s.poses);
        s.spheres.reset(&self.layout);
        let mut gap = cap.max(0.0);
        for (bi, b) in self.bodies.iter().enumerate() {
            if !b.moving {
                continue;
            }
            let pose = s.poses[b.link];
            let centre = pose * b.bound.centre;
            for o in &self.obstacles {
                if o.coarse_gap(&centre, b.bound.radius) >= gap {
                    continue;
                }
                let d = exact_gap(
                    &b.exact,
                    &pose,
                    &o.placed,
                    &Isometry3::identity(),
                    gap,
                    &self.counters,
                );
                gap = gap.min(d);
            }
            if let Some(g) = &self.grid {
                s.spheres.place(bi, &b.spheres, &pose, self.layout[bi]);
                match self.grid_gap(g, b, bi, s, gap, 0.0) {
                    Ok(d) => gap = gap.min(d),
                    Err(_) => return 0.0,
                }
            }
            if gap <= 0.0 {
                return 0.0;
            }
        }
        gap
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

    /// A lower bound (m, at most `cap`) of how far every robot point at `q` may move while
    /// no contact can occur: the clearance to the scene and to links that do not move, and
    /// half the clearance between moving links. A contact is an error naming the bodies.
    fn measure(&self, q: &[f64], cap: f64) -> std::result::Result<f64, Contact> {
        self.measure_with(q, None, cap, (cap * 0.5).max(self.opts.min_step))
    }

    /// How far (in units of `speed`) the robot may go from `q` with no contact possible: each
    /// body's gap divided by its `speed` (m of point motion per unit; a pair's by the sum of
    /// both), at most `cap`. Without `speed`, every body moves at 1 (the result is
    /// [`Checker::measure`]'s clearance). Exact distances are computed only where the spheres'
    /// bound is below `exact_below` (m; 0: only where spheres overlap, to tell contact from
    /// none).
    fn measure_with(
        &self,
        q: &[f64],
        speed: Option<&Speeds>,
        cap: f64,
        exact_below: f64,
    ) -> std::result::Result<f64, Contact> {
        self.counters.states.fetch_add(1, Ordering::Relaxed);
        let mut s = self.scratch.borrow_mut();
        let s = &mut *s;
        self.model.link_poses_into(q, &mut s.values, &mut s.poses);
        s.spheres.reset(&self.layout);
        s.bounds.clear();
        s.bounds.extend(self.bodies.iter().map(|b| Sphere {
            centre: s.poses[b.link] * b.bound.centre,
            radius: b.bound.radius,
        }));
        let mut clear = cap;
        // Counted here and added once: an atomic add per obstacle costs more than the test.
        let mut checks = 0u64;
        let flush = |checks: u64| {
            self.counters
                .sphere_checks
                .fetch_add(checks, Ordering::Relaxed)
        };
        let speed_of = |b: usize| speed.map_or(1.0, |v| v.body[b]).max(1e-9);
        for (bi, b) in self.bodies.iter().enumerate() {
            if !b.moving {
                continue;
            }
            let m = speed_of(bi);
            let bound = s.bounds[bi];
            let (lo, hi, end) = self.layout[bi];
            let (list, far, t) = if s.near.on {
                (
                    &s.near.obstacles[bi][..],
                    &mut s.near.obstacle_far[bi][..],
                    s.near.t,
                )
            } else {
                (&self.all_of[bi][..], &mut s.unlimited[bi][..], f64::NAN)
            };
            for (&k, far) in list.iter().zip(far.iter_mut()) {
                // Its gap at another state of the edge still clears this step ([`Near`]).
                if still_far(*far, t, clear) {
                    continue;
                }
                // Remember the gap, in units of the edge parameter.
                let mut keep = |gap: f64| *far = (t, gap / m);
                let o = self.obstacle(k);
                let pad = self.padding_of(k);
                checks += 1;
                let coarse = o.coarse_gap(&bound.centre, bound.radius) - pad;
                if coarse >= clear * m {
                    keep(coarse);
                    continue;
                }
                checks += (hi - lo) as u64;
                let w = &mut s.spheres;
                w.place(bi, &b.spheres, &s.poses[b.link], self.layout[bi]);
                let lb = f64::from(spheres_gap(
                    &o.sdf,
                    &o.inv,
                    &w.x[lo..end],
                    &w.y[lo..end],
                    &w.z[lo..end],
                    &w.r[lo..end],
                )) - pad;
                if lb >= clear * m {
                    keep(lb);
                    continue;
                }
                // The spheres limit the step: the shapes' own bound, tighter.
                let d = exact_gap(
                    &b.exact,
                    &s.poses[b.link],
                    &o.placed,
                    &Isometry3::identity(),
                    exact_below + pad,
                    &self.counters,
                ) - pad;
                if d <= 0.0 {
                    flush(checks);
                    return Err(Contact {
                        a: b.name.clone(),
                        b: o.id.clone(),
                    });
                }
                let d = d.max(lb);
                keep(d);
                clear = clear.min(d / m);
            }
            if let Some(g) = &self.grid {
                s.spheres
                    .place(bi, &b.spheres, &s.poses[b.link], self.layout[bi]);
                match self.grid_gap(g, b, bi, s, clear * m, self.opts.padding) {
                    Ok(gap) => clear = clear.min(gap / m),
                    Err(c) => {
                        flush(checks);
                        return Err(c);
                    }
                }
            }
        }
        // Moving bodies against each other: their relative speed.
        let (pairs, far, t) = if s.near.on {
            (&s.near.pairs[..], &mut s.near.pair_far[..], s.near.t)
        } else {
            (&self.all_pairs[..], &mut s.unlimited_pairs[..], f64::NAN)
        };
        for (&p, far) in pairs.iter().zip(far.iter_mut()) {
            let (i, j) = self.pairs[p];
            if still_far(*far, t, clear) {
                continue;
            }
            let (bi, bj) = (&s.bounds[i], &s.bounds[j]);
            let m = speed.map_or(2.0, |v| v.pair[p].max(1e-9));
            let mut keep = |gap: f64| *far = (t, gap / m);
            checks += 1;
            let gap = (bi.centre - bj.centre).norm() - bi.radius - bj.radius;
            if gap >= m * clear {
                keep(gap);
                continue;
            }
            let (li, hi_, _) = self.layout[i];
            let (lj, hj, ej) = self.layout[j];
            let w = &mut s.spheres;
            w.place(
                i,
                &self.bodies[i].spheres,
                &s.poses[self.bodies[i].link],
                self.layout[i],
            );
            w.place(
                j,
                &self.bodies[j].spheres,
                &s.poses[self.bodies[j].link],
                self.layout[j],
            );
            let reach = (m * clear) as f32;
            let (cx, cy, cz) = (bj.centre.x as f32, bj.centre.y as f32, bj.centre.z as f32);
            let rj = bj.radius as f32;
            let mut lb = f32::INFINITY;
            for k in li..hi_ {
                let (x, y, z, r) = (w.x[k], w.y[k], w.z[k], w.r[k]);
                // This sphere against the other body's bound first.
                checks += 1;
                let far = ((cx - x).powi(2) + (cy - y).powi(2) + (cz - z).powi(2)).sqrt() - rj - r;
                if far >= reach {
                    lb = lb.min(far);
                    continue;
                }
                checks += (hj - lj) as u64;
                let g = sphere_spheres_gap(
                    (x, y, z, r),
                    (&w.x[lj..ej], &w.y[lj..ej], &w.z[lj..ej], &w.r[lj..ej]),
                );
                lb = lb.min(g);
            }
            let lb = f64::from(lb);
            if lb >= m * clear {
                keep(lb);
                continue;
            }
            // The spheres limit the step: the shapes' own bound, tighter.
            let (a, b) = (&self.bodies[i], &self.bodies[j]);
            let d = exact_gap(
                &a.exact,
                &s.poses[a.link],
                &b.exact,
                &s.poses[b.link],
                2.0 * exact_below,
                &self.counters,
            );
            if d <= 0.0 {
                flush(checks);
                return Err(Contact {
                    a: a.name.clone(),
                    b: b.name.clone(),
                });
            }
            let d = d.max(lb);
            keep(d);
            clear = clear.min(d / m);
        }
        flush(checks);
        Ok(clear.max(0.0))
    }

    /// A lower bound of body `b`'s gap to the voxels less `pad` (at most `cap`), or the
    /// contact (closer than `pad`).
    fn grid_gap(
        &self,
        g: &Grid,
        b: &Body,
        bi: usize,
        s: &Scratch,
        cap: f64,
        pad: f64,
    ) -> std::result::Result<f64, Contact> {
        let (lo, hi, _) = self.layout[bi];
        let w = &s.spheres;
        let size = g.size as f32;
        let half = size / 2.0;
        let mut clear = cap;
        for k in lo..hi {
            let (x, y, z) = (w.x[k], w.y[k], w.z[k]);
            let reach = w.r[k] + (clear + pad) as f32;
            for i in g.span(0, x - reach, x + reach) {
                for j in g.span(1, y - reach, y + reach) {
                    for kk in g.column(i, j, g.span(2, z - reach, z + reach)) {
                        self.counters.sphere_checks.fetch_add(1, Ordering::Relaxed);
                        let c = [
                            (i as f32 + 0.5) * size,
                            (j as f32 + 0.5) * size,
                            (kk as f32 + 0.5) * size,
                        ];
                        let sdf = Sdf::Box {
                            centre: c,
                            half: [half; 3],
                        };
                        let lb = f64::from(sdf.distance(x, y, z) - w.r[k]) - pad;
                        if lb >= clear {
                            continue;
                        }
                        let pose = Isometry3::translation(
                            f64::from(c[0]),
                            f64::from(c[1]),
                            f64::from(c[2]),
                        );
                        let d = exact_gap(
                            &b.exact,
                            &s.poses[b.link],
                            &g.cube,
                            &pose,
                            pad,
                            &self.counters,
                        ) - pad;
                        if d <= 0.0 {
                            return Err(Contact {
                                a: b.name.clone(),
                                b: format!("voxel [{i}, {j}, {kk}]"),
                            });
                        }
                        clear = clear.min(d);
                    }
                }
            }
        }
        Ok(clear)
    }

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

    /// Whether the straight joint-space edge from `a` to `b` is free, proven by conservative
    /// advancement (see the module's documentation) with steps of `resolution` of robot-point
    /// motion where the clearance is smaller: the planners' edge check. Every edge a planner
    /// returns passed it, so no contact hides anywhere on a returned path.
    pub fn motion_free(&self, a: &[f64], b: &[f64]) -> bool {
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
    fn speeds(&self, a: &[f64], b: &[f64]) -> Speeds {
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
        let Some(mut clear) = clearance(0.0) else {
            return false;
        };
        if total <= 0.0 {
            return true;
        }
        // About 8 µm of point motion with the default `min_step`.
        let smallest = self.opts.min_step / total / 128.0;
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
const RAKE_SPACING_PER_REACH: f64 = 0.3;

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

/// The smallest of `LANES` running minima (a select, not `f32::min`, so the lanes vectorise).
#[inline(always)]
fn lanes_min(m: [f32; LANES]) -> f32 {
    m.iter()
        .fold(f32::INFINITY, |a, &b| if b < a { b } else { a })
}

/// The smallest of `d(local point) − r` over spheres in chunks of [`LANES`]; `d` is the
/// obstacle's signed distance in its frame, reached through `inv` (world to object).
#[inline(always)]
fn lanes_gap<F: Fn(f32, f32, f32) -> f32>(
    inv: &[f32; 12],
    x: &[f32],
    y: &[f32],
    z: &[f32],
    r: &[f32],
    d: F,
) -> f32 {
    let mut m = [f32::INFINITY; LANES];
    for (((x, y), z), r) in x
        .chunks_exact(LANES)
        .zip(y.chunks_exact(LANES))
        .zip(z.chunks_exact(LANES))
        .zip(r.chunks_exact(LANES))
    {
        for l in 0..LANES {
            let (lx, ly, lz) = shape::to_local(inv, x[l], y[l], z[l]);
            let g = d(lx, ly, lz) - r[l];
            m[l] = if g < m[l] { g } else { m[l] };
        }
    }
    lanes_min(m)
}

/// The smallest gap (m, negative inside) between any sphere (world `x, y, z`, radius `r`,
/// padded to [`LANES`]) and the obstacle: one loop per kind of shape, so each vectorises.
#[inline]
fn spheres_gap(sdf: &Sdf, inv: &[f32; 12], x: &[f32], y: &[f32], z: &[f32], r: &[f32]) -> f32 {
    match *sdf {
        Sdf::Box { centre, half } => lanes_gap(inv, x, y, z, r, |lx, ly, lz| {
            shape::box_distance(centre, half, lx, ly, lz)
        }),
        Sdf::Cylinder { radius, half } => lanes_gap(inv, x, y, z, r, |lx, ly, lz| {
            shape::cylinder_distance(radius, half, lx, ly, lz)
        }),
        Sdf::Capsule { radius, half } => lanes_gap(inv, x, y, z, r, |lx, ly, lz| {
            shape::capsule_distance(radius, half, lx, ly, lz)
        }),
    }
}

/// A body's spheres: x, y, z, radius (m).
type SphereSlices<'a> = (&'a [f32], &'a [f32], &'a [f32], &'a [f32]);

/// The smallest gap (m) between sphere `a` and the spheres `b` (padded to [`LANES`]).
#[inline]
fn sphere_spheres_gap(a: (f32, f32, f32, f32), b: SphereSlices<'_>) -> f32 {
    let (x, y, z, r) = a;
    let mut m = [f32::INFINITY; LANES];
    for (((bx, by), bz), br) in
        b.0.chunks_exact(LANES)
            .zip(b.1.chunks_exact(LANES))
            .zip(b.2.chunks_exact(LANES))
            .zip(b.3.chunks_exact(LANES))
    {
        for l in 0..LANES {
            let dx = bx[l] - x;
            let dy = by[l] - y;
            let dz = bz[l] - z;
            let g = (dx * dx + dy * dy + dz * dz).sqrt() - br[l] - r;
            m[l] = if g < m[l] { g } else { m[l] };
        }
    }
    lanes_min(m)
}

/// A bundled robot's checker with no scene and the default options, for the crate's tests.
#[cfg(test)]
pub(crate) fn alone(robot: &str) -> Checker {
    let cfg = ferrobot_description::RobotConfig::bundled(robot).expect("robot");
    let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
    Checker::new(model, &PlanningScene::new(), CheckOptions::default()).expect("checker")
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrobot_description::RobotConfig;
    use rand::{Rng, SeedableRng};

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
        let mut sample = || crate::planner::sample(&mut rng, &limits);
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
            let q = crate::planner::sample(&mut rng, &limits);
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
                crate::planner::sample(&mut rng, &limits),
                crate::planner::sample(&mut rng, &limits),
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
            let q = crate::planner::sample(&mut rng, model.limits());
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
                .map(|_| crate::planner::sample(&mut rng, &limits))
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
        let sample = |rng: &mut rand_chacha::ChaCha8Rng| crate::planner::sample(rng, &limits);
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

    /// Two of Sawyer's link cylinders 1.57 mm apart (a state where parry's GJK stalls and
    /// its closest points' line does not separate them): the bound is still positive and
    /// never above the distance found by brute force over one cylinder's surface.
    #[test]
    fn a_stalled_gjk_still_separates_two_cylinders() {
        let c = alone("sawyer");
        let a = [
            -1.4464259796803793,
            0.27279083823671346,
            -1.567952305417259,
            -1.4994866975607903,
            -0.5256165752549635,
            -1.6400233981540766,
            3.527009238589704,
        ];
        let b = [
            -3.050299882888794,
            -0.44136873703780344,
            -3.04259991645813,
            -2.5118771414971626,
            1.1820621830331528,
            -2.6861894276912412,
            0.5967411935521278,
        ];
        let t = 0.99665;
        let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect();
        let poses = c.model.link_poses(&q);
        let body = |name: &str| c.bodies.iter().position(|b| b.name == name).expect("body");
        let (i, j) = (body("right_l1"), body("right_l5"));
        let (bi, bj) = (&c.bodies[i], &c.bodies[j]);
        let d = exact_gap(
            &bi.exact,
            &poses[bi.link],
            &bj.exact,
            &poses[bj.link],
            1.0,
            &c.counters,
        );
        // Each cylinder's axis ends (world) and radius.
        let cylinder = |b: &Body| {
            let (o, e) = &b.exact[0];
            let p = poses[b.link] * o;
            let (h, r, _) = e.capsule.expect("a cylinder's capsule");
            (
                p * nalgebra::Point3::from(h),
                p * nalgebra::Point3::from(-h),
                r,
            )
        };
        let (a0, a1, ra) = cylinder(bi);
        let (b0, b1, rb) = cylinder(bj);
        let (la, ua) = ((a1 - a0).norm(), (a1 - a0).normalize());
        // Signed distance from cylinder A.
        let from_a = |x: nalgebra::Point3<f64>| {
            let v = x - a0;
            let s = v.dot(&ua);
            let dr = (v - ua * s).norm() - ra;
            let dz = (s - la / 2.0).abs() - la / 2.0;
            dr.max(0.0).hypot(dz.max(0.0)) + dr.max(dz).min(0.0)
        };
        let (lb, ub) = ((b1 - b0).norm(), (b1 - b0).normalize());
        let e1 = ub.cross(&nalgebra::Vector3::x()).normalize();
        let e2 = ub.cross(&e1);
        let mut brute = f64::INFINITY;
        for k in 0..1000 {
            let th = f64::from(k) * std::f64::consts::TAU / 1000.0;
            let rim = (e1 * th.cos() + e2 * th.sin()) * rb;
            for h in 0..=600 {
                brute = brute.min(from_a(b0 + ub * (lb * f64::from(h) / 600.0) + rim));
            }
            for f in 0..=100 {
                let f = f64::from(f) / 100.0;
                brute = brute.min(from_a(b0 + rim * f)).min(from_a(b1 + rim * f));
            }
        }
        assert!((0.001..0.002).contains(&brute), "{brute}");
        assert!(d > 0.0 && d <= brute, "bound {d} m, brute force {brute} m");
    }
}
