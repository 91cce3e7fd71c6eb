//! The robot's collision model: each link's collision shapes from the URDF (primitives; meshes
//! as the convex hull of their vertices), a conservative sphere set per link, which links move
//! with the planned joints, and how far any of their points can move for a joint step.

use std::path::{Path, PathBuf};

use ferrobot_description::RobotConfig;
use ferrobot_kinematics::{pose_from_urdf, JointType, LinkTree};
use nalgebra::{Isometry3, Point3};

use crate::acm::SelfCollisionMatrix;
use crate::convert::{self, Exact};
use crate::shape::Shape;
use crate::spheres::{self, Sphere};
use crate::{Error, Result};

/// Largest mesh file read, bytes.
pub const MAX_MESH_BYTES: u64 = 64 << 20;

/// One link's geometry.
#[derive(Debug, Clone)]
pub struct LinkGeometry {
    /// URDF name.
    pub name: String,
    /// Collision shapes and their poses in the link frame.
    pub shapes: Vec<(Isometry3<f64>, Shape)>,
    /// Spheres (link frame) whose union holds every shape.
    pub spheres: Vec<Sphere>,
    /// A sphere (link frame) that holds every sphere of the set.
    pub bound: Sphere,
    /// The exact shapes: parry's shape frame in the link frame, and the shape.
    pub(crate) exact: Vec<(Isometry3<f64>, Exact)>,
}

impl LinkGeometry {
    /// The geometry of `shapes` (poses in the link frame).
    pub fn new(name: &str, shapes: Vec<(Isometry3<f64>, Shape)>) -> Result<Self> {
        let mut exact = Vec::with_capacity(shapes.len());
        let mut spheres = Vec::new();
        for (origin, shape) in &shapes {
            shape.validate(&format!("collision shape of {name}"))?;
            let e = shape.to_parry()?;
            exact.push((origin * e.correction, e));
            spheres.extend(spheres::cover(shape, origin));
        }
        let bound = bounding_sphere(&spheres);
        Ok(LinkGeometry {
            name: name.to_string(),
            shapes,
            spheres,
            bound,
            exact,
        })
    }

    /// Whether the link has any collision shape.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }
}

/// A sphere that holds `spheres` (about their centroid; radius 0 at the origin when empty).
pub(crate) fn bounding_sphere(spheres: &[Sphere]) -> Sphere {
    if spheres.is_empty() {
        return Sphere {
            centre: Point3::origin(),
            radius: 0.0,
        };
    }
    let c = spheres
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, s| a + s.centre.coords)
        / spheres.len() as f64;
    let c = Point3::from(c);
    let radius = spheres
        .iter()
        .map(|s| (s.centre - c).norm() + s.radius)
        .fold(0.0, f64::max);
    Sphere { centre: c, radius }
}

/// The robot's collision model for planning some of its joints.
#[derive(Debug, Clone)]
pub struct CollisionModel {
    name: String,
    tree: LinkTree,
    links: Vec<LinkGeometry>,
    /// [`LinkTree::joints`] index of each planned joint.
    planned: Vec<usize>,
    joint_names: Vec<String>,
    limits: Vec<(f64, f64)>,
    /// Every tree joint's range (URDF limits; ±π for continuous joints; planned joints' given
    /// limits).
    all_limits: Vec<(f64, f64)>,
    /// Every tree joint's value while planning (planned ones overwritten per state).
    values: Vec<f64>,
    moving: Vec<bool>,
    /// The links the planned joints move, parents first.
    moved: Vec<usize>,
    acm: SelfCollisionMatrix,
    urdf_file: Option<PathBuf>,
}

fn invalid(what: impl Into<String>, why: impl Into<String>) -> Error {
    Error::Invalid {
        what: what.into(),
        why: why.into(),
    }
}

