//! State and motion validity: the robot (its moving links and what they carry) against the
//! planning scene and against itself.
//!
//! The planners' search checks edges faster: it advances by the same bound where the spheres
//! show room, and by `resolution` with a contact check where they do not; paths are then
//! proven edge by edge before they are returned.
//!
//! A state is checked in two stages. The broad stage tests each body's conservative spheres
//! against each obstacle's signed distance (in `f32`, structure-of-arrays loops the compiler
//! vectorises); spheres found clear prove their body clear. Only where a sphere is not clear
//! does the exact stage run parry3d on the body's real shapes.
//!
//! A motion (a straight joint-space edge) is proven free by conservative advancement, not
//! sampled: a joint step Δq moves no point of a body more than `Σ |Δqᵢ|·reachᵢ` with the
//! body's own reach ([`CollisionModel::link_reach`]; links near the base move slowly). At each
//! state the checker finds a lower bound of each body's clearance (from the spheres where they
//! are far, exact distances where they are near), and advances along the edge as far as every
//! body's clearance over its speed allows (a pair of moving bodies: over the sum of their
//! speeds), capped at `max_step` of the fastest point. Where the clearance is
//! below `min_step` it takes a step of `min_step` only when the clearances at the step's two
//! ends add up to more than the step (no point of the robot can then reach an obstacle from
//! either end), halving the step until they do; an edge that would need a step below
//! `min_step / 128` (about 8 µm by default) is not proven. Nothing can hide between two
//! checked states, however thin or short the contact.

use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Vector3};
use parry3d::query;

use crate::convert::{self, Exact};
use crate::model::{bounding_sphere, CollisionModel};
use crate::scene::PlanningScene;
use crate::shape::{Sdf, Shape};
use crate::spheres::{self, Sphere};
use crate::{Error, Result};

/// Options of the checker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckOptions {
    /// Fast edge checks (while searching): largest motion of any robot point between two
    /// states checked for contact, m.
    pub resolution: f64,
    /// Proven edge checks: largest advance of conservative advancement, m.
    pub max_step: f64,
    /// Proven edge checks: the step (in robot-point motion) where the clearance is below it,
    /// halved near contact (down to `min_step / 128`), m.
    pub min_step: f64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            resolution: 0.01,
            max_step: 0.05,
            min_step: 0.001,
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
    /// Paths the planners had to search again with proven edges (their search's edges
    /// missed a contact).
    pub replans: AtomicU64,
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
    centre: Vector3<f64>,
    radius: f64,
    pose: parry3d::math::Pose,
    exact: Exact,
}

impl Obstacle {
    fn new(id: &str, shape: &Shape, pose: &Isometry3<f64>) -> Result<Self> {
        let exact = shape.to_parry()?;
        let inv = pose.inverse();
        let r = inv.rotation.to_rotation_matrix();
        let m = r.matrix();
        let t = inv.translation.vector;
        let (lo, hi) = shape.bounds();
        let centre = pose * Point3::from((lo + hi) / 2.0);
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
            centre: centre.coords,
            radius: ((hi - lo) / 2.0).norm(),
            pose: convert::pose(&(pose * exact.correction)),
            exact,
        })
    }
}

/// Voxels as the checker sees them: a dense bit grid over their bounds.
#[derive(Debug, Clone)]
struct Grid {
    size: f64,
    lo: [i32; 3],
    dims: [usize; 3],
    bits: Vec<u64>,
    cube: Exact,
}

impl Grid {
    fn occupied(&self, c: [i32; 3]) -> bool {
        let mut idx = 0usize;
        for ((&v, &lo), &dim) in c.iter().zip(&self.lo).zip(&self.dims) {
            let d = v - lo;
            if d < 0 || d as usize >= dim {
                return false;
            }
            idx = idx * dim + d as usize;
        }
        self.bits[idx / 64] >> (idx % 64) & 1 == 1
    }
}

