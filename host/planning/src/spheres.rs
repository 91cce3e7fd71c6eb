//! Conservative sphere sets: spheres whose union holds a shape, for the broad check. A grid
//! of cells over the shape's bounding box, each cell that may touch the shape covered by the
//! sphere through its corners; a sphere of the description is itself.

use nalgebra::{Isometry3, Point3, Vector3};

use crate::shape::Shape;

/// A sphere: centre (m, in the frame it is given in) and radius (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre, m.
    pub centre: Point3<f64>,
    /// Radius, m.
    pub radius: f64,
}

/// Smallest cell edge of the covering grid, m.
pub const MIN_CELL: f64 = 0.02;
/// Largest cell edge of the covering grid, m.
pub const MAX_CELL: f64 = 0.15;
/// Most cells along one axis (a 100 m shape is still covered, coarsely).
const MAX_CELLS: usize = 24;

/// Spheres (in the frame of `origin`'s parent, m) whose union holds `shape` placed at
/// `origin`. The cell edge is the shape's smallest extent, kept within
/// [[`MIN_CELL`], [`MAX_CELL`]].
pub fn cover(shape: &Shape, origin: &Isometry3<f64>) -> Vec<Sphere> {
    if let Shape::Sphere(r) = shape {
        return vec![Sphere {
            centre: origin * Point3::origin(),
            radius: *r,
        }];
    }
    let (lo, hi) = shape.bounds();
    let ext = hi - lo;
    let cell = ext.min().clamp(MIN_CELL, MAX_CELL);
    let n = ext.map(|e| ((e / cell).ceil() as usize).clamp(1, MAX_CELLS));
    let step = Vector3::new(ext.x / n.x as f64, ext.y / n.y as f64, ext.z / n.z as f64);
    let radius = step.norm() / 2.0;
    let sdf = shape.sdf();
    let mut out = Vec::new();
    for i in 0..n.x {
        for j in 0..n.y {
            for k in 0..n.z {
                let c = lo
                    + Vector3::new(
                        (i as f64 + 0.5) * step.x,
                        (j as f64 + 0.5) * step.y,
                        (k as f64 + 0.5) * step.z,
                    );
                // A cell whose centre is farther than its half-diagonal from the shape cannot
                // touch it (the signed distance never exceeds the true one).
                if f64::from(sdf.distance(c.x as f32, c.y as f32, c.z as f32)) <= radius + 1e-6 {
                    out.push(Sphere {
                        centre: origin * Point3::from(c),
                        // f32 rounding of later transforms: a hair of margin.
                        radius: radius + 1e-5,
                    });
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every point of the shape lies in some sphere.
    fn covers(shape: &Shape) {
        let spheres = cover(shape, &Isometry3::identity());
        assert!(!spheres.is_empty());
        let (lo, hi) = shape.bounds();
        let sdf = shape.sdf();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut inside = 0;
        for _ in 0..20_000 {
            let p =
                Point3::from(lo + (hi - lo).component_mul(&Vector3::from_fn(|_, _| rng.random())));
            if sdf.distance(p.x as f32, p.y as f32, p.z as f32) > 0.0 {
                continue;
            }
            inside += 1;
            assert!(
                spheres.iter().any(|s| (s.centre - p).norm() <= s.radius),
                "{shape:?}: {p} is in no sphere"
            );
        }
        assert!(inside > 1000);
    }

    #[test]
    fn the_spheres_hold_the_shapes() {
        covers(&Shape::Box([0.22, 0.05, 0.05]));
        covers(&Shape::Box([0.3, 0.3, 0.005]));
        covers(&Shape::Cylinder {
            radius: 0.177,
            length: 0.09,
        });
        covers(&Shape::Capsule {
            radius: 0.03,
            length: 0.2,
        });
    }
}
