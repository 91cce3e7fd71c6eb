//! The world as the vectorised engine checks it: each object's signed distance in `f32`, the
//! same for every lane. Boxes, cylinders, spheres and capsules are exact; a mesh's convex
//! hull is its bounding box, a lower bound of its distance, so a sphere found clear of it is
//! clear and one that is not is inconclusive (the exact check decides).

use nalgebra::Isometry3;

use super::lane::Lane;
use super::program::ProgramSphere;
use crate::scene::PlanningScene;
use crate::shape::{box_distance, capsule_distance, cylinder_distance, to_local, Sdf, Shape};

/// One object: world to object frame (rotation rows, translation) and its signed distance.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Object {
    inv: [f32; 12],
    sdf: Sdf,
    exact: bool,
    /// Clearance kept from it, m: subtracted from its distance.
    padding: f32,
}

/// The world's objects for the vectorised engine.
#[derive(Debug, Clone, Default)]
pub struct Environment {
    objects: Vec<Object>,
    ids: Vec<String>,
}

impl Environment {
    /// The world objects of `scene` (not its attached objects, which move with the robot, nor
    /// its voxels, which the engine does not hold: see [`Environment::complete`]).
    pub fn from_scene(scene: &PlanningScene) -> Self {
        let mut env = Environment::default();
        for o in scene.objects() {
            env.push(&o.id, &o.shape, &o.pose);
        }
        env
    }

    /// Adds `shape` at `pose` (root frame).
    pub fn push(&mut self, id: &str, shape: &Shape, pose: &Isometry3<f64>) {
        self.push_padded(id, shape, pose, 0.0);
    }

    /// Adds `shape` at `pose` (root frame), its distances less `padding` (m): the room kept
    /// from it.
    pub fn push_padded(&mut self, id: &str, shape: &Shape, pose: &Isometry3<f64>, padding: f64) {
        let inv = pose.inverse();
        let m = inv.rotation.to_rotation_matrix().into_inner();
        let t = inv.translation.vector;
        let mut a = [0f32; 12];
        for (k, v) in a.iter_mut().take(9).enumerate() {
            *v = m[(k / 3, k % 3)] as f32;
        }
        a[9..].copy_from_slice(&[t.x as f32, t.y as f32, t.z as f32]);
        self.objects.push(Object {
            inv: a,
            sdf: shape.sdf(),
            exact: !matches!(shape, Shape::Hull(_)),
            padding: padding as f32,
        });
        self.ids.push(id.to_string());
    }

    /// Adds an object as the checker holds it: world to object frame `inv` (rotation rows,
    /// translation) and its signed distance.
    pub(crate) fn push_sdf(
        &mut self,
        id: &str,
        inv: [f32; 12],
        sdf: Sdf,
        exact: bool,
        padding: f64,
    ) {
        self.objects.push(Object {
            inv,
            sdf,
            exact,
            padding: padding as f32,
        });
        self.ids.push(id.to_string());
    }

    /// Objects held.
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    /// Whether it holds no object.
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// Whether every object's distance is exact (no convex hull stands in as its box).
    pub fn exact(&self) -> bool {
        self.objects.iter().all(|o| o.exact)
    }

    /// Whether the engine holds all of `scene`'s world: it holds no voxels.
    pub fn complete(scene: &PlanningScene) -> bool {
        scene.voxels().is_none()
    }

    /// The id of object `i`.
    pub fn id(&self, i: usize) -> &str {
        &self.ids[i]
    }

    /// The smallest signed distance (m) from the point `p` (root frame) to any object, per
    /// lane; `f32::MAX` without objects. Never more than the true distance.
    #[inline]
    pub fn distance<L: Lane>(&self, p: &[L; 3]) -> L {
        let mut d = L::splat(f32::MAX);
        for o in &self.objects {
            d = d.min(object_distance(o, p));
        }
        d
    }

    /// [`Environment::distance`] to object `i` alone.
    pub fn distance_to<L: Lane>(&self, i: usize, p: &[L; 3]) -> L {
        object_distance(&self.objects[i], p)
    }

    /// The least gap (m) between object `i` and the spheres about `centres` (root frame) whose
    /// radii `spheres` give, per lane: each sphere's [`Environment::distance_to`] less its
    /// radius, the shape's kind chosen once for all of them.
    #[inline(always)]
    pub fn spheres_gap<L: Lane>(
        &self,
        i: usize,
        centres: &[[L; 3]],
        spheres: &[ProgramSphere],
    ) -> L {
        let o = &self.objects[i];
        match o.sdf {
            Sdf::Box { centre, half } => gaps(o, centres, spheres, BoxSdf(centre, half)),
            Sdf::Cylinder { radius, half } => gaps(o, centres, spheres, Cylinder(radius, half)),
            Sdf::Capsule { radius, half } => gaps(o, centres, spheres, Capsule(radius, half)),
        }
    }
}

/// One kind of shape's signed distance, its parameters held (a trait rather than a closure:
/// its method is inlined wherever the AVX path needs it, `checker/lanes_avx.rs`).
trait Distance {
    fn at<L: Lane>(&self, x: L, y: L, z: L) -> L;
}

/// A box's centre and half sizes, m.
struct BoxSdf([f32; 3], [f32; 3]);
/// A cylinder's radius and half length, m.
struct Cylinder(f32, f32);
/// A capsule's radius and half length, m.
struct Capsule(f32, f32);

impl Distance for BoxSdf {
    #[inline(always)]
    fn at<L: Lane>(&self, x: L, y: L, z: L) -> L {
        box_distance(self.0, self.1, x, y, z)
    }
}

impl Distance for Cylinder {
    #[inline(always)]
    fn at<L: Lane>(&self, x: L, y: L, z: L) -> L {
        cylinder_distance(self.0, self.1, x, y, z)
    }
}

impl Distance for Capsule {
    #[inline(always)]
    fn at<L: Lane>(&self, x: L, y: L, z: L) -> L {
        capsule_distance(self.0, self.1, x, y, z)
    }
}

/// [`Environment::spheres_gap`] with the object's signed distance `sdf`: per sphere as
/// [`object_distance`] less the radius.
#[inline(always)]
fn gaps<L: Lane>(
    o: &Object,
    centres: &[[L; 3]],
    spheres: &[ProgramSphere],
    sdf: impl Distance,
) -> L {
    let mut least = L::splat(f32::MAX);
    for (c, s) in centres.iter().zip(spheres) {
        let (x, y, z) = to_local(&o.inv, c[0], c[1], c[2]);
        least = least.min(sdf.at(x, y, z) - L::splat(o.padding) - L::splat(s.radius));
    }
    least
}

#[inline(always)]
fn object_distance<L: Lane>(o: &Object, p: &[L; 3]) -> L {
    let (x, y, z) = to_local(&o.inv, p[0], p[1], p[2]);
    o.sdf.distance(x, y, z) - L::splat(o.padding)
}