/// The vertices of a mesh file (OBJ or STL), scaled, m.
fn mesh_points(path: &Path, scale: [f64; 3]) -> Result<Vec<Point3<f64>>> {
    let what = format!("mesh {}", path.display());
    let bytes = ferrobot_description::read_bytes(path, MAX_MESH_BYTES)
        .map_err(|e| invalid(&what, e.to_string()))?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let raw: Vec<[f64; 3]> = match ext.as_deref() {
        Some("obj") => {
            let (models, _) = tobj::load_obj_buf(
                &mut std::io::Cursor::new(&bytes),
                &tobj::LoadOptions::default(),
                |_| Err(tobj::LoadError::OpenFileFailed),
            )
            .map_err(|e| invalid(&what, e.to_string()))?;
            models
                .iter()
                .flat_map(|m| {
                    m.mesh
                        .positions
                        .chunks_exact(3)
                        .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
                })
                .collect()
        }
        Some("stl") => {
            let mesh = stl_io::read_stl(&mut std::io::Cursor::new(&bytes))
                .map_err(|e| invalid(&what, e.to_string()))?;
            mesh.vertices
                .iter()
                .map(|v| [f64::from(v[0]), f64::from(v[1]), f64::from(v[2])])
                .collect()
        }
        _ => return Err(invalid(&what, "only .obj and .stl meshes are read")),
    };
    Ok(raw
        .into_iter()
        .map(|p| Point3::new(p[0] * scale[0], p[1] * scale[1], p[2] * scale[2]))
        .collect())
}

/// A mesh's file: `package://NAME/rest` and `file://` prefixes dropped, relative to `dir`.
fn mesh_path(filename: &str, dir: Option<&Path>) -> PathBuf {
    let rest = if let Some(r) = filename.strip_prefix("package://") {
        r.split_once('/').map_or(r, |(_, rest)| rest)
    } else {
        filename.strip_prefix("file://").unwrap_or(filename)
    };
    let p = PathBuf::from(rest);
    match dir {
        Some(d) if p.is_relative() => d.join(p),
        _ => p,
    }
}

/// Each link's shapes from a URDF's `<collision>` elements; meshes are read relative to `dir`.
pub fn urdf_geometry(urdf: &urdf_rs::Robot, dir: Option<&Path>) -> Result<Vec<LinkGeometry>> {
    let tree = LinkTree::from_urdf(urdf).map_err(|e| invalid("URDF", e.to_string()))?;
    tree.links()
        .map(|name| {
            let link = urdf.links.iter().find(|l| l.name == name);
            let mut shapes = Vec::new();
            for c in link.map(|l| l.collision.as_slice()).unwrap_or_default() {
                let shape = match &c.geometry {
                    urdf_rs::Geometry::Box { size } => Shape::Box([size[0], size[1], size[2]]),
                    urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
                        radius: *radius,
                        length: *length,
                    },
                    urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
                        radius: *radius,
                        length: *length,
                    },
                    urdf_rs::Geometry::Sphere { radius } => Shape::Sphere(*radius),
                    urdf_rs::Geometry::Mesh { filename, scale } => {
                        let s = scale.map_or([1.0; 3], |s| [s[0], s[1], s[2]]);
                        Shape::Hull(mesh_points(&mesh_path(filename, dir), s)?)
                    }
                };
                shapes.push((pose_from_urdf(&c.origin), shape));
            }
            LinkGeometry::new(name, shapes)
        })
        .collect()
}

/// Each link's shapes from a robot configuration's URDF (meshes read beside the
/// configuration file), in the URDF tree's link order.
pub fn config_geometry(cfg: &RobotConfig) -> Result<Vec<LinkGeometry>> {
    urdf_geometry(&cfg.urdf, config_dir(cfg))
}

/// Where a configuration's meshes are read from: its file's folder (none for a bundled robot).
fn config_dir(cfg: &RobotConfig) -> Option<&Path> {
    cfg.file
        .parent()
        .filter(|_| !cfg.file.starts_with("<bundled>"))
}

