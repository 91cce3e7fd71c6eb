//! The scene's bodies and the robot's link shapes as rapier colliders: primitives,
//! movable capsules as chains of balls, movable meshes as convex hulls, static meshes exact.

use nalgebra::Isometry3;
use rapier3d::prelude::*;

use super::{convert, BALL_SPACING, MAX_BALLS};
use crate::scene::{Body, Shape};

impl super::World {
    /// The colliders of the rigid body `rb`, in its order (any no longer in the set left
    /// out).
    pub(super) fn colliders_of<'a>(
        &'a self,
        rb: &'a RigidBody,
    ) -> impl Iterator<Item = &'a Collider> + 'a {
        rb.colliders()
            .iter()
            .filter_map(|ch| self.pw.colliders.get(*ch))
    }
}

pub(super) fn collider(b: &Body) -> Option<ColliderBuilder> {
    let f = |v: f64| v as f32;
    let upright = |c: ColliderBuilder| {
        // rapier's cylinders stand along y; the scene's along z.
        c.position(Pose::from_rotation(
            rapier3d::math::Rotation::from_rotation_x(std::f32::consts::FRAC_PI_2),
        ))
    };
    let c = match &b.shape {
        Shape::Box(s) => ColliderBuilder::cuboid(f(s[0] / 2.0), f(s[1] / 2.0), f(s[2] / 2.0)),
        Shape::Cylinder { radius, length } => {
            upright(ColliderBuilder::cylinder(f(length / 2.0), f(*radius)))
        }
        Shape::Capsule { radius, length }
            if !b.fixed && balls(f(*radius), f(*length)) <= MAX_BALLS =>
        {
            ColliderBuilder::compound(ball_chain(f(*radius), f(*length)))
        }
        Shape::Capsule { radius, length } => {
            ColliderBuilder::capsule_z(f(length / 2.0), f(*radius))
        }
        Shape::Sphere(r) => ColliderBuilder::ball(f(*r)),
        Shape::Mesh { mesh, .. } => {
            let v: Vec<Vector> = mesh.vertices.iter().map(convert::point).collect();
            if b.fixed {
                ColliderBuilder::trimesh(v, mesh.triangles.clone()).ok()?
            } else {
                ColliderBuilder::new(SharedShape::new(crate::hull::Hull::new(&v)?))
            }
        }
    };
    Some(c)
}

/// A movable capsule (along z, `length` between its end centres, m) as balls of its
/// `radius` along its axis, at most [`BALL_SPACING`] of the radius apart (the side's ripples
/// are under 1.4 % of the radius). Why: rapier's capsule lying on a box, once awake, rolls on by
/// itself and gathers speed (0.1-4 m in 20 s kept awake), while balls roll true on it.
fn ball_chain(radius: f32, length: f32) -> Vec<(Pose, SharedShape)> {
    let n = balls(radius, length) - 1;
    (0..=n)
        .map(|i| {
            let z = -length / 2.0 + length * i as f32 / n as f32;
            (
                Pose::from_translation(Vector::new(0.0, 0.0, z)),
                SharedShape::ball(radius),
            )
        })
        .collect()
}

/// How many balls [`ball_chain`] makes of a capsule (saturating for absurd ones).
fn balls(radius: f32, length: f32) -> usize {
    let gaps = (length / (BALL_SPACING * radius)).ceil();
    if gaps.is_finite() && gaps < MAX_BALLS as f32 {
        gaps.max(1.0) as usize + 1
    } else {
        usize::MAX
    }
}

pub(super) fn link_collider(s: &crate::body::LinkShape) -> Option<ColliderBuilder> {
    let body = Body {
        id: String::new(),
        shape: s.shape.clone(),
        pose: Isometry3::identity(),
        mass: 0.0,
        friction: 0.8,
        colour: [0.0; 3],
        texture: None,
        fixed: false,
    };
    let c = collider(&body)?;
    // The shape's own orientation (cylinders upright) after the link's origin.
    let own = c.position;
    Some(c.position(convert::pose(&s.origin) * own).friction(0.8))
}
