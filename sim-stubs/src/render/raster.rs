//! Rasterising: triangles clipped at the near plane and scan-converted into the buffers of
//! 1/z and shading-record ids (top-left fill rule, no cracks along shared edges).

use nalgebra::{Matrix3, Vector3};

use super::shading::Shade;
use super::{Intr, Poses, RenderedImage, Renderer, View, NEAR};

impl Renderer {
    /// Rasterise every drawn mesh at its owner's pose (`poses`) into `out`'s buffers of 1/z
    /// and ids; the shading record of each triangle that wrote a pixel, by id. Meshes wholly
    /// behind the near plane or outside the view, and the back faces of closed meshes, are
    /// skipped. The robot's decals, when drawn, come last.
    pub(super) fn rasterise(
        &self,
        view: &View,
        poses: &Poses<'_>,
        out: &mut RenderedImage,
    ) -> Vec<Shade> {
        let (k, frustum) = (&view.k, &view.frustum);
        // Every triangle that survives culling gets a shading record; the id buffer names the
        // nearest one per pixel (deferred shading: each pixel is shaded once).
        let mut shades: Vec<Shade> = Vec::with_capacity(self.triangles());
        let first_decal = self.first_decal.min(self.meshes.len());
        let (solid, decals) = self.meshes.split_at(first_decal);
        let decals = if self.decals { decals } else { &[] };
        for (owner, m) in solid.iter().chain(&self.others).chain(decals) {
            let Some(owner_pose) = poses.of(*owner) else {
                continue;
            };
            let t = view.world_to_cam * owner_pose * m.origin;
            let rot: Matrix3<f32> = t.rotation.to_rotation_matrix().matrix().cast::<f32>();
            let tr: Vector3<f32> = t.translation.vector.cast::<f32>();
            // Meshes wholly behind the near plane or outside the view are skipped.
            let c = rot * m.centre + tr;
            if c.z + m.radius < NEAR || frustum.iter().any(|n| n.dot(&c) < -m.radius) {
                continue;
            }
            let mat = &self.materials[m.material as usize];
            for (tri, n) in m.tris.iter().zip(&m.normals) {
                let v = tri.map(|p| rot * p + tr);
                let mut nc = rot * n;
                let facing = nc.dot(&v[0]);
                if facing >= 0.0 {
                    if m.closed {
                        continue;
                    }
                    nc = -nc;
                }
                let id = shades.len() as u32;
                if !raster_clipped(k, &v, &mut out.depth, &mut out.ids, id) {
                    continue;
                }
                shades.push(Shade::new(mat, m, n, &nc, &view.sun, &rot, &tr));
            }
        }
        shades
    }
}

/// Clip a camera-frame triangle at the near plane and rasterise the pieces; true if any
/// pixel was written.
fn raster_clipped(
    k: &Intr,
    v: &[Vector3<f32>; 3],
    inv_depth: &mut [f32],
    ids: &mut [u32],
    id: u32,
) -> bool {
    let inside = v.map(|p| p.z >= NEAR);
    if inside.iter().all(|&i| i) {
        return raster(k, v, inv_depth, ids, id);
    }
    if !inside.iter().any(|&i| i) {
        return false;
    }
    // Sutherland-Hodgman against z = NEAR: at most a quad.
    let mut poly: [Vector3<f32>; 4] = [Vector3::zeros(); 4];
    let mut n = 0;
    for i in 0..3 {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        let (ia, ib) = (a.z >= NEAR, b.z >= NEAR);
        if ia {
            poly[n] = a;
            n += 1;
        }
        if ia != ib {
            // From the nearer end, so that the triangle on the other side of a shared edge
            // (which runs it the other way) gets the same point.
            let (p0, p1) = if a.z < b.z { (a, b) } else { (b, a) };
            let t = (NEAR - p0.z) / (p1.z - p0.z);
            let mut p = p0 + (p1 - p0) * t;
            p.z = NEAR;
            poly[n] = p;
            n += 1;
        }
    }
    let first = raster(k, &[poly[0], poly[1], poly[2]], inv_depth, ids, id);
    let second = n == 4 && raster(k, &[poly[0], poly[2], poly[3]], inv_depth, ids, id);
    first || second
}

