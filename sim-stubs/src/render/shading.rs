//! Shading: each pixel coloured once from the record of the triangle it shows (flat light
//! from ambient, a sun and a headlight, times the colour or the texture), and 1/z turned into
//! depth.

use nalgebra::{Matrix3, Vector3};

use super::textures::{noise_table, texture_colour, texture_units, NOISE_SIZE};
use super::{DrawMesh, Intr, Material, RenderedImage, Renderer};
use crate::scene::Texture;

impl Renderer {
    /// The shading pass over `out`, whose ids name records of `shades` (`k`: the intrinsics):
    /// labels, depth (z from 1/z; 0 where nothing was hit) and colour (the background there).
    pub(super) fn shade(&self, shades: &[Shade], k: &Intr, out: &mut RenderedImage) {
        let (w, h) = (k.w, k.h);
        let bg = self.background.map(to_u8);
        let mut scratch = Scratch {
            indices: vec![0; w],
            palette_of: vec![u32::MAX; shades.len()],
            palettes: Vec::new(),
        };
        for r in 0..h {
            let row = r * w;
            let ry = (r as f32 - k.cy) / k.fy;
            let ids = &out.ids[row..row + w];
            let mut x = 0;
            while x < w {
                // One run of pixels showing the same triangle is shaded at a time.
                let id = ids[x];
                let end = run_end(ids, x);
                let span = row + x..row + end;
                let depth = &mut out.depth[span.clone()];
                let labels = &mut out.labels[span.clone()];
                let rgb = &mut out.rgb[3 * span.start..3 * span.end];
                match shades.get(id as usize) {
                    None => {
                        depth.fill(0.0);
                        labels.fill(0);
                        for p in rgb.chunks_exact_mut(3) {
                            p.copy_from_slice(&bg);
                        }
                    }
                    Some(sh) => {
                        labels.fill(sh.label);
                        // The buffer held 1/z while rasterising.
                        for d in depth.iter_mut() {
                            *d = 1.0 / *d;
                        }
                        self.shade_run(sh, id, k, x, ry, depth, rgb, &mut scratch);
                    }
                }
                x = end;
            }
        }
    }

    /// Colour one run of pixels of one triangle, starting at column `x0` of the row at
    /// normalised height `ry`, from their depths.
    #[allow(clippy::too_many_arguments)]
    fn shade_run(
        &self,
        sh: &Shade,
        id: u32,
        k: &Intr,
        x0: usize,
        ry: f32,
        depth: &[f32],
        rgb: &mut [u8],
        scratch: &mut Scratch,
    ) {
        let mat = &self.materials[sh.material as usize];
        let Some(tex) = &mat.texture else {
            for p in rgb.chunks_exact_mut(3) {
                p.copy_from_slice(&sh.rgb);
            }
            return;
        };
        // Texture coordinates are affine in the camera-frame point p = z (rx, ry, 1) with
        // rx = (x - cx) / fx: u = z (ua x + ub) + a0, v likewise.
        let coeffs = |a: &[f32; 3]| (a[0] / k.fx, a[1] * ry + a[2] - a[0] * k.cx / k.fx);
        let ((ua, ub), (va, vb)) = (coeffs(&sh.a), coeffs(&sh.b));
        let x0 = x0 as i32;
        let uv = |i: i32, z: f32| {
            let x = (x0 + i) as f32;
            (z * (ua * x + ub) + sh.a0, z * (va * x + vb) + sh.b0)
        };
        match tex {
            Texture::Noise { .. } => {
                let t = noise_table();
                let palette = scratch.palette(id, sh);
                // First the table's indices (a loop that vectorises), then the look-ups.
                let indices = &mut scratch.indices[..depth.len()];
                let mask = NOISE_SIZE as u32 - 1;
                for (i, (ix, &z)) in (0..).zip(indices.iter_mut().zip(depth)) {
                    let (u, v) = uv(i, z);
                    *ix = (floor_bits(v) & mask) * NOISE_SIZE as u32 + (floor_bits(u) & mask);
                }
                let palette = &scratch.palettes[palette];
                for (p, &ix) in rgb.chunks_exact_mut(3).zip(indices.iter()) {
                    p.copy_from_slice(&palette[usize::from(t[ix as usize])]);
                }
            }
            Texture::Checker { .. } => {
                let (c1, c2) = (sh.c1.map(to_u8_255), (sh.c1, sh.dc));
                let c2 = [0, 1, 2].map(|c| to_u8_255(c2.0[c] + c2.1[c] * 255.0));
                for (i, (p, &z)) in (0..).zip(rgb.chunks_exact_mut(3).zip(depth)) {
                    let (u, v) = uv(i, z);
                    let odd = floor_bits(u).wrapping_add(floor_bits(v)) & 1 != 0;
                    p.copy_from_slice(if odd { &c2 } else { &c1 });
                }
            }
            _ => {
                for (i, (p, &z)) in (0..).zip(rgb.chunks_exact_mut(3).zip(depth)) {
                    let (u, v) = uv(i, z);
                    let c = texture_colour(tex, mat.colour, u, v);
                    for ch in 0..3 {
                        p[ch] = to_u8(c[ch] * sh.light);
                    }
                }
            }
        }
    }
}

