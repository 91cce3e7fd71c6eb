//! Collision shapes in their own frame, as the description and the planning scene give them,
//! with the two things the checker needs of each: a signed distance from a point (the broad
//! check, `f32`) and the exact shape for parry3d (made in the `convert` module).

use crate::lanes::Lane;
use crate::{Error, Result};
use nalgebra::{Point3, Vector3};

/// Largest size of any shape or object, m: anything larger is a typing error.
pub const MAX_SIZE: f64 = 100.0;
/// Smallest size of any shape, m.
pub const MIN_SIZE: f64 = 1e-4;
/// Largest distance of an object from the robot's root, m.
pub const MAX_DISTANCE: f64 = 1000.0;

/// A shape centred on its frame's origin (cylinders and capsules along z).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Full extents along x, y, z, m.
    Box([f64; 3]),
    /// Radius and length along z, m.
    Cylinder {
        /// Radius, m.
        radius: f64,
        /// Length, m.
        length: f64,
    },
    /// Radius, m.
    Sphere(f64),
    /// Radius and length of the straight part along z, m.
    Capsule {
        /// Radius, m.
        radius: f64,
        /// Length of the cylinder between the half-spheres, m.
        length: f64,
    },
    /// The convex hull of points (a mesh's vertices), m.
    Hull(Vec<Point3<f64>>),
}

fn size(what: &str, name: &str, v: f64) -> Result<()> {
    if !v.is_finite() || !(MIN_SIZE..=MAX_SIZE).contains(&v) {
        return Err(Error::Invalid {
            what: what.to_string(),
            why: format!("{name} {v} m is not within [{MIN_SIZE}, {MAX_SIZE}] m"),
        });
    }
    Ok(())
}

impl Shape {
    /// The scene file's name of the shape.
    pub fn kind(&self) -> &'static str {
        match self {
            Shape::Box(_) => "box",
            Shape::Cylinder { .. } => "cylinder",
            Shape::Sphere(_) => "sphere",
            Shape::Capsule { .. } => "capsule",
            Shape::Hull(_) => "mesh",
        }
    }

    /// Checks sizes (finite, within [[`MIN_SIZE`], [`MAX_SIZE`]]) and that a hull has volume;
    /// `what` names the shape in the error.
    pub fn validate(&self, what: &str) -> Result<()> {
        match self {
            Shape::Box(s) => {
                for (axis, &v) in ["x size", "y size", "z size"].iter().zip(s) {
                    size(what, axis, v)?;
                }
            }
            Shape::Cylinder { radius, length } | Shape::Capsule { radius, length } => {
                size(what, "radius", *radius)?;
                size(what, "length", *length)?;
            }
            Shape::Sphere(r) => size(what, "radius", *r)?,
            Shape::Hull(points) => {
                if points.iter().any(|p| {
                    p.coords
                        .iter()
                        .any(|v| !v.is_finite() || v.abs() > MAX_SIZE)
                }) {
                    return Err(Error::Invalid {
                        what: what.to_string(),
                        why: format!("a hull point is not finite or beyond {MAX_SIZE} m"),
                    });
                }
                let (lo, hi) = self.bounds();
                let e = self.to_parry().ok();
                let volume = e.map_or(0.0, |e| e.shape.mass_properties(1.0).mass());
                (volume > 1e-12 && (hi - lo).min() >= MIN_SIZE)
                    .then_some(())
                    .ok_or(())
                    .map_err(|_| Error::Invalid {
                        what: what.to_string(),
                        why: "the points have no convex hull with volume".into(),
                    })?;
            }
        }
        Ok(())
    }

    /// Lowest and highest corner of the shape's bounding box in its own frame, m.
    pub fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        let h = match self {
            Shape::Box(s) => Vector3::new(s[0], s[1], s[2]) / 2.0,
            Shape::Cylinder { radius, length } => Vector3::new(*radius, *radius, length / 2.0),
            Shape::Sphere(r) => Vector3::repeat(*r),
            Shape::Capsule { radius, length } => {
                Vector3::new(*radius, *radius, length / 2.0 + radius)
            }
            Shape::Hull(points) => {
                let mut lo = Vector3::repeat(f64::INFINITY);
                let mut hi = Vector3::repeat(f64::NEG_INFINITY);
                for p in points {
                    lo = lo.inf(&p.coords);
                    hi = hi.sup(&p.coords);
                }
                if points.is_empty() {
                    return (Vector3::zeros(), Vector3::zeros());
                }
                return (lo, hi);
            }
        };
        (-h, h)
    }

    /// Radius of a sphere about the frame's origin that holds the shape, m.
    pub fn bounding_radius(&self) -> f64 {
        match self {
            Shape::Sphere(r) => *r,
            Shape::Capsule { radius, length } => radius + length / 2.0,
            Shape::Hull(points) => points.iter().map(|p| p.coords.norm()).fold(0.0, f64::max),
            _ => {
                let (lo, hi) = self.bounds();
                lo.abs().sup(&hi.abs()).norm()
            }
        }
    }

    /// The broad-check form of the shape: enough to compute a signed distance from a point
    /// (exact for primitives, the bounding box for hulls).
    pub(crate) fn sdf(&self) -> Sdf {
        match self {
            Shape::Box(s) => Sdf::Box {
                centre: [0.0; 3],
                half: [s[0] as f32 / 2.0, s[1] as f32 / 2.0, s[2] as f32 / 2.0],
            },
            Shape::Cylinder { radius, length } => Sdf::Cylinder {
                radius: *radius as f32,
                half: *length as f32 / 2.0,
            },
            Shape::Sphere(r) => Sdf::Capsule {
                radius: *r as f32,
                half: 0.0,
            },
            Shape::Capsule { radius, length } => Sdf::Capsule {
                radius: *radius as f32,
                half: *length as f32 / 2.0,
            },
            Shape::Hull(_) => {
                let (lo, hi) = self.bounds();
                let c = (lo + hi) / 2.0;
                let h = (hi - lo) / 2.0;
                Sdf::Box {
                    centre: [c.x as f32, c.y as f32, c.z as f32],
                    half: [h.x as f32, h.y as f32, h.z as f32],
                }
            }
        }
    }
}