/// Per-state buffers.
#[derive(Debug, Default)]
struct Scratch {
    values: Vec<f64>,
    poses: Vec<Isometry3<f64>>,
    /// World spheres of every body: x, y, z, radius (`f32`), body ranges.
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    r: Vec<f32>,
    ranges: Vec<(usize, usize)>,
    bounds: Vec<Sphere>,
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
    reach: Vec<f64>,
    /// Each body's reach per planned joint ([`CollisionModel::link_reach`]); 0 when fixed.
    body_reach: Vec<Vec<f64>>,
    opts: CheckOptions,
    scratch: RefCell<Scratch>,
    counters: Counters,
    proven: std::cell::Cell<bool>,
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

/// The distance (m; 0 when touching) between shapes `a` at `pa` and `b` at `pb`. Convex
/// (support-mapped) pairs go to GJK directly: parry's own cuboid–cuboid distance (separating
/// axes, then a projection heuristic) may return more than the true distance when faces are
/// nearly parallel (3.9 cm for boxes 0.05 mm apart), and conservative advancement needs a
/// distance that is never too large.
fn shape_distance(
    pa: &parry3d::math::Pose,
    a: &dyn parry3d::shape::Shape,
    pb: &parry3d::math::Pose,
    b: &dyn parry3d::shape::Shape,
) -> f64 {
    if let (Some(sa), Some(sb)) = (a.as_support_map(), b.as_support_map()) {
        let pos12 = pa.inv_mul(pb);
        return f64::from(query::details::distance_support_map_support_map(
            &pos12, sa, sb,
        ));
    }
    query::distance(pa, a, pb, b).map_or(0.0, |d| f64::from(d.distance))
}

/// The smallest distance (m; 0 when touching) between the exact shapes `a` (on their link at
/// `pose_a`) and `b`.
fn exact_gap(
    a: &[(Isometry3<f64>, Exact)],
    pose_a: &Isometry3<f64>,
    b: &[(parry3d::math::Pose, &Exact)],
    counters: &Counters,
) -> f64 {
    let mut gap = f64::INFINITY;
    for (o, ea) in a {
        let pa = convert::pose(&(pose_a * o));
        for (pb, eb) in b {
            counters.exact_checks.fetch_add(1, Ordering::Relaxed);
            let d = shape_distance(&pa, ea.shape.as_ref(), pb, eb.shape.as_ref());
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
        let grid = scene.voxels().filter(|v| !v.cells.is_empty()).map(|v| {
            let mut lo = [i32::MAX; 3];
            let mut hi = [i32::MIN; 3];
            for c in &v.cells {
                for a in 0..3 {
                    lo[a] = lo[a].min(c[a]);
                    hi[a] = hi[a].max(c[a]);
                }
            }
            let dims = [0, 1, 2].map(|a| (i64::from(hi[a]) - i64::from(lo[a]) + 1) as usize);
            let mut grid = Grid {
                size: v.size,
                lo,
                dims,
                bits: vec![0; (dims[0] * dims[1] * dims[2]).div_ceil(64)],
                cube: Shape::Box([v.size; 3])
                    .to_parry()
                    .expect("a cube has a hull"),
            };
            for c in &v.cells {
                let mut idx = 0usize;
                for a in 0..3 {
                    idx = idx * dims[a] + (c[a] - lo[a]) as usize;
                }
                grid.bits[idx / 64] |= 1 << (idx % 64);
            }
            grid
        });
        let extra: Vec<(usize, Vec<Sphere>)> = bodies[links..]
            .iter()
            .map(|b| (b.link, b.spheres.clone()))
            .collect();
        let reach = model.reach(&extra);
        let body_reach = bodies
            .iter()
            .map(|b| {
                if b.moving {
                    model.link_reach(b.link, &b.spheres)
                } else {
                    vec![0.0; model.dof()]
                }
            })
            .collect();
        Ok(Checker {
            body_reach,
            model,
            bodies,
            obstacles,
            robot_obstacles,
            fixed_of,
            grid,
            pairs,
            reach,
            opts,
            scratch: RefCell::new(Scratch::default()),
            counters: Counters::default(),
            proven: std::cell::Cell::new(false),
        })
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
        speed: Option<&[f64]>,
        cap: f64,
        exact_below: f64,
    ) -> std::result::Result<f64, Contact> {
        self.counters.states.fetch_add(1, Ordering::Relaxed);
        let mut s = self.scratch.borrow_mut();
        let s = &mut *s;
        self.model.tree_values_into(q, &mut s.values);
        self.model.tree().poses_into(&s.values, &mut s.poses);
        s.x.clear();
        s.y.clear();
        s.z.clear();
        s.r.clear();
        s.ranges.clear();
        s.bounds.clear();
        for b in &self.bodies {
            let start = s.x.len();
            if b.moving {
                let p = &s.poses[b.link];
                let m = p.rotation.to_rotation_matrix();
                let m = m.matrix();
                let t = p.translation.vector;
                for sp in &b.spheres {
                    let c = m * sp.centre.coords + t;
                    s.x.push(c.x as f32);
                    s.y.push(c.y as f32);
                    s.z.push(c.z as f32);
                    s.r.push(sp.radius as f32);
                }
            }
            s.ranges.push((start, s.x.len()));
            s.bounds.push(Sphere {
                centre: s.poses[b.link] * b.bound.centre,
                radius: b.bound.radius,
            });
        }
        let mut clear = cap;
        let speed_of = |b: usize| speed.map_or(1.0, |v| v[b]).max(1e-9);
        for (bi, b) in self.bodies.iter().enumerate() {
            if !b.moving {
                continue;
            }
            let m = speed_of(bi);
            let bound = s.bounds[bi];
            let (lo, hi) = s.ranges[bi];
            let fixed = self.fixed_of[bi].iter().map(|&o| &self.robot_obstacles[o]);
            for o in self.obstacles.iter().chain(fixed) {
                let gap = (bound.centre.coords - o.centre).norm() - bound.radius - o.radius;
                if gap >= clear * m {
                    continue;
                }
                self.counters
                    .sphere_checks
                    .fetch_add((hi - lo) as u64, Ordering::Relaxed);
                let lb = f64::from(spheres_gap(
                    &o.sdf,
                    &o.inv,
                    &s.x[lo..hi],
                    &s.y[lo..hi],
                    &s.z[lo..hi],
                    &s.r[lo..hi],
                ));
                if lb >= clear * m {
                    continue;
                }
                if lb >= exact_below {
                    clear = lb / m;
                    continue;
                }
                let d = exact_gap(
                    &b.exact,
                    &s.poses[b.link],
                    &[(o.pose, &o.exact)],
                    &self.counters,
                );
                if d <= 0.0 {
                    return Err(Contact {
                        a: b.name.clone(),
                        b: o.id.clone(),
                    });
                }
                clear = clear.min(d / m);
            }
            if let Some(g) = &self.grid {
                clear = clear.min(self.grid_gap(g, b, bi, s, clear * m)? / m);
            }
        }
        // Moving bodies against each other: both move, so the sum of their speeds.
        for &(i, j) in &self.pairs {
            let (bi, bj) = (&s.bounds[i], &s.bounds[j]);
            let m = if speed.is_some() {
                speed_of(i) + speed_of(j)
            } else {
                2.0
            };
            let gap = (bi.centre - bj.centre).norm() - bi.radius - bj.radius;
            if gap >= m * clear {
                continue;
            }
            let (li, hi_) = s.ranges[i];
            let (lj, hj) = s.ranges[j];
            self.counters
                .sphere_checks
                .fetch_add(((hi_ - li) * (hj - lj)) as u64, Ordering::Relaxed);
            let mut lb = f32::INFINITY;
            let (cx, cy, cz) = (bj.centre.x as f32, bj.centre.y as f32, bj.centre.z as f32);
            let rj = bj.radius as f32;
            for k in li..hi_ {
                let (x, y, z, r) = (s.x[k], s.y[k], s.z[k], s.r[k]);
                // This sphere against the other body's bound first.
                let far = ((cx - x).powi(2) + (cy - y).powi(2) + (cz - z).powi(2)).sqrt() - rj - r;
                if f64::from(far) >= m * clear {
                    lb = lb.min(far);
                    continue;
                }
                for m in lj..hj {
                    let dx = s.x[m] - x;
                    let dy = s.y[m] - y;
                    let dz = s.z[m] - z;
                    lb = lb.min((dx * dx + dy * dy + dz * dz).sqrt() - s.r[m] - r);
                }
            }
            let lb = f64::from(lb);
            if lb >= m * clear {
                continue;
            }
            if lb >= 2.0 * exact_below {
                clear = lb / m;
                continue;
            }
            let (a, b) = (&self.bodies[i], &self.bodies[j]);
            let pb = &s.poses[b.link];
            let other: Vec<(parry3d::math::Pose, &Exact)> = b
                .exact
                .iter()
                .map(|(o, e)| (convert::pose(&(pb * o)), e))
                .collect();
            let d = exact_gap(&a.exact, &s.poses[a.link], &other, &self.counters);
            if d <= 0.0 {
                return Err(Contact {
                    a: a.name.clone(),
                    b: b.name.clone(),
                });
            }
            clear = clear.min(d / m);
        }
        Ok(clear.max(0.0))
    }

    /// A lower bound of body `b`'s gap to the voxels (at most `cap`), or the contact.
    fn grid_gap(
        &self,
        g: &Grid,
        b: &Body,
        bi: usize,
        s: &Scratch,
        cap: f64,
    ) -> std::result::Result<f64, Contact> {
        let (lo, hi) = s.ranges[bi];
        let size = g.size as f32;
        let half = size / 2.0;
        let mut clear = cap;
        for k in lo..hi {
            let (x, y, z) = (s.x[k], s.y[k], s.z[k]);
            let reach = s.r[k] + clear as f32;
            let cell = |v: f32| (v / size).floor() as i32;
            for i in cell(x - reach)..=cell(x + reach) {
                for j in cell(y - reach)..=cell(y + reach) {
                    for kk in cell(z - reach)..=cell(z + reach) {
                        if !g.occupied([i, j, kk]) {
                            continue;
                        }
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
                        let lb = f64::from(sdf.distance(x, y, z) - s.r[k]);
                        if lb >= clear {
                            continue;
                        }
                        let pose = convert::pose(&Isometry3::translation(
                            f64::from(c[0]),
                            f64::from(c[1]),
                            f64::from(c[2]),
                        ));
                        let d = exact_gap(
                            &b.exact,
                            &s.poses[b.link],
                            &[(pose, &g.cube)],
                            &self.counters,
                        );
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

    /// Whether the straight joint-space edge from `a` to `b` is free: proven
    /// ([`Checker::motion_proven`]) when [`Checker::set_proven`] asked for it, else checked
    /// at states at most `resolution` of robot-point motion apart (the planners' search).
    pub fn motion_free(&self, a: &[f64], b: &[f64]) -> bool {
        if self.proven.get() {
            return self.motion_proven(a, b);
        }
        if !self.within_limits(a) || !self.within_limits(b) {
            return false;
        }
        // Advance by the spheres' clearance where it is large (proven free), by the resolution
        // where it is not (checked for contact alone).
        self.advance(a, b, self.opts.resolution, 0.0)
    }

    /// Each body's largest point motion (m) over the edge from `a` to `b`.
    fn speeds(&self, a: &[f64], b: &[f64]) -> Vec<f64> {
        self.body_reach
            .iter()
            .map(|r| {
                r.iter()
                    .zip(a.iter().zip(b))
                    .map(|(r, (x, y))| r * (x - y).abs())
                    .sum()
            })
            .collect()
    }

    /// The search's edge check: from each state, as far as every body's gap over its speed
    /// along the edge allows (at most `max_step` of the fastest point), and at least `floor`
    /// (m of the fastest point, where states are checked for contact alone). Exact distances
    /// where the spheres' bound is below `exact_below` (m).
    fn advance(&self, a: &[f64], b: &[f64], floor: f64, exact_below: f64) -> bool {
        self.counters.edges.fetch_add(1, Ordering::Relaxed);
        let total = self.motion_bound(a, b);
        let speed = self.speeds(a, b);
        let mut q = a.to_vec();
        let mut t = 0.0f64;
        let (cap, floor) = if total > 0.0 {
            (self.opts.max_step / total, floor / total)
        } else {
            (1.0, 1.0)
        };
        loop {
            for ((v, x), y) in q.iter_mut().zip(a).zip(b) {
                *v = x + (y - x) * t;
            }
            let Ok(dt) = self.measure_with(&q, Some(&speed), cap, exact_below) else {
                return false;
            };
            if t >= 1.0 {
                return true;
            }
            t = (t + dt.max(floor)).min(1.0);
        }
    }

    /// Makes [`Checker::motion_free`] prove edges (true) or check them at the resolution.
    pub fn set_proven(&self, proven: bool) {
        self.proven.set(proven);
    }

    /// Whether every state on the straight joint-space edge from `a` to `b` is free (the ends
    /// included), by conservative advancement from `a` (see the module's documentation).
    pub fn motion_proven(&self, a: &[f64], b: &[f64]) -> bool {
        if !self.within_limits(a) || !self.within_limits(b) {
            return false;
        }
        self.counters.edges.fetch_add(1, Ordering::Relaxed);
        let total = self.motion_bound(a, b);
        let speed = self.speeds(a, b);
        let exact_below = (self.opts.max_step * 0.5).max(self.opts.min_step);
        let mut q = a.to_vec();
        let (cap, min_dt) = if total > 0.0 {
            (self.opts.max_step / total, self.opts.min_step / total)
        } else {
            (1.0, 1.0)
        };
        // How far along the edge (in t) nothing can be reached from `t`, or `None` at a
        // contact.
        let mut clearance = |t: f64| {
            for ((v, x), y) in q.iter_mut().zip(a).zip(b) {
                *v = x + (y - x) * t;
            }
            self.measure_with(&q, Some(&speed), cap, exact_below).ok()
        };
        let Some(mut clear) = clearance(0.0) else {
            return false;
        };
        if total <= 0.0 {
            return true;
        }
        let smallest = min_dt / 128.0;
        let mut t = 0.0f64;
        while t < 1.0 {
            if clear >= min_dt {
                // No point can reach anything within `clear`.
                t = (t + clear).min(1.0);
                let Some(c) = clearance(t) else {
                    return false;
                };
                clear = c;
                continue;
            }
            // Near contact: a step of h is free when the clearances at its ends add up to more
            // than h (a point x into it is at least max(c0 − x, c1 − (h − x)) > 0 from
            // anything; for each body, as each clearance is the smallest over bodies).
            let mut h = min_dt;
            loop {
                let next = (t + h).min(1.0);
                let Some(c) = clearance(next) else {
                    return false;
                };
                if clear + c > next - t {
                    t = next;
                    clear = c;
                    break;
                }
                h /= 2.0;
                if h < smallest {
                    return false;
                }
            }
        }
        true
    }

    /// Whether every edge of `path` is proven free.
    pub fn path_proven(&self, path: &[Vec<f64>]) -> bool {
        path.len() == 1 && self.is_free(&path[0])
            || path.windows(2).all(|w| self.motion_proven(&w[0], &w[1])) && !path.is_empty()
    }
}

/// The smallest gap (m, negative inside) between any sphere (world `x, y, z`, radius `r`)
/// and the obstacle.
#[inline]
fn spheres_gap(sdf: &Sdf, inv: &[f32; 12], x: &[f32], y: &[f32], z: &[f32], r: &[f32]) -> f32 {
    let mut gap = f32::INFINITY;
    for k in 0..x.len() {
        let (wx, wy, wz) = (x[k], y[k], z[k]);
        let lx = inv[0] * wx + inv[1] * wy + inv[2] * wz + inv[9];
        let ly = inv[3] * wx + inv[4] * wy + inv[5] * wz + inv[10];
        let lz = inv[6] * wx + inv[7] * wy + inv[8] * wz + inv[11];
        gap = gap.min(sdf.distance(lx, ly, lz) - r[k]);
    }
    gap
}
