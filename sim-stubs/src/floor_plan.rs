//! A scene's ground-truth floor plan: the occupancy grid of what a base would bump into, as
//! PyRobot's LoCoBot builds its map (cells of 2 cm, obstacles from what lies 0.1–0.8 m above
//! the floor), computed from the scene's exact geometry rather than from a camera.

use crate::scene::{Body, Result, Scene, SceneError, Shape};
use nalgebra::Point3;

/// PyRobot's obstacle band: what lies this high above the floor (m) is an obstacle.
pub const OBSTACLE_BAND: [f64; 2] = [0.1, 0.8];

/// Spacing of the heights tested on each cell's centre line, m.
const DZ: f64 = 0.005;

/// An occupancy grid of the floor: cell `(i, j)` spans `origin + [i, i + 1] · resolution` in x
/// and `origin + [j, j + 1] · resolution` in y (world frame); row by row from the lowest y, x
/// fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct FloorPlan {
    /// Lower-left corner of cell (0, 0), m.
    pub origin: [f64; 2],
    /// Cell size, m.
    pub resolution: f64,
    /// Cells along x.
    pub width: usize,
    /// Cells along y.
    pub height: usize,
    /// Whether each cell holds an obstacle.
    pub occupied: Vec<bool>,
}

/// Largest floor plan, cells.
pub const MAX_CELLS: usize = 25_000_000;

impl Scene {
    /// The floor plan over the floor's extent (or, without a floor, the bodies'), cells of
    /// `resolution` m (in [0.005, 1]): a cell is occupied when a body other than the floor
    /// holds a point of its centre's vertical line between `band` heights (m above the floor;
    /// tested every 5 mm; meshes count by their bounding box). Movable objects count too
    /// unless `fixed_only`.
    pub fn floor_plan(
        &self,
        resolution: f64,
        band: [f64; 2],
        fixed_only: bool,
    ) -> Result<FloorPlan> {
        let bad = |problem: String| SceneError::Invalid {
            file: self.file.clone(),
            key: "floor plan".into(),
            problem,
        };
        if !(0.005..=1.0).contains(&resolution) {
            return Err(bad(format!(
                "resolution {resolution} m is not in [0.005, 1]"
            )));
        }
        if !(band.iter().all(|z| z.is_finite()) && band[0] <= band[1]) {
            return Err(bad(format!(
                "height band {band:?} m is not finite and ordered"
            )));
        }
        let floor = self.body("floor");
        let extent = match floor {
            Some(f) => Some(f.world_bounds()),
            None => self
                .bodies
                .iter()
                .map(Body::world_bounds)
                .reduce(|a, b| (a.0.inf(&b.0), a.1.sup(&b.1))),
        };
        let Some((lo, hi)) = extent else {
            return Err(bad("the scene has no bodies".into()));
        };
        let width = ((hi.x - lo.x) / resolution).ceil().max(1.0);
        let height = ((hi.y - lo.y) / resolution).ceil().max(1.0);
        if width * height > MAX_CELLS as f64 {
            return Err(bad(format!(
                "{width} × {height} cells, more than {MAX_CELLS}"
            )));
        }
        let (width, height) = (width as usize, height as usize);
        let mut occupied = vec![false; width * height];
        let heights: Vec<f64> = (0..=((band[1] - band[0]) / DZ).ceil() as usize)
            .map(|k| (band[0] + k as f64 * DZ).min(band[1]))
            .collect();
        for b in &self.bodies {
            if floor.is_some_and(|f| std::ptr::eq(f, b)) || (fixed_only && !b.fixed) {
                continue;
            }
            let (blo, bhi) = b.world_bounds();
            // The band's heights the body's box reaches, once per body.
            let zs: Vec<f64> = heights
                .iter()
                .copied()
                .filter(|z| (blo.z..=bhi.z).contains(z))
                .collect();
            if zs.is_empty() {
                continue;
            }
            let cell = |v: f64, o: f64, n: usize| {
                (((v - o) / resolution).floor().max(0.0) as usize).min(n - 1)
            };
            let inv = b.pose.inverse();
            for j in cell(blo.y, lo.y, height)..=cell(bhi.y, lo.y, height) {
                for i in cell(blo.x, lo.x, width)..=cell(bhi.x, lo.x, width) {
                    let (x, y) = (
                        lo.x + (i as f64 + 0.5) * resolution,
                        lo.y + (j as f64 + 0.5) * resolution,
                    );
                    let hit = zs
                        .iter()
                        .any(|&z| holds(&b.shape, &(inv * Point3::new(x, y, z))));
                    if hit {
                        occupied[j * width + i] = true;
                    }
                }
            }
        }
        Ok(FloorPlan {
            origin: [lo.x, lo.y],
            resolution,
            width,
            height,
            occupied,
        })
    }
}

/// Whether `shape` holds the point `p` of its own frame (a mesh: its bounding box).
fn holds(shape: &Shape, p: &Point3<f64>) -> bool {
    match shape {
        Shape::Box(s) => (0..3).all(|k| p[k].abs() <= s[k] / 2.0),
        Shape::Cylinder { radius, length } => {
            p.x.hypot(p.y) <= *radius && p.z.abs() <= length / 2.0
        }
        Shape::Sphere(r) => p.coords.norm() <= *r,
        Shape::Capsule { radius, length } => {
            let z = p.z.clamp(-length / 2.0, length / 2.0);
            p.x.hypot(p.y).hypot(p.z - z) <= *radius
        }
        Shape::Mesh { mesh, .. } => {
            let (lo, hi) = mesh.bounds();
            (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k])
        }
    }
}