/// Rasterise a triangle in front of the near plane: every pixel centre inside it (top-left
/// fill rule) nearer than the buffer of 1/z gets its 1/z and `id`; true if any did.
///
/// Edge functions and 1/z are affine in the pixel coordinates. Each row's span is solved from
/// the edge functions; an edge shared by two triangles gets the same (negated) coefficients
/// in both, so the fill rule leaves no crack and no overlap along it.
fn raster(
    k: &Intr,
    v: &[Vector3<f32>; 3],
    inv_depth: &mut [f32],
    ids: &mut [u32],
    id: u32,
) -> bool {
    let s = v.map(|p| {
        let iz = 1.0 / p.z;
        (k.fx * p.x * iz + k.cx, k.fy * p.y * iz + k.cy, iz)
    });
    let area = (s[1].0 - s[0].0) * (s[2].1 - s[0].1) - (s[1].1 - s[0].1) * (s[2].0 - s[0].0);
    if !area.is_finite() || area.abs() < 1e-12 {
        return false;
    }
    let (a, b, c) = if area > 0.0 {
        (s[0], s[1], s[2])
    } else {
        (s[0], s[2], s[1])
    };
    let xmin = a.0.min(b.0).min(c.0).ceil().max(0.0);
    let xmax = a.0.max(b.0).max(c.0).floor().min(k.w as f32 - 1.0);
    let ymin = a.1.min(b.1).min(c.1).ceil().max(0.0);
    let ymax = a.1.max(b.1).max(c.1).floor().min(k.h as f32 - 1.0);
    if xmin > xmax || ymin > ymax {
        return false;
    }
    // Edge from q0 to q1: e(x, y) = dx (y - y0) - dy (x - x0) = ex x + ey y + e0, positive
    // inside; on an edge a pixel belongs to the triangle only for top or left edges. The
    // coefficients are computed from the edge's lower endpoint (in (y, x) order), so the two
    // triangles sharing an edge get exactly opposite ones.
    let edge = |q0: (f32, f32, f32), q1: (f32, f32, f32)| {
        let (dx, dy) = (q1.0 - q0.0, q1.1 - q0.1);
        let top_left = (dy == 0.0 && dx < 0.0) || dy > 0.0;
        let e0 = if (q0.1, q0.0) <= (q1.1, q1.0) {
            dy * q0.0 - dx * q0.1
        } else {
            -((-dy) * q1.0 - (-dx) * q1.1)
        };
        (-dy, dx, e0, top_left)
    };
    let es = [edge(b, c), edge(c, a), edge(a, b)];
    // 1/z = (e_bc a.iz + e_ca b.iz + e_ab c.iz) / area, affine too.
    let inv = 1.0 / area.abs();
    let zx = (es[0].0 * a.2 + es[1].0 * b.2 + es[2].0 * c.2) * inv;
    let zy = (es[0].1 * a.2 + es[1].1 * b.2 + es[2].1 * c.2) * inv;
    let z0 = (es[0].2 * a.2 + es[1].2 * b.2 + es[2].2 * c.2) * inv;
    let (ymin, ymax) = (ymin as usize, ymax as usize);
    let mut any = false;
    for y in ymin..=ymax {
        let fy = y as f32;
        // The row's span: each edge bounds x from one side (e = ex x + c >= 0).
        let (mut lo, mut hi) = (xmin as i64, xmax as i64);
        for &(ex, ey, e0, tl) in &es {
            let c = ey * fy + e0;
            if ex > 0.0 {
                // Clamped far beyond any image, so that the integer steps cannot overflow.
                let t = (-c / ex).clamp(-1e9, 1e9);
                let xs = if tl { ceil_i64(t) } else { floor_i64(t) + 1 };
                lo = lo.max(xs);
            } else if ex < 0.0 {
                let t = (-c / ex).clamp(-1e9, 1e9);
                let xe = if tl { floor_i64(t) } else { ceil_i64(t) - 1 };
                hi = hi.min(xe);
            } else if c < 0.0 || (c == 0.0 && !tl) {
                hi = lo - 1;
            }
        }
        if lo > hi {
            continue;
        }
        let (lo, hi) = (lo as usize, hi as usize);
        let row = y * k.w;
        let iz0 = zx * lo as f32 + zy * fy + z0;
        let zs = &mut inv_depth[row + lo..=row + hi];
        let is = &mut ids[row + lo..=row + hi];
        let mut wrote = 0u32;
        // Branch-free, so that it vectorises: 1/z at the span's i-th pixel from its start; the
        // id and 1/z go in through a mask (a select would be turned back into a branch).
        for (i, (zb, ib)) in (0i32..).zip(zs.iter_mut().zip(is.iter_mut())) {
            let iz = iz0 + zx * i as f32;
            let mask = 0u32.wrapping_sub(u32::from(iz > *zb));
            *zb = f32::from_bits(zb.to_bits() ^ ((zb.to_bits() ^ iz.to_bits()) & mask));
            *ib ^= (*ib ^ id) & mask;
            wrote |= mask;
        }
        let wrote = wrote != 0;
        any |= wrote;
    }
    any
}

/// floor(t) without a libm call (saturating beyond the i64 range, 0 for NaN).
fn floor_i64(t: f32) -> i64 {
    let i = t as i64;
    i - i64::from((i as f32) > t)
}

/// ceil(t) without a libm call (saturating beyond the i64 range, 0 for NaN).
fn ceil_i64(t: f32) -> i64 {
    let i = t as i64;
    i + i64::from((i as f32) < t)
}
