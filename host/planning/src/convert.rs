//! The one place where nalgebra's `f64` types meet parry3d's `f32` glam types.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use parry3d::math::{Pose, Rotation, Vector};
use parry3d::shape::SharedShape;

use crate::shape::Shape;
use crate::{Error, Result};

/// An exact shape for parry3d and the pose of parry's shape frame in ours (parry's cylinders
/// run along y, ours along z).
#[derive(Clone)]
pub(crate) struct Exact {
    /// The shape.
    pub shape: SharedShape,
    /// Parry's shape frame in our shape frame.
    pub correction: Isometry3<f64>,
    /// The shape's bounding box in parry's shape frame: centre and half-extents, m (the
    /// checker's separating-axis bound takes it).
    pub bbox: (Vector3<f64>, Vector3<f64>),
    /// Whether the shape is its bounding box (a box): the separating-axis test is then exact.
    pub is_box: bool,
    /// For spheres, capsules and cylinders: the half-axis (m, in parry's shape frame) and the
    /// radius of the capsule that holds the shape, and whether the shape is that capsule.
    pub capsule: Option<(Vector3<f64>, f64, bool)>,
}

impl std::fmt::Debug for Exact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Exact")
            .field("shape", &self.shape.shape_type())
            .finish()
    }
}

/// A vector (m) for parry.
pub(crate) fn vector(v: &Vector3<f64>) -> Vector {
    Vector::new(v.x as f32, v.y as f32, v.z as f32)
}

/// A pose for parry.
pub(crate) fn pose(p: &Isometry3<f64>) -> Pose {
    let q = p.rotation.quaternion();
    Pose::from_parts(
        vector(&p.translation.vector),
        Rotation::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32).normalize(),
    )
}

/// The parry shape of `s`; `None` for a hull without volume.
pub(crate) fn shape(s: &Shape) -> Option<Exact> {
    let none = Isometry3::identity();
    let (shape, correction) = match s {
        Shape::Box(e) => (
            SharedShape::cuboid(e[0] as f32 / 2.0, e[1] as f32 / 2.0, e[2] as f32 / 2.0),
            none,
        ),
        Shape::Sphere(r) => (SharedShape::ball(*r as f32), none),
        Shape::Capsule { radius, length } => (
            SharedShape::capsule_z(*length as f32 / 2.0, *radius as f32),
            none,
        ),
        Shape::Cylinder { radius, length } => (
            SharedShape::cylinder(*length as f32 / 2.0, *radius as f32),
            // Parry's y axis onto our z axis.
            Isometry3::from_parts(
                Default::default(),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2),
            ),
        ),
        Shape::Hull(points) => {
            let pts: Vec<Vector> = points.iter().map(|p| vector(&p.coords)).collect();
            (SharedShape::convex_hull(&pts)?, none)
        }
    };
    // The shape's own bounds, with parry's cylinder axis (y) for ours (z).
    let (lo, hi) = s.bounds();
    let (mut c, mut h) = ((lo + hi) / 2.0, (hi - lo) / 2.0);
    if matches!(s, Shape::Cylinder { .. }) {
        c.swap_rows(1, 2);
        h.swap_rows(1, 2);
    }
    let bbox = (c, h);
    Some(Exact {
        shape,
        correction,
        bbox,
        is_box: matches!(s, Shape::Box(_)),
        capsule: match s {
            Shape::Sphere(r) => Some((Vector3::zeros(), *r, true)),
            Shape::Capsule { radius, length } => {
                Some((Vector3::new(0.0, 0.0, length / 2.0), *radius, true))
            }
            // Along parry's y.
            Shape::Cylinder { radius, length } => {
                Some((Vector3::new(0.0, length / 2.0, 0.0), *radius, false))
            }
            _ => None,
        },
    })
}

impl Shape {
    /// The exact shape for parry3d, in the shape's frame (cylinders turned from parry's y
    /// axis to our z axis by [`shape`]).
    pub(crate) fn to_parry(&self) -> Result<Exact> {
        shape(self).ok_or_else(|| Error::Invalid {
            what: "shape".into(),
            why: "no convex hull".into(),
        })
    }
}