impl CollisionModel {
    /// The model of `urdf` for planning `joints` (URDF names, in path order) within `limits`
    /// (rad or m, one `(min, max)` per joint); meshes are read relative to `dir`. The
    /// self-collision matrix is `acm`, or computed by sampling when `None`.
    pub fn new(
        name: &str,
        urdf: &urdf_rs::Robot,
        joints: &[String],
        limits: &[(f64, f64)],
        dir: Option<&Path>,
        acm: Option<SelfCollisionMatrix>,
    ) -> Result<Self> {
        let tree = LinkTree::from_urdf(urdf).map_err(|e| invalid("URDF", e.to_string()))?;
        if joints.is_empty() || joints.len() != limits.len() {
            return Err(invalid(
                "planned joints",
                format!("{} joints and {} limits", joints.len(), limits.len()),
            ));
        }
        let mut planned = Vec::with_capacity(joints.len());
        for (j, &(lo, hi)) in joints.iter().zip(limits) {
            let i = tree
                .joint_index(j)
                .ok_or_else(|| invalid("planned joints", format!("{j:?} is no movable joint")))?;
            if planned.contains(&i) {
                return Err(invalid("planned joints", format!("{j:?} twice")));
            }
            if !(lo.is_finite()
                && hi.is_finite()
                && lo < hi
                && hi - lo <= 4.0 * std::f64::consts::PI)
            {
                return Err(invalid(
                    format!("limits of {j}"),
                    format!("[{lo}, {hi}] is not a finite range of at most 4π"),
                ));
            }
            planned.push(i);
        }
        let links = urdf_geometry(urdf, dir)?;
        let n = links.len();
        let moved = tree.links_moved_by(&planned);
        let mut moving = vec![false; n];
        for &l in &moved {
            moving[l] = true;
        }
        let all_limits = tree
            .joints()
            .iter()
            .enumerate()
            .map(|(i, j)| {
                if let Some(k) = planned.iter().position(|&p| p == i) {
                    return limits[k];
                }
                let u = urdf.joints.iter().find(|u| u.name == j.name);
                match u {
                    Some(u) if matches!(u.joint_type, urdf_rs::JointType::Continuous) => {
                        (-std::f64::consts::PI, std::f64::consts::PI)
                    }
                    Some(u)
                        if u.limit.lower.is_finite()
                            && u.limit.upper.is_finite()
                            && u.limit.lower <= u.limit.upper =>
                    {
                        (u.limit.lower, u.limit.upper)
                    }
                    _ => (0.0, 0.0),
                }
            })
            .collect();
        let mut model = CollisionModel {
            all_limits,
            name: name.to_string(),
            values: vec![0.0; tree.joints().len()],
            tree,
            links,
            planned,
            joint_names: joints.to_vec(),
            limits: limits.to_vec(),
            moving,
            moved,
            acm: SelfCollisionMatrix::default(),
            urdf_file: None,
        };
        model.acm = match acm {
            Some(a) => a,
            None => SelfCollisionMatrix::compute(&model, crate::acm::DEFAULT_SAMPLES, 1),
        };
        Ok(model)
    }

    /// The model of a robot's arm: its arm joints within their limits, the fingers and other
    /// joints at 0 until [`CollisionModel::set_value`], the stored self-collision matrix
    /// (`[collision]` of its configuration) or one computed by sampling.
    pub fn from_config(cfg: &RobotConfig) -> Result<Self> {
        let arm = cfg
            .arm
            .as_ref()
            .ok_or_else(|| invalid("robot", format!("{} has no arm", cfg.name)))?;
        let limits = arm
            .joints
            .iter()
            .map(|n| {
                cfg.joint_index(n)
                    .map(|i| {
                        let l = cfg.joints[i].limits;
                        (f64::from(l.min), f64::from(l.max))
                    })
                    .ok_or_else(|| invalid("arm joints", format!("{n:?} not in the joint table")))
            })
            .collect::<Result<Vec<_>>>()?;
        let dir = config_dir(cfg);
        let acm = cfg
            .collision
            .as_ref()
            .map(|c| SelfCollisionMatrix::from_entries(&c.disabled));
        let mut m = CollisionModel::new(&cfg.name, &cfg.urdf, &arm.joints, &limits, dir, acm)?;
        m.urdf_file = dir.map(|d| d.join(&cfg.urdf_file));
        Ok(m)
    }

