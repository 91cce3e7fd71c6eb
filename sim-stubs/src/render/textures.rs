//! Surface textures: procedural patterns (checker, tiles, value noise baked into a table) and
//! images, sampled at planar coordinates of the body's frame in the texture's units.

use crate::scene::Texture;

/// A cheap integer hash to [0, 1).
fn hash2(x: i32, y: i32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343) ^ (y as u32).wrapping_mul(0xd816_3841);
    h ^= h >> 13;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    (h & 0xff_ffff) as f32 / 16_777_216.0
}

/// Texels per noise cell of the baked noise table.
const NOISE_TEXELS: usize = 8;

/// Side of the baked noise table, texels (a power of two): it repeats every
/// `NOISE_SIZE / NOISE_TEXELS` = 128 cells, far beyond what one view shows.
pub(super) const NOISE_SIZE: usize = 1024;

/// Two octaves of value noise, tileable, baked once (a lookup per pixel instead of eight
/// hashes).
pub(super) fn noise_table() -> &'static [u8] {
    static TABLE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let cells = (NOISE_SIZE / NOISE_TEXELS) as i32;
        let mut t = vec![0u8; NOISE_SIZE * NOISE_SIZE];
        for y in 0..NOISE_SIZE {
            for x in 0..NOISE_SIZE {
                let (u, v) = (
                    x as f32 / NOISE_TEXELS as f32,
                    y as f32 / NOISE_TEXELS as f32,
                );
                let n = 0.6 * value_noise(u, v, cells) + 0.4 * value_noise(u * 4.0, v * 4.0, cells);
                t[y * NOISE_SIZE + x] = (n * 255.0) as u8;
            }
        }
        t
    })
}

/// Smooth value noise in [0, 1), repeating every `period` cells.
fn value_noise(x: f32, y: f32, period: i32) -> f32 {
    let (xi, yi) = (floor_i(x), floor_i(y));
    let (fx, fy) = (x - xi as f32, y - yi as f32);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let h = |i: i32, j: i32| hash2(i.rem_euclid(period), j.rem_euclid(period));
    let a = h(xi, yi);
    let b = h(xi + 1, yi);
    let c = h(xi, yi + 1);
    let d = h(xi + 1, yi + 1);
    let top = a + (b - a) * sx;
    let bottom = c + (d - c) * sx;
    top + (bottom - top) * sy
}

fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * t)
}

/// floor(x) for |x| < 2^31 without a libm call.
fn floor_i(x: f32) -> i32 {
    let i = x as i32;
    i - i32::from((i as f32) > x)
}

/// x mod 1 in [0, 1).
fn fract(x: f32) -> f32 {
    x - floor_i(x) as f32
}

/// Texture coordinates per metre on the surface: one unit is a checker square, a tile, an
/// image's width or a texel of the noise table.
pub(super) fn texture_units(t: &Texture) -> f32 {
    match t {
        Texture::Checker { scale, .. }
        | Texture::Tiles { scale, .. }
        | Texture::Image { scale, .. } => 1.0 / *scale as f32,
        Texture::Noise { scale, .. } => NOISE_TEXELS as f32 / *scale as f32,
    }
}

/// A texture's colour at planar coordinates (u, v) of the body's frame in the texture's
/// units ([`texture_units`]): the two axes across the dominant axis of the surface's normal.
pub(super) fn texture_colour(t: &Texture, colour: [f32; 3], u: f32, v: f32) -> [f32; 3] {
    match t {
        Texture::Checker { colour: c2, .. } => {
            let parity = (floor_i(u).wrapping_add(floor_i(v))) & 1;
            if parity == 0 {
                colour
            } else {
                *c2
            }
        }
        Texture::Noise { colour: c2, .. } => {
            let t = noise_table();
            let x = (floor_i(u) as usize) & (NOISE_SIZE - 1);
            let y = (floor_i(v) as usize) & (NOISE_SIZE - 1);
            mix(colour, *c2, f32::from(t[y * NOISE_SIZE + x]) / 255.0)
        }
        Texture::Tiles { colour: c2, .. } => {
            let (fu, fv) = (fract(u), fract(v));
            if fu < 0.04 || fv < 0.04 {
                *c2
            } else {
                // Each tile a slightly different shade, so tiles are told apart.
                let shade = 0.9 + 0.2 * hash2(floor_i(u), floor_i(v));
                colour.map(|c| c * shade)
            }
        }
        Texture::Image {
            width,
            height,
            pixels,
            ..
        } => {
            let (fu, fv) = (fract(u), fract(v));
            let x = ((fu * *width as f32) as usize).min(*width as usize - 1);
            let y = (((1.0 - fv) * *height as f32) as usize).min(*height as usize - 1);
            let p = pixels[y * *width as usize + x];
            [0, 1, 2].map(|i| p[i] * colour[i])
        }
    }
}