/// A shape as the broad check sees it: a signed distance from a point in the shape's frame
/// that never exceeds the true one (so a sphere found clear is clear).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Sdf {
    /// A box of half-extents `half` about `centre`, m.
    Box { centre: [f32; 3], half: [f32; 3] },
    /// A cylinder along z.
    Cylinder { radius: f32, half: f32 },
    /// A capsule along z (a sphere when `half` is 0).
    Capsule { radius: f32, half: f32 },
}

impl Sdf {
    /// Signed distance of point `(x, y, z)` (shape frame, m) from the surface; negative
    /// inside.
    #[inline(always)]
    pub(crate) fn distance<L: Lane>(&self, x: L, y: L, z: L) -> L {
        match *self {
            Sdf::Box { centre, half } => box_distance(centre, half, x, y, z),
            Sdf::Cylinder { radius, half } => cylinder_distance(radius, half, x, y, z),
            Sdf::Capsule { radius, half } => capsule_distance(radius, half, x, y, z),
        }
    }
}

// Each signed distance is written once over `Lane`: for one `f32` (the checker's loops over
// spheres, which vectorise: `Lane`'s max and min on `f32` are selects, not `f32::max`/`min`,
// whose NaN rules would keep them from it) and for the vectorised engine's lanes
// (`crate::lanes`), which check many configurations at once.

/// [`Sdf::Box`]'s signed distance.
#[inline(always)]
pub(crate) fn box_distance<L: Lane>(centre: [f32; 3], half: [f32; 3], x: L, y: L, z: L) -> L {
    let zero = L::splat(0.0);
    let qx = (x - L::splat(centre[0])).abs() - L::splat(half[0]);
    let qy = (y - L::splat(centre[1])).abs() - L::splat(half[1]);
    let qz = (z - L::splat(centre[2])).abs() - L::splat(half[2]);
    let (ox, oy, oz) = (qx.max(zero), qy.max(zero), qz.max(zero));
    (ox * ox + oy * oy + oz * oz).sqrt() + qx.max(qy).max(qz).min(zero)
}

/// [`Sdf::Cylinder`]'s signed distance.
#[inline(always)]
pub(crate) fn cylinder_distance<L: Lane>(radius: f32, half: f32, x: L, y: L, z: L) -> L {
    let zero = L::splat(0.0);
    let dr = (x * x + y * y).sqrt() - L::splat(radius);
    let dz = z.abs() - L::splat(half);
    let (or, oz) = (dr.max(zero), dz.max(zero));
    (or * or + oz * oz).sqrt() + dr.max(dz).min(zero)
}

/// [`Sdf::Capsule`]'s signed distance.
#[inline(always)]
pub(crate) fn capsule_distance<L: Lane>(radius: f32, half: f32, x: L, y: L, z: L) -> L {
    let dz = z - z.max(L::splat(-half)).min(L::splat(half));
    (x * x + y * y + dz * dz).sqrt() - L::splat(radius)
}

/// Point `(x, y, z)` (world, m) in the frame whose world-to-frame transform is `inv`
/// (rotation rows, then translation).
#[inline(always)]
pub(crate) fn to_local<L: Lane>(inv: &[f32; 12], x: L, y: L, z: L) -> (L, L, L) {
    let m: [L; 12] = crate::lanes::splat_all(inv);
    (
        m[0] * x + m[1] * y + m[2] * z + m[9],
        m[3] * x + m[4] * y + m[5] * z + m[10],
        m[6] * x + m[7] * y + m[8] * z + m[11],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signed_distances_of_the_primitives() {
        let b = Shape::Box([0.2, 0.4, 0.6]).sdf();
        assert!((b.distance(0.3, 0.0, 0.0) - 0.2).abs() < 1e-6);
        assert!((b.distance(0.0, 0.0, 0.0) + 0.1).abs() < 1e-6);
        assert!((b.distance(0.2, 0.3, 0.0) - (0.01f32 + 0.01).sqrt()).abs() < 1e-6);
        let c = Shape::Cylinder {
            radius: 0.1,
            length: 0.4,
        }
        .sdf();
        assert!((c.distance(0.3, 0.0, 0.0) - 0.2).abs() < 1e-6);
        assert!((c.distance(0.0, 0.0, 0.5) - 0.3).abs() < 1e-6);
        let s = Shape::Capsule {
            radius: 0.05,
            length: 0.2,
        }
        .sdf();
        assert!((s.distance(0.0, 0.0, 0.25) - 0.1).abs() < 1e-6);
        assert!((s.distance(0.15, 0.0, 0.05) - 0.1).abs() < 1e-6);
    }

    #[test]
    fn hostile_sizes_are_refused() {
        for bad in [f64::NAN, f64::INFINITY, -1.0, 0.0, 1e9] {
            assert!(Shape::Box([bad, 1.0, 1.0]).validate("box").is_err());
            assert!(Shape::Sphere(bad).validate("ball").is_err());
            assert!(Shape::Cylinder {
                radius: 0.1,
                length: bad
            }
            .validate("can")
            .is_err());
        }
        let flat = Shape::Hull(vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
        ]);
        assert!(flat.validate("flat").is_err());
        assert!(Shape::Hull(vec![]).validate("empty").is_err());
    }
}
