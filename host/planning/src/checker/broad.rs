//! The broad phase: each body's conservative spheres placed in the world (`f32`, padded to
//! [`LANES`] in structure-of-arrays form) and their smallest gap (m) to an obstacle's signed
//! distance or to another body's spheres, in loops the compiler vectorises.

use nalgebra::Isometry3;

use crate::coarse::{FAR, LANES};
use crate::shape::{self, Sdf};
use crate::spheres::Sphere;

/// World spheres of every body: x, y, z, radius (`f32`), at the checker's layout (each
/// body's spheres padded to [`LANES`] with far spheres of no radius, whose gaps are huge and
/// never the smallest); a body's are placed the first time a state needs them.
#[derive(Debug, Default)]
pub(super) struct Placed {
    pub(super) x: Vec<f32>,
    pub(super) y: Vec<f32>,
    pub(super) z: Vec<f32>,
    pub(super) r: Vec<f32>,
    ready: Vec<bool>,
}

impl Placed {
    /// Forgets every placement: a new state.
    pub(super) fn reset(&mut self, layout: &[(usize, usize, usize)]) {
        let n = layout.last().map_or(0, |l| l.2);
        if self.x.len() != n {
            for v in [&mut self.x, &mut self.y, &mut self.z] {
                v.clear();
                v.resize(n, FAR);
            }
            self.r.clear();
            self.r.resize(n, 0.0);
        }
        self.ready.clear();
        self.ready.resize(layout.len(), false);
    }

    /// Places body `bi`'s spheres (`spheres` in its link's frame, the link at `pose`) at
    /// `range`, unless they are already.
    pub(super) fn place(
        &mut self,
        bi: usize,
        spheres: &[Sphere],
        pose: &Isometry3<f64>,
        range: (usize, usize, usize),
    ) {
        if self.ready[bi] {
            return;
        }
        self.ready[bi] = true;
        let m = pose.rotation.to_rotation_matrix();
        let m = m.matrix();
        let t = pose.translation.vector;
        for (k, sp) in (range.0..range.1).zip(spheres) {
            let c = m * sp.centre.coords + t;
            self.x[k] = c.x as f32;
            self.y[k] = c.y as f32;
            self.z[k] = c.z as f32;
            self.r[k] = sp.radius as f32;
        }
    }
}

/// The smallest of `LANES` running minima (a select, not `f32::min`, so the lanes vectorise).
#[inline(always)]
fn lanes_min(m: [f32; LANES]) -> f32 {
    m.iter()
        .fold(f32::INFINITY, |a, &b| if b < a { b } else { a })
}

/// The smallest of `d(local point) − r` over spheres in chunks of [`LANES`]; `d` is the
/// obstacle's signed distance in its frame, reached through `inv` (world to object).
#[inline(always)]
fn lanes_gap<F: Fn(f32, f32, f32) -> f32>(
    inv: &[f32; 12],
    x: &[f32],
    y: &[f32],
    z: &[f32],
    r: &[f32],
    d: F,
) -> f32 {
    let mut m = [f32::INFINITY; LANES];
    for (((x, y), z), r) in x
        .chunks_exact(LANES)
        .zip(y.chunks_exact(LANES))
        .zip(z.chunks_exact(LANES))
        .zip(r.chunks_exact(LANES))
    {
        for l in 0..LANES {
            let (lx, ly, lz) = shape::to_local(inv, x[l], y[l], z[l]);
            let g = d(lx, ly, lz) - r[l];
            m[l] = if g < m[l] { g } else { m[l] };
        }
    }
    lanes_min(m)
}

/// The smallest gap (m, negative inside) between any sphere (world `x, y, z`, radius `r`,
/// padded to [`LANES`]) and the obstacle: one loop per kind of shape, so each vectorises.
#[inline]
pub(super) fn spheres_gap(
    sdf: &Sdf,
    inv: &[f32; 12],
    x: &[f32],
    y: &[f32],
    z: &[f32],
    r: &[f32],
) -> f32 {
    match *sdf {
        Sdf::Box { centre, half } => lanes_gap(inv, x, y, z, r, |lx, ly, lz| {
            shape::box_distance(centre, half, lx, ly, lz)
        }),
        Sdf::Cylinder { radius, half } => lanes_gap(inv, x, y, z, r, |lx, ly, lz| {
            shape::cylinder_distance(radius, half, lx, ly, lz)
        }),
        Sdf::Capsule { radius, half } => lanes_gap(inv, x, y, z, r, |lx, ly, lz| {
            shape::capsule_distance(radius, half, lx, ly, lz)
        }),
    }
}

/// A body's spheres: x, y, z, radius (m).
type SphereSlices<'a> = (&'a [f32], &'a [f32], &'a [f32], &'a [f32]);

/// The smallest gap (m) between sphere `a` and the spheres `b` (padded to [`LANES`]).
#[inline]
pub(super) fn sphere_spheres_gap(a: (f32, f32, f32, f32), b: SphereSlices<'_>) -> f32 {
    let (x, y, z, r) = a;
    let mut m = [f32::INFINITY; LANES];
    for (((bx, by), bz), br) in
        b.0.chunks_exact(LANES)
            .zip(b.1.chunks_exact(LANES))
            .zip(b.2.chunks_exact(LANES))
            .zip(b.3.chunks_exact(LANES))
    {
        for l in 0..LANES {
            let dx = bx[l] - x;
            let dy = by[l] - y;
            let dz = bz[l] - z;
            let g = (dx * dx + dy * dy + dz * dz).sqrt() - br[l] - r;
            m[l] = if g < m[l] { g } else { m[l] };
        }
    }
    lanes_min(m)
}