/// Where the run of equal ids starting at `x` ends (exclusive).
fn run_end(ids: &[u32], x: usize) -> usize {
    let id = ids[x];
    let mut end = x + 1;
    // Eight at a time first (a comparison that vectorises).
    while let Some(chunk) = ids.get(end..end + 8) {
        if !chunk.iter().fold(true, |same, &i| same & (i == id)) {
            break;
        }
        end += 8;
    }
    while end < ids.len() && ids[end] == id {
        end += 1;
    }
    end
}

/// The shading pass's scratch: a row of noise-table indices, and the noise texture's colours
/// per shading record, made when the record is first shaded.
struct Scratch {
    indices: Vec<u32>,
    /// Index into `palettes` per shading record (`u32::MAX`: none yet).
    palette_of: Vec<u32>,
    /// Entry n: the colour at the noise table's value n.
    palettes: Vec<[[u8; 3]; 256]>,
}

impl Scratch {
    /// The palette of shading record `id`, made now if it has none yet.
    fn palette(&mut self, id: u32, sh: &Shade) -> usize {
        let slot = &mut self.palette_of[id as usize];
        if *slot == u32::MAX {
            *slot = self.palettes.len() as u32;
            self.palettes.push(std::array::from_fn(|n| {
                [0, 1, 2].map(|c| to_u8_255(sh.c1[c] + sh.dc[c] * n as f32))
            }));
        }
        *slot as usize
    }
}

/// floor(x) in the low bits (two's complement) for |x| < 2^21: x - 1/2 rounded to an integer
/// by adding 1.5 * 2^23, which leaves no fraction bits (ties, at integers, may go either way).
fn floor_bits(x: f32) -> u32 {
    const MAGIC: f32 = 12_582_912.0;
    (x - 0.5 + MAGIC).to_bits()
}

/// A colour channel 0-255 as 8 bits.
fn to_u8_255(x: f32) -> u8 {
    (x.clamp(0.0, 255.0) + 0.5) as u8
}

/// A colour channel 0-1 as 8 bits.
fn to_u8(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// How one drawn triangle is shaded.
pub(super) struct Shade {
    /// Lit colour without texture.
    rgb: [u8; 3],
    /// Light factor.
    light: f32,
    material: u32,
    /// The lit colour, 0-255 per channel, and the step towards the texture's second colour
    /// per step of the noise table ((second - first) / 255).
    c1: [f32; 3],
    dc: [f32; 3],
    /// Texture coordinates in the texture's units (see [`texture_units`]): u = a . p + a0,
    /// v = b . p + b0 for a camera-frame point p.
    a: [f32; 3],
    a0: f32,
    b: [f32; 3],
    b0: f32,
    label: u32,
}

impl Shade {
    /// The record of a triangle of mesh `m` (material `mat`) with normal `n` in the mesh's
    /// frame and `nc` in the optical frame (facing the camera), lit by the sun towards `sun`
    /// (optical frame); `rot`, `tr`: the mesh's frame in the optical frame.
    pub(super) fn new(
        mat: &Material,
        m: &DrawMesh,
        n: &Vector3<f32>,
        nc: &Vector3<f32>,
        sun: &Vector3<f32>,
        rot: &Matrix3<f32>,
        tr: &Vector3<f32>,
    ) -> Shade {
        // Flat shading: ambient, sun, and a headlight along the optical axis.
        let view = -Vector3::z();
        let light = 0.35 + 0.45 * nc.dot(sun).max(0.0) + 0.3 * nc.dot(&view).max(0.0);
        // The texture's plane: the mesh-frame axes across the dominant axis of the
        // normal, as camera-frame rows (u = a . p + a0).
        let (ia, ib) = if n.x.abs() >= n.y.abs() && n.x.abs() >= n.z.abs() {
            (1, 2)
        } else if n.y.abs() >= n.z.abs() {
            (0, 2)
        } else {
            (0, 1)
        };
        let rt = rot.transpose();
        let (ra, rb): (Vector3<f32>, Vector3<f32>) =
            (rt.row(ia).transpose(), rt.row(ib).transpose());
        let units = mat.texture.as_ref().map_or(1.0, texture_units);
        let second = match &mat.texture {
            Some(Texture::Checker { colour, .. } | Texture::Noise { colour, .. }) => *colour,
            _ => mat.colour,
        };
        let c1 = mat.colour.map(|c| c * light * 255.0);
        Shade {
            rgb: mat.colour.map(|c| to_u8(c * light)),
            light,
            material: m.material,
            c1,
            dc: [0, 1, 2].map(|i| (second[i] * light * 255.0 - c1[i]) / 255.0),
            a: (ra * units).into(),
            a0: -ra.dot(tr) * units,
            b: (rb * units).into(),
            b0: -rb.dot(tr) * units,
            label: m.label,
        }
    }
}
