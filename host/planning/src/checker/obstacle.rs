//! What the robot is checked against, as the checker holds it: world objects (and the shapes
//! of links that do not move) with their signed distance in `f32`, their exact shape and
//! bounding box; voxels as a dense bit grid or a sorted list of cells. Poses in the robot's
//! root frame, m.

use nalgebra::Isometry3;

use crate::convert::Exact;
use crate::shape::{self, Sdf, Shape};
use crate::Result;

/// A world object (or voxel) as the checker sees it.
#[derive(Debug, Clone)]
pub(super) struct Obstacle {
    pub(super) id: String,
    pub(super) sdf: Sdf,
    /// Whether `sdf` is the shape's own signed distance (not a convex hull's bounding box).
    pub(super) exact: bool,
    /// World to object frame: rotation rows and translation, `f32`.
    pub(super) inv: [f32; 12],
    /// The exact shape and the pose of its frame.
    pub(super) placed: [(Isometry3<f64>, Exact); 1],
    /// Bounding box in the object frame: centre and half-extents, m.
    pub(super) bbox: ([f32; 3], [f32; 3]),
}

impl Obstacle {
    /// A lower bound (m) of the gap between the obstacle and the sphere at `c` (world) of
    /// radius `r`: the signed distance of the obstacle's bounding box.
    pub(super) fn coarse_gap(&self, c: &nalgebra::Point3<f64>, r: f64) -> f64 {
        let (lx, ly, lz) = shape::to_local(&self.inv, c.x as f32, c.y as f32, c.z as f32);
        let (centre, half) = self.bbox;
        f64::from(shape::box_distance(centre, half, lx, ly, lz)) - r
    }

    pub(super) fn new(id: &str, shape: &Shape, pose: &Isometry3<f64>) -> Result<Self> {
        let exact = shape.to_parry()?;
        let inv = pose.inverse();
        let r = inv.rotation.to_rotation_matrix();
        let m = r.matrix();
        let t = inv.translation.vector;
        Ok(Obstacle {
            id: id.to_string(),
            sdf: shape.sdf(),
            exact: !matches!(shape, Shape::Hull(_)),
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
pub(super) struct Grid {
    pub(super) size: f64,
    /// The cells' smallest and largest coordinates along each axis.
    lo: [i32; 3],
    hi: [i32; 3],
    pub(super) occupancy: Occupancy,
    /// A voxel, at the origin.
    pub(super) cube: [(Isometry3<f64>, Exact); 1],
}

#[derive(Debug, Clone)]
pub(super) enum Occupancy {
    Dense { dims: [usize; 3], bits: Vec<u64> },
    Sorted(Vec<[i32; 3]>),
}

impl Grid {
    /// `cells` sorted without repeats, not empty.
    pub(super) fn new(size: f64, cells: &[[i32; 3]]) -> Self {
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
    pub(super) fn column(
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
    pub(super) fn span(&self, a: usize, from: f32, to: f32) -> std::ops::RangeInclusive<i32> {
        let size = self.size as f32;
        // Saturating casts: a span far outside is clipped below.
        let first = ((from / size).floor() as i32).max(self.lo[a]);
        let last = ((to / size).floor() as i32).min(self.hi[a]);
        first..=last
    }
}