    /// Robot name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The URDF file the model came from, when it came from a file (not a bundled robot).
    pub fn urdf_file(&self) -> Option<&Path> {
        self.urdf_file.as_deref()
    }

    /// The link tree.
    pub fn tree(&self) -> &LinkTree {
        &self.tree
    }

    /// Every link's geometry, in [`LinkTree::links`] order.
    pub fn links(&self) -> &[LinkGeometry] {
        &self.links
    }

    /// Index of a link by name.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.tree.link_index(name)
    }

    /// Number of planned joints.
    pub fn dof(&self) -> usize {
        self.planned.len()
    }

    /// Planned joint names, in path order.
    pub fn joint_names(&self) -> &[String] {
        &self.joint_names
    }

    /// Limits of the planned joints, rad or m.
    pub fn limits(&self) -> &[(f64, f64)] {
        &self.limits
    }

    /// Every movable joint's range ([`LinkTree::joints`] order): planned joints' limits, the
    /// URDF's for the others (±π for continuous joints).
    pub fn all_limits(&self) -> Vec<(f64, f64)> {
        self.all_limits.clone()
    }

    /// Whether link `i` moves with the planned joints.
    pub fn is_moving(&self, i: usize) -> bool {
        self.moving.get(i).copied().unwrap_or(false)
    }

    /// Lets links `a` and `b` touch (adds the pair to the self-collision matrix as touching by
    /// default).
    pub fn allow_pair(&mut self, a: &str, b: &str) {
        self.acm.allow(a, b);
    }

    /// The self-collision matrix.
    pub fn acm(&self) -> &SelfCollisionMatrix {
        &self.acm
    }

    /// Sets the value (rad or m) a joint that is not planned keeps while planning (a finger,
    /// the head): within the joint's limits (a joint whose range is a whole turn, as a
    /// continuous joint's, takes any angle, wrapped into it). Unknown names, planned joints,
    /// non-finite values and values beyond the limits are errors that change nothing.
    pub fn set_value(&mut self, joint: &str, value: f64) -> Result<()> {
        let i = self.unplanned(joint)?;
        let (lo, hi) = self.all_limits[i];
        let v = if Self::whole_turn((lo, hi)) && value.is_finite() && value.abs() <= 1e6 {
            ferrobot_geometry::wrap(value)
        } else {
            value
        };
        if !(v.is_finite() && lo - 1e-9 <= v && v <= hi + 1e-9) {
            return Err(invalid(
                format!("value of {joint}"),
                format!("{value} is not within its limits [{lo}, {hi}]"),
            ));
        }
        self.values[i] = v.clamp(lo, hi);
        Ok(())
    }

    /// [`CollisionModel::set_value`] for a measured value, which may sit a little past a
    /// limit (a servo's overshoot, a finger's encoder): held to the limits rather than
    /// refused. Only a non-finite value is an error.
    pub fn set_measured_value(&mut self, joint: &str, value: f64) -> Result<()> {
        let i = self.unplanned(joint)?;
        if !value.is_finite() {
            return Err(invalid(format!("value of {joint}"), format!("{value}")));
        }
        let (lo, hi) = self.all_limits[i];
        let held = if Self::whole_turn((lo, hi)) {
            ferrobot_geometry::wrap(value.clamp(-1e6, 1e6))
        } else {
            value.clamp(lo, hi)
        };
        self.set_value(joint, held)
    }

    /// The tree index of `joint`, a movable joint that is not planned.
    fn unplanned(&self, joint: &str) -> Result<usize> {
        let i = self
            .tree
            .joint_index(joint)
            .ok_or_else(|| invalid("joint", format!("{joint:?} is no movable joint")))?;
        if self.planned.contains(&i) {
            return Err(invalid("joint", format!("{joint:?} is planned")));
        }
        Ok(i)
    }

    /// Whether a range is a whole turn, [−π, π] (a continuous joint's here).
    fn whole_turn((lo, hi): (f64, f64)) -> bool {
        lo == -std::f64::consts::PI && hi == std::f64::consts::PI
    }

    /// The values of the joints that are not planned, by name.
    pub fn fixed_values(&self) -> Vec<(String, f64)> {
        self.tree
            .joints()
            .iter()
            .enumerate()
            .filter(|(i, _)| !self.planned.contains(i))
            .map(|(i, j)| (j.name.clone(), self.values[i]))
            .collect()
    }

    /// Every tree joint's value for planned joint values `q`.
    pub fn tree_values(&self, q: &[f64]) -> Vec<f64> {
        let mut v = self.values.clone();
        for (&i, &x) in self.planned.iter().zip(q) {
            v[i] = x;
        }
        v
    }

    /// Every tree joint's value for planned values `q`, into `out`.
    pub(crate) fn tree_values_into(&self, q: &[f64], out: &mut Vec<f64>) {
        out.clear();
        out.extend_from_slice(&self.values);
        for (&i, &x) in self.planned.iter().zip(q) {
            out[i] = x;
        }
    }

    /// Pose of every link in the root frame for planned joint values `q`, into `poses`:
    /// only the links the planned joints move are computed when `poses` already holds every
    /// link's pose from an earlier call (the other links never move), and none when that call
    /// was for the same `q` (an edge's start is measured right after the edge is begun there).
    /// `values` holds the tree's joint values of the last call.
    pub(crate) fn link_poses_into(
        &self,
        q: &[f64],
        values: &mut Vec<f64>,
        poses: &mut Vec<Isometry3<f64>>,
    ) {
        let complete = poses.len() == self.links.len() && values.len() == self.values.len();
        if complete
            && q.len() == self.planned.len()
            && self.planned.iter().zip(q).all(|(&i, &x)| values[i] == x)
        {
            return;
        }
        self.tree_values_into(q, values);
        if complete {
            self.tree.update_poses(values, &self.moved, poses);
        } else {
            self.tree.poses_into(values, poses);
        }
    }

    /// Pose of every link in the root frame for planned joint values `q`.
    pub fn link_poses(&self, q: &[f64]) -> Vec<Isometry3<f64>> {
        self.tree.poses(&self.tree_values(q))
    }

    /// For each planned joint, the largest of [`CollisionModel::link_reach`] over the links it
    /// carries and `extra` spheres (link index, spheres in that link's frame): a step Δq moves
    /// no point more than Σ |Δqᵢ|·reachᵢ.
    pub fn reach(&self, extra: &[(usize, Vec<Sphere>)]) -> Vec<f64> {
        self.largest(extra, |l, s| self.link_reach(l, s))
    }

    /// The arm's size (m): the largest bound on a moving point's distance from a planned
    /// joint's origin (`origin_reach`), with `extra` spheres as
    /// [`CollisionModel::reach`] takes them.
    pub fn span(&self, extra: &[(usize, Vec<Sphere>)]) -> f64 {
        self.largest(extra, |l, s| self.origin_reach(l, s))
            .into_iter()
            .fold(0.0, f64::max)
    }

    /// For each planned joint, the largest of `bound(link, spheres)` over the links and their
    /// `extra` spheres.
    fn largest(
        &self,
        extra: &[(usize, Vec<Sphere>)],
        bound: impl Fn(usize, &[Sphere]) -> Vec<f64>,
    ) -> Vec<f64> {
        let mut out = vec![0.0f64; self.planned.len()];
        for l in 0..self.links.len() {
            let spheres: Vec<Sphere> = self.links[l]
                .spheres
                .iter()
                .copied()
                .chain(
                    extra
                        .iter()
                        .filter(|(el, _)| *el == l)
                        .flat_map(|(_, s)| s.iter().copied()),
                )
                .collect();
            for (o, r) in out.iter_mut().zip(bound(l, &spheres)) {
                *o = o.max(r);
            }
        }
        out
    }

    /// For each planned joint, a bound (m) on how far a unit step of it moves any point of
    /// `spheres` (in link `link`'s frame) when the joint carries the link, else 0: for a
    /// revolute joint the points' distance from its axis, for a prismatic one 1. A step Δq
    /// moves no point of them more than Σ |Δqᵢ|·reachᵢ, in the world and in the frame of any
    /// link above the joints.
    ///
    /// The smaller of two bounds: the distance from the joint's origin along the chain
    /// (`origin_reach`) and the distance from its axis
    /// (`axis_reach`), which is much smaller where the link lies along the
    /// axis (a wrist's roll: the LoCoBot's gripper 0.103 → 0.055 m, its fingers 0.109 →
    /// 0.018 m) or beside it (Sawyer's `right_l1` about its own joint 0.300 → 0.117 m).
    pub fn link_reach(&self, link: usize, spheres: &[Sphere]) -> Vec<f64> {
        let origin = self.origin_reach(link, spheres);
        self.planned
            .iter()
            .zip(&origin)
            .map(|(&j, &r)| {
                self.axis_reach(link, spheres, j, &origin)
                    .map_or(r, |a| a.min(r))
            })
            .collect()
    }

    /// A bound (m) on the distance from revolute joint `j`'s axis of any point of `spheres`
    /// (in link `link`'s frame) when `j` carries the link; `None` when it does not apply
    /// (`j` prismatic or not above the link, or a prismatic planned joint between them).
    ///
    /// The chain from the link up to `j` is rigid except at planned joints. Where none lies
    /// between, the spheres' distance from the axis is fixed: the bound is exact. Where some
    /// do, let `k` be the one nearest `j`: `k`'s origin is fixed relative to `j`'s axis, and
    /// every point below `k` is within `origin[k]` of that origin (the origin bound), so the
    /// bound is the origin's distance from the axis plus `origin[k]` (the triangle
    /// inequality).
    fn axis_reach(&self, link: usize, spheres: &[Sphere], j: usize, origin: &[f64]) -> Option<f64> {
        let joint = &self.tree.joints()[j];
        if joint.kind != JointType::Revolute {
            return None;
        }
        // Points with radii, in the frame of link `at`: the spheres, or the origin of the
        // nearest planned joint passed, with its bound.
        let mut points: Vec<(Point3<f64>, f64)> =
            spheres.iter().map(|s| (s.centre, s.radius)).collect();
        let mut at = link;
        loop {
            let lj = self.tree.link_joint(at);
            if lj == Some(j) {
                let a = joint.axis;
                let far = points.iter().fold(0.0f64, |m, (p, r)| {
                    let v = p.coords;
                    m.max((v - a * v.dot(&a)).norm() + r)
                });
                // Rounding of the chain's products: a nanometre and a part in 10⁹.
                return Some(far * (1.0 + 1e-9) + 1e-9);
            }
            if let Some(k) = lj {
                if let Some(pk) = self.planned.iter().position(|&p| p == k) {
                    if self.tree.joints()[k].kind != JointType::Revolute {
                        return None;
                    }
                    // Everything below is within `origin[pk]` of k's origin.
                    points = vec![(Point3::origin(), origin[pk])];
                } else {
                    // A joint not planned: rigid at its value.
                    let v = self.values[k];
                    let m = match self.tree.joints()[k].kind {
                        JointType::Revolute => Isometry3::rotation(self.tree.joints()[k].axis * v),
                        JointType::Prismatic => {
                            let a = self.tree.joints()[k].axis * v;
                            Isometry3::translation(a.x, a.y, a.z)
                        }
                    };
                    for (p, _) in &mut points {
                        *p = m * *p;
                    }
                }
            }
            let o = self
                .tree
                .link_origin(at)
                .unwrap_or_else(Isometry3::identity);
            for (p, _) in &mut points {
                *p = o * *p;
            }
            at = self.tree.parent(at)?;
        }
    }

    /// [`CollisionModel::link_reach`]'s bound from each joint's origin: the norms of the
    /// joint offsets from the link up to the joint (and prismatic travel) plus the spheres'
    /// extent in the link's frame.
    fn origin_reach(&self, link: usize, spheres: &[Sphere]) -> Vec<f64> {
        let extent = spheres
            .iter()
            .map(|s| s.centre.coords.norm() + s.radius)
            .fold(0.0, f64::max);
        self.planned
            .iter()
            .map(|&j| {
                // The path from `link` up to the joint's link: its joint offsets (and
                // prismatic travel) bound how far `link`'s frame is from the joint's origin.
                let mut at = link;
                let mut offset = 0.0;
                loop {
                    if self.tree.link_joint(at) == Some(j) {
                        return if self.tree.joints()[j].kind == JointType::Prismatic {
                            1.0
                        } else {
                            offset + extent
                        };
                    }
                    offset += self
                        .tree
                        .link_origin(at)
                        .map_or(0.0, |o| o.translation.vector.norm());
                    if let Some(jj) = self.tree.link_joint(at) {
                        if self.tree.joints()[jj].kind == JointType::Prismatic {
                            offset += match self.planned.iter().position(|&p| p == jj) {
                                Some(k) => self.limits[k].0.abs().max(self.limits[k].1.abs()),
                                None => self.values[jj].abs(),
                            };
                        }
                    }
                    match self.tree.parent(at) {
                        Some(p) => at = p,
                        None => return 0.0,
                    }
                }
            })
            .collect()
    }

    /// The exact shapes of link `l` placed at `pose`: parry pose and shape.
    pub(crate) fn exact_at<'a>(
        &'a self,
        l: usize,
        pose: &'a Isometry3<f64>,
    ) -> impl Iterator<Item = (parry3d::math::Pose, &'a Exact)> + 'a {
        self.links[l]
            .exact
            .iter()
            .map(move |(o, e)| (convert::pose(&(pose * o)), e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrobot_description::RobotConfig;

    /// At random states of both bundled arms, no sphere of a moving link reaches farther from
    /// a revolute planned joint's axis than the link's reach for that joint; and the axis
    /// bound is attained (within 1 mm, so it is exact where no planned joint lies between)
    /// for the LoCoBot's gripper about its wrist's roll, where it is half the origin bound.
    #[test]
    fn reach_bounds_every_sphere_from_each_axis() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for robot in ["locobot", "sawyer"] {
            let cfg = RobotConfig::bundled(robot).expect("robot");
            let model = CollisionModel::from_config(&cfg).expect("model");
            let reach: Vec<Vec<f64>> = (0..model.links().len())
                .map(|l| model.link_reach(l, &model.links()[l].spheres))
                .collect();
            let mut seen = vec![vec![0.0f64; model.dof()]; model.links().len()];
            for _ in 0..400 {
                let q: Vec<f64> = model
                    .limits()
                    .iter()
                    .map(|&(lo, hi)| rng.random_range(lo..=hi))
                    .collect();
                let poses = model.link_poses(&q);
                for (k, &j) in model.planned.iter().enumerate() {
                    let lj = (0..poses.len())
                        .find(|&l| model.tree().link_joint(l) == Some(j))
                        .expect("joint's link");
                    let axis = poses[lj].rotation * model.tree().joints()[j].axis;
                    let o = poses[lj].translation.vector;
                    for (l, link) in model.links().iter().enumerate() {
                        for s in &link.spheres {
                            let v = (poses[l] * s.centre).coords - o;
                            let d = (v - axis * v.dot(&axis)).norm() + s.radius;
                            if reach[l][k] == 0.0 {
                                continue;
                            }
                            assert!(
                                d <= reach[l][k] + 1e-9,
                                "{robot} {}: {d} m from joint {k}'s axis, reach {}",
                                link.name,
                                reach[l][k]
                            );
                            seen[l][k] = seen[l][k].max(d);
                        }
                    }
                }
            }
            if robot == "locobot" {
                let g = model.link_index("gripper_link").expect("gripper");
                let roll = model.dof() - 1;
                assert!((seen[g][roll] - reach[g][roll]).abs() < 1e-3);
                let origin = model.origin_reach(g, &model.links()[g].spheres);
                assert!(reach[g][roll] < 0.6 * origin[roll], "{reach:?}");
            }
        }
    }

    /// A joint that is not planned takes values within its limits only, as the problems
    /// files' `fixed_joints` give them (a LoCoBot finger at 12 m was accepted); a whole-turn
    /// joint any angle, wrapped; measured values are held to the limits. Refusals change
    /// nothing. Every bundled robot's unplanned joints start within their limits, so an
    /// export's `fixed_joints` read back.
    #[test]
    fn unplanned_joints_keep_values_within_their_limits() {
        for robot in ["locobot", "locobot_lite", "sawyer"] {
            let cfg = RobotConfig::bundled(robot).expect(robot);
            let mut model = CollisionModel::from_config(&cfg).expect("model");
            let fixed = model.fixed_values();
            assert!(!fixed.is_empty(), "{robot}");
            for (name, v) in &fixed {
                let i = model.tree.joint_index(name).expect("joint");
                let (lo, hi) = model.all_limits[i];
                assert!(
                    lo <= *v && *v <= hi,
                    "{robot} {name}: {v} not in [{lo}, {hi}]"
                );
                model.set_value(name, *v).expect("its own value");
            }
        }
        let cfg = RobotConfig::bundled("locobot").expect("locobot");
        let mut model = CollisionModel::from_config(&cfg).expect("model");
        // A finger (prismatic, its URDF's range [0, 1] m).
        let finger = "joint_7".to_string();
        let i = model.tree.joint_index(&finger).expect("joint");
        let (lo, hi) = model.all_limits[i];
        assert_eq!((lo, hi), (0.0, 1.0));
        model.set_value(&finger, hi).expect("its limit");
        for bad in [12.0, hi + 1e-3, lo - 1e-3, f64::NAN, f64::INFINITY] {
            let err = model.set_value(&finger, bad).expect_err("refused");
            assert!(err.to_string().contains(&finger), "{err}");
            assert_eq!(model.values[i], hi, "{bad}");
        }
        model.set_measured_value(&finger, hi + 1e-3).expect("held");
        assert_eq!(model.values[i], hi);
        model.set_measured_value(&finger, -5.0).expect("held");
        assert_eq!(model.values[i], lo);
        assert!(model.set_measured_value(&finger, f64::NAN).is_err());
        assert!(model.set_value("joint_1", 0.0).is_err(), "planned");
        assert!(model.set_value("no_such_joint", 0.0).is_err());
        // A whole-turn range (the wheels are continuous) takes any angle, wrapped into it.
        model.set_value("wheel_left_joint", 7.0).expect("any angle");
        let w = model.tree.joint_index("wheel_left_joint").expect("wheel");
        assert!((model.values[w] - (7.0 - 2.0 * std::f64::consts::PI)).abs() < 1e-12);
    }

    /// Poses into reused buffers equal poses computed afresh, whether the joint values change,
    /// repeat (nothing recomputed) or come back.
    #[test]
    fn poses_into_reused_buffers_follow_every_change() {
        let cfg = RobotConfig::bundled("sawyer").expect("sawyer");
        let model = CollisionModel::from_config(&cfg).expect("model");
        let dof = model.dof();
        let q1: Vec<f64> = (0..dof).map(|i| 0.1 * i as f64 - 0.2).collect();
        let mut q2 = q1.clone();
        q2[dof - 1] += 0.3;
        q2[0] -= 0.5;
        let (mut values, mut poses) = (Vec::new(), Vec::new());
        for q in [&q1, &q2, &q2, &q1, &q1, &q2] {
            model.link_poses_into(q, &mut values, &mut poses);
            let fresh = model.link_poses(q);
            assert_eq!(poses.len(), fresh.len());
            for (a, b) in poses.iter().zip(&fresh) {
                assert!((a.translation.vector - b.translation.vector).norm() < 1e-12);
                assert!(a.rotation.angle_to(&b.rotation) < 1e-9);
            }
        }
        // Not vacuous: the two settings put some link elsewhere.
        let (p1, p2) = (model.link_poses(&q1), model.link_poses(&q2));
        assert!(p1
            .iter()
            .zip(&p2)
            .any(|(a, b)| (a.translation.vector - b.translation.vector).norm() > 0.05));
    }
}
