//! State and motion validity: the robot (its moving links and what they carry) against the
//! planning scene and against itself.
//!
//! A state is checked in two stages. The broad stage tests each body's conservative spheres
//! against each obstacle's signed distance (in `f32`, structure-of-arrays loops the compiler
//! vectorises); spheres found clear prove their body clear. Only where a sphere is not clear
//! does the exact stage run parry3d on the body's real shapes.
//!
//! A motion (a straight joint-space edge) is proven free, not sampled: a joint step Δq moves
//! no point of the robot more than `Σ |Δqᵢ|·reachᵢ` ([`CollisionModel::reach`]). States are
//! placed so that no point moves more than `resolution` between neighbours, and each must be
//! clear of the world by `resolution / 2` and of the robot's other links by `resolution`:
//! then every state between them is free. Where a state is free but closer than that, its
//! neighbourhood is proven again with a quarter of the resolution, down to
//! `min_resolution`, where states that far apart are checked for contact alone.

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
    /// Largest motion of any robot point between two checked states of an edge, m.
    pub resolution: f64,
    /// Finest resolution of the refinement near obstacles, m.
    pub min_resolution: f64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            resolution: 0.01,
            min_resolution: 0.001,
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
        for a in 0..3 {
            let d = c[a] - self.lo[a];
            if d < 0 || d as usize >= self.dims[a] {
                return false;
            }
            idx = idx * self.dims[a] + d as usize;
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
    /// Body pairs checked against each other.
    pairs: Vec<(usize, usize)>,
    reach: Vec<f64>,
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

/// Whether the exact shapes `a` (at their poses) come within `margin` (m) of `b`.
fn exact_near(
    a: &[(Isometry3<f64>, Exact)],
    pose_a: &Isometry3<f64>,
    b: &[(parry3d::math::Pose, &Exact)],
    margin: f64,
    counters: &Counters,
) -> bool {
    for (o, ea) in a {
        let pa = convert::pose(&(pose_a * o));
        for (pb, eb) in b {
            counters.exact_checks.fetch_add(1, Ordering::Relaxed);
            let hit = if margin <= 0.0 {
                query::intersection_test(&pa, ea.shape.as_ref(), pb, eb.shape.as_ref())
                    .map_or(true, |i| i.intersecting)
            } else {
                query::distance(&pa, ea.shape.as_ref(), pb, eb.shape.as_ref())
                    .map_or(true, |d| f64::from(d.distance) <= margin)
            };
            if hit {
                return true;
            }
        }
    }
    false
}

impl Checker {
    /// A checker of `model` in `scene`. Attached objects must name a link of the model;
    /// objects overlapping each other are fine.
    pub fn new(
        model: Arc<CollisionModel>,
        scene: &PlanningScene,
        opts: CheckOptions,
    ) -> Result<Self> {
        if !(opts.resolution.is_finite()
            && opts.min_resolution.is_finite()
            && opts.min_resolution >= 1e-4
            && opts.resolution >= opts.min_resolution
            && opts.resolution <= 0.5)
        {
            return Err(Error::Invalid {
                what: "check options".into(),
                why: format!(
                    "resolution {} m and min_resolution {} m must satisfy 1e-4 ≤ min ≤ resolution ≤ 0.5",
                    opts.resolution, opts.min_resolution
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
        let mut pairs = Vec::new();
        for i in 0..bodies.len() {
            for j in i + 1..bodies.len() {
                let (a, b) = (&bodies[i], &bodies[j]);
                if !a.moving && !b.moving {
                    continue;
                }
                let allowed = match (i >= links, j >= links) {
                    (false, false) => model.acm().is_disabled(&a.name, &b.name),
                    (true, false) => touch[i - links].contains(&b.link),
                    (false, true) => touch[j - links].contains(&a.link),
                    (true, true) => a.link == b.link,
                };
                if !allowed {
                    pairs.push((i, j));
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
                cube: Shape::Box([v.size; 3]).to_parry().expect("a cube has a hull"),
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
        Ok(Checker {
            model,
            bodies,
            obstacles,
            grid,
            pairs,
            reach,
            opts,
            scratch: RefCell::new(Scratch::default()),
            counters: Counters::default(),
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

    /// The body pairs checked for self-collision, by name.
    pub fn self_pairs(&self) -> Vec<(String, String)> {
        self.pairs
            .iter()
            .map(|&(a, b)| (self.bodies[a].name.clone(), self.bodies[b].name.clone()))
            .collect()
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

    /// The first contact of the robot at `q` (exact shapes), or `None` when free. `q` must
    /// have the model's joint count (a wrong count counts as a contact of "limits").
    pub fn contact(&self, q: &[f64]) -> Option<Contact> {
        if !self.within_limits(q) {
            return Some(Contact {
                a: "joint limits".into(),
                b: format!("{q:?}"),
            });
        }
        self.check(q, 0.0, 0.0)
    }

    /// Whether `q` is within limits and free of collision.
    pub fn is_free(&self, q: &[f64]) -> bool {
        self.contact(q).is_none()
    }

    /// The contact at `q` closer than `world` (m) to the scene or `own` (m) to the robot's
    /// other links.
    fn check(&self, q: &[f64], world: f64, own: f64) -> Option<Contact> {
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
            let p = &s.poses[b.link];
            let start = s.x.len();
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
            s.ranges.push((start, s.x.len()));
            s.bounds.push(Sphere {
                centre: p * b.bound.centre,
                radius: b.bound.radius,
            });
        }
        // The world.
        for (bi, b) in self.bodies.iter().enumerate() {
            if !b.moving {
                continue;
            }
            let bound = s.bounds[bi];
            let (lo, hi) = s.ranges[bi];
            for o in &self.obstacles {
                if (bound.centre.coords - o.centre).norm() > bound.radius + o.radius + world {
                    continue;
                }
                self.counters
                    .sphere_checks
                    .fetch_add((hi - lo) as u64, Ordering::Relaxed);
                if spheres_near(
                    &o.sdf,
                    &o.inv,
                    &s.x[lo..hi],
                    &s.y[lo..hi],
                    &s.z[lo..hi],
                    &s.r[lo..hi],
                    world as f32,
                ) && exact_near(
                    &b.exact,
                    &s.poses[b.link],
                    &[(o.pose, &o.exact)],
                    world,
                    &self.counters,
                ) {
                    return Some(Contact {
                        a: b.name.clone(),
                        b: o.id.clone(),
                    });
                }
            }
            if let Some(g) = &self.grid {
                if let Some(c) = self.grid_contact(g, b, bi, s, world) {
                    return Some(c);
                }
            }
        }
        // The robot itself.
        for &(i, j) in &self.pairs {
            let (bi, bj) = (&s.bounds[i], &s.bounds[j]);
            if (bi.centre - bj.centre).norm() > bi.radius + bj.radius + own {
                continue;
            }
            let (li, hi_) = s.ranges[i];
            let (lj, hj) = s.ranges[j];
            self.counters
                .sphere_checks
                .fetch_add(((hi_ - li) * (hj - lj)) as u64, Ordering::Relaxed);
            let own32 = own as f32;
            let mut near = false;
            for k in li..hi_ {
                let (x, y, z, r) = (s.x[k], s.y[k], s.z[k], s.r[k] + own32);
                let mut any = false;
                for m in lj..hj {
                    let dx = s.x[m] - x;
                    let dy = s.y[m] - y;
                    let dz = s.z[m] - z;
                    let rr = s.r[m] + r;
                    any |= dx * dx + dy * dy + dz * dz <= rr * rr;
                }
                if any {
                    near = true;
                    break;
                }
            }
            if !near {
                continue;
            }
            let (a, b) = (&self.bodies[i], &self.bodies[j]);
            let pb = &s.poses[b.link];
            let other: Vec<(parry3d::math::Pose, &Exact)> = b
                .exact
                .iter()
                .map(|(o, e)| (convert::pose(&(pb * o)), e))
                .collect();
            if exact_near(&a.exact, &s.poses[a.link], &other, own, &self.counters) {
                return Some(Contact {
                    a: a.name.clone(),
                    b: b.name.clone(),
                });
            }
        }
        None
    }

    /// A contact of body `b` with the voxels within `margin`.
    fn grid_contact(
        &self,
        g: &Grid,
        b: &Body,
        bi: usize,
        s: &Scratch,
        margin: f64,
    ) -> Option<Contact> {
        let (lo, hi) = s.ranges[bi];
        let size = g.size as f32;
        let half = size / 2.0;
        for k in lo..hi {
            let (x, y, z) = (s.x[k], s.y[k], s.z[k]);
            let reach = s.r[k] + margin as f32;
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
                        if sdf.distance(x, y, z) > reach {
                            continue;
                        }
                        let pose = convert::pose(&Isometry3::translation(
                            f64::from(c[0]),
                            f64::from(c[1]),
                            f64::from(c[2]),
                        ));
                        if exact_near(
                            &b.exact,
                            &s.poses[b.link],
                            &[(pose, &g.cube)],
                            margin,
                            &self.counters,
                        ) {
                            return Some(Contact {
                                a: b.name.clone(),
                                b: format!("voxel [{i}, {j}, {kk}]"),
                            });
                        }
                    }
                }
            }
        }
        None
    }

    /// Whether every state on the straight joint-space edge from `a` to `b` is free. The end
    /// states themselves are checked too.
    pub fn motion_free(&self, a: &[f64], b: &[f64]) -> bool {
        if !self.within_limits(a) || !self.within_limits(b) {
            return false;
        }
        self.prove(a, b, 0.0, 1.0, self.opts.resolution)
    }

    /// Proves the edge's states for `t` in `[t0, t1]` free at resolution `res`.
    fn prove(&self, a: &[f64], b: &[f64], t0: f64, t1: f64, res: f64) -> bool {
        let span = self.motion_bound(a, b) * (t1 - t0);
        let finest = res <= self.opts.min_resolution * (1.0 + 1e-9);
        let n = ((span / res).ceil() as usize).max(1);
        let mut q = vec![0.0; a.len()];
        // Cell centres, in van der Corput order: a collision in the middle shows early.
        for k in van_der_corput(n) {
            let t = t0 + (t1 - t0) * (k as f64 + 0.5) / n as f64;
            for ((v, x), y) in q.iter_mut().zip(a).zip(b) {
                *v = x + (y - x) * t;
            }
            if finest {
                // At the finest level, cell ends (at most `res` of motion apart) are checked
                // for contact alone.
                for e in [t0 + (t1 - t0) * k as f64 / n as f64, t] {
                    for ((v, x), y) in q.iter_mut().zip(a).zip(b) {
                        *v = x + (y - x) * e;
                    }
                    if self.check(&q, 0.0, 0.0).is_some() {
                        return false;
                    }
                }
                continue;
            }
            if self.check(&q, res / 2.0, res).is_none() {
                continue;
            }
            if self.check(&q, 0.0, 0.0).is_some() {
                return false;
            }
            let c0 = t0 + (t1 - t0) * k as f64 / n as f64;
            let c1 = t0 + (t1 - t0) * (k + 1) as f64 / n as f64;
            if !self.prove(a, b, c0, c1, (res / 4.0).max(self.opts.min_resolution)) {
                return false;
            }
        }
        if finest {
            let mut q = b.to_vec();
            for ((v, x), y) in q.iter_mut().zip(a).zip(b) {
                *v = x + (y - x) * t1;
            }
            return self.check(&q, 0.0, 0.0).is_none();
        }
        true
    }
}

/// `0..n` in an order that halves the gaps (bit-reversal over the next power of two,
/// skipping values ≥ n).
fn van_der_corput(n: usize) -> Vec<usize> {
    if n <= 2 {
        return (0..n).collect();
    }
    let bits = usize::BITS - (n - 1).leading_zeros();
    (0..(1usize << bits))
        .map(|k| k.reverse_bits() >> (usize::BITS - bits))
        .filter(|&r| r < n)
        .collect()
}

/// Whether any sphere (world `x, y, z`, radius `r`) comes within `margin` of the obstacle.
#[inline]
fn spheres_near(
    sdf: &Sdf,
    inv: &[f32; 12],
    x: &[f32],
    y: &[f32],
    z: &[f32],
    r: &[f32],
    margin: f32,
) -> bool {
    let mut any = false;
    for k in 0..x.len() {
        let (wx, wy, wz) = (x[k], y[k], z[k]);
        let lx = inv[0] * wx + inv[1] * wy + inv[2] * wz + inv[9];
        let ly = inv[3] * wx + inv[4] * wy + inv[5] * wz + inv[10];
        let lz = inv[6] * wx + inv[7] * wy + inv[8] * wz + inv[11];
        any |= sdf.distance(lx, ly, lz) <= r[k] + margin;
    }
    any
}
