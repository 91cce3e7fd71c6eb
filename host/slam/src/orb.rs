//! ORB features (Rublee et al. 2011): FAST-9 corners on an image pyramid, spread over a grid,
//! oriented by their intensity centroid, described by 256 rotated binary intensity tests.
//!
//! Why our own and not a crate: no maintained Rust crate of the field provides ORB (kornia's
//! crates have no ORB descriptor; the crates that do are single-author releases without tests
//! or users). What ORB needs is short: the FAST segment test, a pyramid, a blur and a table of
//! test pairs. The test pairs are drawn once from a seeded Gaussian (BRIEF's G II pattern), not
//! copied from OpenCV's learned table.

use std::f32::consts::PI;

/// A 256-bit binary descriptor; two descriptors compare by their Hamming distance.
pub type Descriptor = [u64; 4];

/// Hamming distance of two descriptors, bits (0-256).
#[inline]
pub fn hamming(a: &Descriptor, b: &Descriptor) -> u32 {
    (a[0] ^ b[0]).count_ones()
        + (a[1] ^ b[1]).count_ones()
        + (a[2] ^ b[2]).count_ones()
        + (a[3] ^ b[3]).count_ones()
}

/// A grey image, 8 bit, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct GreyImage {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// Row-major intensities.
    pub data: Vec<u8>,
}

impl GreyImage {
    /// The luma (ITU-R BT.601, integer weights) of a row-major RGB image of `width` ×
    /// `height` px; `None` when `rgb` has not 3 bytes per pixel.
    pub fn from_rgb(width: usize, height: usize, rgb: &[u8]) -> Option<Self> {
        if rgb.len() != 3 * width * height {
            return None;
        }
        let data = rgb
            .chunks_exact(3)
            .map(|p| ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8)
            .collect();
        Some(GreyImage {
            width,
            height,
            data,
        })
    }

    /// The image scaled by `1 / factor` (bilinear, pixel centres aligned; weights in 1/256).
    fn downscaled(&self, factor: f32) -> GreyImage {
        let w = ((self.width as f32 / factor).round() as usize).max(1);
        let h = ((self.height as f32 / factor).round() as usize).max(1);
        // Source indices and weights of the two samples, per output column and row.
        let taps = |n_out: usize, n_in: usize| -> Vec<(usize, usize, u32, u32)> {
            (0..n_out)
                .map(|x| {
                    let sx = ((x as f32 + 0.5) * factor - 0.5).clamp(0.0, (n_in - 1) as f32);
                    let x0 = sx as usize;
                    let x1 = (x0 + 1).min(n_in - 1);
                    let f = ((sx - x0 as f32) * 256.0).round() as u32;
                    (x0, x1, 256 - f, f)
                })
                .collect()
        };
        let cols = taps(w, self.width);
        let rows = taps(h, self.height);
        let mut data = vec![0u8; w * h];
        // Weights sum to 256 on each axis, so every sum is at most 255 · 2¹⁶ + 2¹⁵: the
        // wrapping arithmetic never wraps (and the test profile checks no overflow per pixel).
        let blend =
            |a: u32, b: u32, wa: u32, wb: u32| a.wrapping_mul(wa).wrapping_add(b.wrapping_mul(wb));
        for (out_row, &(y0, y1, gy, fy)) in data.chunks_exact_mut(w).zip(&rows) {
            let r0 = &self.data[y0 * self.width..(y0 + 1) * self.width];
            let r1 = &self.data[y1 * self.width..(y1 + 1) * self.width];
            for (o, &(x0, x1, gx, fx)) in out_row.iter_mut().zip(&cols) {
                let top = blend(r0[x0] as u32, r0[x1] as u32, gx, fx);
                let bottom = blend(r1[x0] as u32, r1[x1] as u32, gx, fx);
                *o = (blend(top, bottom, gy, fy).wrapping_add(1 << 15) >> 16) as u8;
            }
        }
        GreyImage {
            width: w,
            height: h,
            data,
        }
    }

    /// The image smoothed by the binomial kernel [1 4 6 4 1] / 16 along both axes (a
    /// Gaussian of σ ≈ 1 px), borders clamped: what the descriptor's tests read, so that one
    /// pixel of noise does not flip them.
    fn blurred(&self) -> GreyImage {
        let (w, h) = (self.width, self.height);
        let mut tmp = vec![0u16; w * h];
        for (row, out) in self.data.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
            let at = |x: isize| row[x.clamp(0, w as isize - 1) as usize] as u16;
            let tap = |x: isize| at(x - 2) + 4 * at(x - 1) + 6 * at(x) + 4 * at(x + 1) + at(x + 2);
            // The interior without clamping (the compiler vectorises it), the edges with.
            if w >= 5 {
                for (o, p) in out[2..w - 2].iter_mut().zip(row.windows(5)) {
                    *o = p[0] as u16
                        + 4 * p[1] as u16
                        + 6 * p[2] as u16
                        + 4 * p[3] as u16
                        + p[4] as u16;
                }
            }
            for x in [0, 1, w.saturating_sub(2), w.saturating_sub(1)] {
                if x < w {
                    out[x] = tap(x as isize);
                }
            }
        }
        let mut data = vec![0u8; w * h];
        let row = |y: isize| {
            let y = y.clamp(0, h as isize - 1) as usize;
            &tmp[y * w..(y + 1) * w]
        };
        for (y, out) in data.chunks_exact_mut(w).enumerate() {
            let y = y as isize;
            let (a, b, c, d, e) = (row(y - 2), row(y - 1), row(y), row(y + 1), row(y + 2));
            for (x, o) in out.iter_mut().enumerate() {
                let s =
                    a[x] as u32 + 4 * b[x] as u32 + 6 * c[x] as u32 + 4 * d[x] as u32 + e[x] as u32;
                *o = ((s + 128) >> 8) as u8;
            }
        }
        GreyImage {
            width: w,
            height: h,
            data,
        }
    }
}

/// Settings of the ORB extractor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbSettings {
    /// Features wanted over all levels.
    pub features: usize,
    /// Pyramid levels.
    pub levels: usize,
    /// Scale between levels.
    pub scale: f32,
    /// FAST threshold, grey levels: a pixel of the circle differs from the centre by more.
    pub threshold: u8,
    /// Side of the grid cells that spread features over the image, px at each level.
    pub cell: usize,
}

impl Default for OrbSettings {
    /// 1000 features on 4 levels at scale 1.2 (ORB-SLAM2 uses 1000 features on 8 levels for
    /// 640 × 480); threshold 4, below ORB-SLAM2's fallback of 7 for cells without corners
    /// (its first try is 20): the grid keeps the strongest corners of each cell, so strong
    /// texture wins where there is some and soft plaster still gives features; 32 px cells.
    fn default() -> Self {
        OrbSettings {
            features: 1000,
            levels: 4,
            scale: 1.2,
            threshold: 4,
            cell: 32,
        }
    }
}

/// One ORB feature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keypoint {
    /// Column of the corner in the full-resolution image, px.
    pub u: f32,
    /// Row of the corner in the full-resolution image, px.
    pub v: f32,
    /// Pyramid level it was found on (0 = full resolution).
    pub level: u8,
    /// Orientation of its intensity centroid, rad.
    pub angle: f32,
    /// FAST score (summed contrast beyond the threshold).
    pub score: f32,
}

/// Radius of the orientation patch, px (at the feature's level).
const PATCH_RADIUS: i32 = 15;
/// Half-size of the square the binary tests are drawn in, px.
const TEST_HALF: i32 = 13;
/// Distance from the border where features are not taken, px: the rotated tests (at most
/// 13 √2 ≈ 18.4 px) and the orientation patch stay inside.
const BORDER: usize = 19;
/// Orientation bins of the precomputed rotated test patterns (12° each).
const ANGLE_BINS: usize = 30;

/// The extractor: its settings and the precomputed test patterns.
#[derive(Debug, Clone)]
pub struct OrbExtractor {
    settings: OrbSettings,
    /// For each orientation bin, 256 test pairs `(x1, y1, x2, y2)` rotated by the bin's angle.
    patterns: Vec<[(i8, i8, i8, i8); 256]>,
    /// Half-widths of the orientation disc, per row offset −15..=15.
    disc: Vec<i32>,
}

/// The features of one image: keypoints and their descriptors, in the same order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Features {
    /// Keypoints.
    pub keypoints: Vec<Keypoint>,
    /// Descriptors.
    pub descriptors: Vec<Descriptor>,
}

impl OrbExtractor {
    /// An extractor with `settings` (levels 1-12, scale 1.01-2, features 1-100 000, cell at
    /// least 8 px: out-of-range values are clamped).
    pub fn new(settings: OrbSettings) -> Self {
        let settings = OrbSettings {
            features: settings.features.clamp(1, 100_000),
            levels: settings.levels.clamp(1, 12),
            scale: if settings.scale.is_finite() {
                settings.scale.clamp(1.01, 2.0)
            } else {
                1.2
            },
            threshold: settings.threshold.max(1),
            cell: settings.cell.max(8),
        };
        let base = test_pairs();
        let patterns = (0..ANGLE_BINS)
            .map(|b| {
                let a = b as f32 * 2.0 * PI / ANGLE_BINS as f32;
                let (s, c) = a.sin_cos();
                let rot = |x: i8, y: i8| -> (i8, i8) {
                    let (x, y) = (x as f32, y as f32);
                    ((c * x - s * y).round() as i8, (s * x + c * y).round() as i8)
                };
                let mut out = [(0i8, 0i8, 0i8, 0i8); 256];
                for (o, &(x1, y1, x2, y2)) in out.iter_mut().zip(base.iter()) {
                    let (a1, b1) = rot(x1, y1);
                    let (a2, b2) = rot(x2, y2);
                    *o = (a1, b1, a2, b2);
                }
                out
            })
            .collect();
        let r = PATCH_RADIUS;
        let disc = (-r..=r)
            .map(|dy| (((r * r - dy * dy) as f32).sqrt()) as i32)
            .collect();
        OrbExtractor {
            settings,
            patterns,
            disc,
        }
    }

    /// The settings in use.
    pub fn settings(&self) -> &OrbSettings {
        &self.settings
    }

    /// The scale of level `level` relative to the full image.
    pub fn level_scale(&self, level: u8) -> f32 {
        self.settings.scale.powi(level as i32)
    }

    /// ORB features of `image`, strongest first within each grid cell, at most
    /// `settings.features` in all; none for an image whose buffer does not match its size.
    pub fn extract(&self, image: &GreyImage) -> Features {
        let s = &self.settings;
        if image.data.len() != image.width * image.height {
            return Features::default();
        }
        // Features per level in geometric proportion to the level's area (as ORB-SLAM2).
        let f = 1.0 / s.scale;
        let total: f32 = (0..s.levels).map(|l| f.powi(2 * l as i32)).sum();
        let mut out = Features::default();
        let mut level_img = image.clone();
        for level in 0..s.levels {
            if level > 0 {
                level_img = image.downscaled(s.scale.powi(level as i32));
            }
            if level_img.width <= 2 * BORDER + 1 || level_img.height <= 2 * BORDER + 1 {
                break;
            }
            let want = ((s.features as f32) * f.powi(2 * level as i32) / total).ceil() as usize;
            let corners = self.corners(&level_img, want);
            if corners.is_empty() {
                continue;
            }
            let smooth = level_img.blurred();
            let scale = s.scale.powi(level as i32);
            for (x, y, dx, dy, score) in corners {
                let angle = self.orientation(&level_img, x, y);
                let d = self.describe(&smooth, x, y, angle);
                // Pixel centres: level pixel x covers [x, x + 1) scaled, centred at x + 0.5.
                out.keypoints.push(Keypoint {
                    u: (x as f32 + 0.5 + dx) * scale - 0.5,
                    v: (y as f32 + 0.5 + dy) * scale - 0.5,
                    level: level as u8,
                    angle,
                    score,
                });
                out.descriptors.push(d);
            }
        }
        out
    }

    /// FAST-9 corners of one level after 3 × 3 non-maximum suppression, spread over the grid:
    /// at most `want`, the strongest of each cell first.
    fn corners(&self, img: &GreyImage, want: usize) -> Vec<(usize, usize, f32, f32, f32)> {
        let (w, h) = (img.width, img.height);
        let score = fast_scores(img, self.settings.threshold);
        // Non-maximum suppression and the grid.
        let cell = self.settings.cell;
        let cols = w.div_ceil(cell);
        let rows = h.div_ceil(cell);
        let mut cells: Vec<Vec<(usize, usize, f32)>> = vec![Vec::new(); cols * rows];
        for y in BORDER..h - BORDER {
            // Most scores are 0: skipped by an iterator over the row (no index arithmetic).
            let row = &score[y * w + BORDER..(y + 1) * w - BORDER];
            for (x, &sc) in (BORDER..).zip(row).filter(|&(_, &sc)| sc != 0) {
                let mut is_max = true;
                'n: for dy in -1isize..=1 {
                    for dx in -1isize..=1 {
                        if dx == 0 && dy == 0 {
                            continue;
                        }
                        let j = ((y as isize + dy) as usize) * w + (x as isize + dx) as usize;
                        let o = score[j];
                        // Ties go to the first in raster order.
                        if o > sc || (o == sc && (dy < 0 || (dy == 0 && dx < 0))) {
                            is_max = false;
                            break 'n;
                        }
                    }
                }
                if is_max {
                    cells[(y / cell) * cols + x / cell].push((x, y, sc as f32));
                }
            }
        }
        let occupied = cells.iter().filter(|c| !c.is_empty()).count().max(1);
        let per_cell = (2 * want).div_ceil(occupied).max(1);
        let mut all = Vec::new();
        for c in &mut cells {
            c.sort_by(|a, b| b.2.total_cmp(&a.2).then((a.1, a.0).cmp(&(b.1, b.0))));
            // Round-robin rank: a cell's k-th corner competes with the others' k-th.
            for (rank, &p) in c.iter().take(per_cell).enumerate() {
                all.push((rank, p));
            }
        }
        all.sort_by(|a, b| {
            a.0.cmp(&b.0)
                .then(b.1 .2.total_cmp(&a.1 .2))
                .then((a.1 .1, a.1 .0).cmp(&(b.1 .1, b.1 .0)))
        });
        all.truncate(want);
        all.into_iter()
            .map(|(_, (x, y, sc))| {
                let (dx, dy) = Self::refine(&score, w, x, y);
                (x, y, dx, dy, sc)
            })
            .collect()
    }

    /// The sub-pixel offset of a corner at `(x, y)`: the vertex of a parabola through the
    /// FAST scores of it and its neighbours, along each axis, within ±0.5 px.
    fn refine(score: &[u16], w: usize, x: usize, y: usize) -> (f32, f32) {
        let s = |xx: usize, yy: usize| score[yy * w + xx] as f32;
        let c = s(x, y);
        let vertex = |a: f32, b: f32| {
            let d = a + b - 2.0 * c;
            if d < 0.0 {
                (0.5 * (a - b) / d).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        };
        (
            vertex(s(x - 1, y), s(x + 1, y)),
            vertex(s(x, y - 1), s(x, y + 1)),
        )
    }

    /// The angle of the intensity centroid of the disc around `(x, y)`, rad.
    fn orientation(&self, img: &GreyImage, x: usize, y: usize) -> f32 {
        let r = PATCH_RADIUS;
        // Integer sums, exact: |m10|, |m01| <= 15 * 255 * 961 < 2^31.
        let (mut m10, mut m01) = (0i32, 0i32);
        for dy in -r..=r {
            let half = self.disc[(dy + r) as usize];
            let start = (y as i32 + dy) as usize * img.width + x - half as usize;
            let row = &img.data[start..=start + 2 * half as usize];
            // The row's sum and its moment about its first pixel (dx = i - half); the
            // compiler vectorises both.
            let (mut sum, mut moment) = (0i32, 0i32);
            // Wrapping adds, which cannot wrap (the bound above): the test profile's overflow
            // checks would otherwise keep the loop scalar.
            for (i, &v) in row.iter().enumerate() {
                sum = sum.wrapping_add(v as i32);
                moment = moment.wrapping_add((i as i32).wrapping_mul(v as i32));
            }
            m10 += moment - half * sum;
            m01 += dy * sum;
        }
        (m01 as f32).atan2(m10 as f32)
    }

    /// The 256 rotated tests around `(x, y)` on the blurred level.
    fn describe(&self, img: &GreyImage, x: usize, y: usize, angle: f32) -> Descriptor {
        let a = angle.rem_euclid(2.0 * PI);
        let bin = ((a / (2.0 * PI) * ANGLE_BINS as f32).round() as usize) % ANGLE_BINS;
        let pat = &self.patterns[bin];
        let w = img.width as isize;
        let centre = (y * img.width + x) as isize;
        let mut d = [0u64; 4];
        // Offsets within the image (the border keeps the tests inside), so the wrapping
        // arithmetic never wraps; it spares the test profile an overflow check per step.
        let at = |dx: i8, dy: i8| {
            img.data[centre
                .wrapping_add((dy as isize).wrapping_mul(w))
                .wrapping_add(dx as isize) as usize]
        };
        for (k, &(x1, y1, x2, y2)) in pat.iter().enumerate() {
            d[k >> 6] |= ((at(x1, y1) < at(x2, y2)) as u64) << (k & 63);
        }
        d
    }
}

/// The FAST-9 score of every pixel at least `BORDER - 1` px from the edges (0 elsewhere and
/// where there is no corner): the summed contrast beyond `threshold` of the brighter or the
/// darker ring pixels, whichever is larger, at least 1, where nine contiguous pixels of the
/// 16-pixel Bresenham circle of radius 3 are all brighter than the centre by more than
/// `threshold` or all darker.
fn fast_scores(img: &GreyImage, threshold: u8) -> Vec<u16> {
    let (w, h) = (img.width, img.height);
    let t = threshold as i16;
    let mut score = vec![0u16; w * h];
    let lo = BORDER - 1;
    if w <= 2 * lo || h <= 2 * lo {
        return score;
    }
    let mut maybe = vec![0u8; w];
    for y in lo..h - lo {
        let r: [&[u8]; 7] = std::array::from_fn(|k| &img.data[(y + k - 3) * w..(y + k - 2) * w]);
        may_be_corners(&r, lo, w - lo, t, &mut maybe);
        let out = &mut score[y * w..(y + 1) * w];
        for x in lo..w - lo {
            if maybe[x] == 0 {
                continue;
            }
            let c = r[3][x] as i16;
            let ring = [
                r[0][x],
                r[0][x + 1],
                r[1][x + 2],
                r[2][x + 3],
                r[3][x + 3],
                r[4][x + 3],
                r[5][x + 2],
                r[6][x + 1],
                r[6][x],
                r[6][x - 1],
                r[5][x - 2],
                r[4][x - 3],
                r[3][x - 3],
                r[2][x - 3],
                r[1][x - 2],
                r[0][x - 1],
            ];
            let (mut mb, mut md, mut sb, mut sd) = (0u32, 0u32, 0u16, 0u16);
            // Branch-free, and wrapping where nothing can wrap (|d| <= 255, sums <= 16 · 255):
            // the contrast beyond the threshold is positive exactly where the pixel counts.
            for (k, &p) in ring.iter().enumerate() {
                let d = (p as i16).wrapping_sub(c);
                mb |= ((d > t) as u32) << (k & 15);
                md |= ((d < -t) as u32) << (k & 15);
                sb = sb.wrapping_add(d.wrapping_sub(t).max(0) as u16);
                sd = sd.wrapping_add(0i16.wrapping_sub(d).wrapping_sub(t).max(0) as u16);
            }
            if has_run9(mb) || has_run9(md) {
                out[x] = sb.max(sd).max(1);
            }
        }
    }
    score
}

/// FAST's quick rejection for the pixels `a..b` of the middle row of `r` (seven rows, the
/// circle's): `maybe[x]` is 1 where at least two of the four compass pixels of the circle and
/// two of its four diagonal ones are brighter than the centre by more than `t`, or two and
/// two darker, else 0. Nine contiguous circle pixels hold two of every four spaced by four,
/// so a pixel marked 0 is no corner. Branch-free over whole rows, so that the compiler
/// vectorises it: most pixels of an image end here.
fn may_be_corners(r: &[&[u8]; 7], a: usize, b: usize, t: i16, maybe: &mut [u8]) {
    let n = b - a;
    let centre = &r[3][a..b];
    let compass = [
        &r[0][a..b],
        &r[3][a + 3..b + 3],
        &r[6][a..b],
        &r[3][a - 3..b - 3],
    ];
    let diagonal = [
        &r[1][a + 2..b + 2],
        &r[5][a + 2..b + 2],
        &r[5][a - 2..b - 2],
        &r[1][a - 2..b - 2],
    ];
    let out = &mut maybe[a..b];
    for i in 0..n {
        let c = centre[i] as i16;
        // Wrapping where nothing can wrap (|c ± t| <= 510, counts <= 4), so that the test
        // profile's overflow checks leave the loop vectorised.
        let (hi, lo) = (c.wrapping_add(t), c.wrapping_sub(t));
        let (mut cb, mut cd, mut db, mut dd) = (0u8, 0u8, 0u8, 0u8);
        for q in compass {
            let p = q[i] as i16;
            cb = cb.wrapping_add((p > hi) as u8);
            cd = cd.wrapping_add((p < lo) as u8);
        }
        for q in diagonal {
            let p = q[i] as i16;
            db = db.wrapping_add((p > hi) as u8);
            dd = dd.wrapping_add((p < lo) as u8);
        }
        out[i] = ((cb >= 2) & (db >= 2) | (cd >= 2) & (dd >= 2)) as u8;
    }
}

/// Whether the 16-bit circle mask has nine contiguous set bits (wrapping round).
#[inline]
fn has_run9(m: u32) -> bool {
    if m.count_ones() < 9 {
        return false;
    }
    let mut r = m | (m << 16);
    // r & (r >> 1) & ... over nine shifts: a bit survives where nine in a row are set.
    let mut acc = r;
    for _ in 1..9 {
        r >>= 1;
        acc &= r;
    }
    acc != 0
}

/// BRIEF's G II test pairs: both points drawn from an isotropic Gaussian of σ = S / 5 around
/// the centre (S = 31 px, the patch), clamped to ±13 px; drawn once from a fixed seed so every
/// build describes alike.
fn test_pairs() -> [(i8, i8, i8, i8); 256] {
    // SplitMix64: a fixed, portable stream.
    let mut state: u64 = 0x0DB5_EED0_F00D_0001;
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut gauss = || {
        // Box–Muller on two uniforms in (0, 1].
        let u1 = ((next() >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
        let u2 = (next() >> 11) as f64 / (1u64 << 53) as f64;
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    };
    let sigma = 31.0 / 5.0;
    let mut g = || {
        (gauss() * sigma)
            .round()
            .clamp(-TEST_HALF as f64, TEST_HALF as f64) as i8
    };
    let mut out = [(0, 0, 0, 0); 256];
    for o in out.iter_mut() {
        loop {
            let p = (g(), g(), g(), g());
            if (p.0, p.1) != (p.2, p.3) {
                *o = p;
                break;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// FAST-9 by its definition: the 16 circle pixels, nine contiguous all brighter (or all
    /// darker) than the centre by more than `t`; the score as [`fast_scores`] defines it.
    fn fast_by_definition(img: &GreyImage, t: u8) -> Vec<u16> {
        const CIRCLE: [(i64, i64); 16] = [
            (0, -3),
            (1, -3),
            (2, -2),
            (3, -1),
            (3, 0),
            (3, 1),
            (2, 2),
            (1, 3),
            (0, 3),
            (-1, 3),
            (-2, 2),
            (-3, 1),
            (-3, 0),
            (-3, -1),
            (-2, -2),
            (-1, -3),
        ];
        let (w, h) = (img.width, img.height);
        let at = |x: i64, y: i64| img.data[y as usize * w + x as usize] as i64;
        let t = t as i64;
        let mut out = vec![0u16; w * h];
        let lo = (BORDER - 1) as i64;
        for y in lo..h as i64 - lo {
            for x in lo..w as i64 - lo {
                let c = at(x, y);
                let d: Vec<i64> = CIRCLE
                    .iter()
                    .map(|&(dx, dy)| at(x + dx, y + dy) - c)
                    .collect();
                let run =
                    |f: &dyn Fn(i64) -> bool| (0..16).any(|s| (0..9).all(|k| f(d[(s + k) % 16])));
                if run(&|v| v > t) || run(&|v| v < -t) {
                    let sb: i64 = d.iter().filter(|&&v| v > t).map(|&v| v - t).sum();
                    let sd: i64 = d.iter().filter(|&&v| v < -t).map(|&v| -v - t).sum();
                    out[y as usize * w + x as usize] = sb.max(sd).max(1) as u16;
                }
            }
        }
        out
    }

    #[test]
    fn orientation_is_the_intensity_centroids_angle() {
        let (w, h) = (64, 64);
        let mut state = 0x0f0f_1234_5555_aaaau64;
        let data: Vec<u8> = (0..w * h)
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                // A ramp up and to the right, with noise.
                ((i % w + i / w) as u64 * 2 + state % 40) as u8
            })
            .collect();
        let img = GreyImage {
            width: w,
            height: h,
            data,
        };
        let orb = OrbExtractor::new(OrbSettings::default());
        let r = PATCH_RADIUS;
        for (x, y) in [(32usize, 32usize), (20, 40), (40, 17)] {
            // The centroid by its definition: every pixel of the disc, in floating point.
            let (mut m10, mut m01) = (0.0f64, 0.0f64);
            for dy in -r..=r {
                let half = orb.disc[(dy + r) as usize];
                for dx in -half..=half {
                    let v = img.data[(y as i32 + dy) as usize * w + (x as i32 + dx) as usize];
                    m10 += dx as f64 * v as f64;
                    m01 += dy as f64 * v as f64;
                }
            }
            let want = m01.atan2(m10) as f32;
            let got = orb.orientation(&img, x, y);
            assert!((got - want).abs() < 1e-6, "({x}, {y}): {got} vs {want}");
            // The ramp rises along +x and +y: the centroid lies near 45°.
            assert!((got - std::f32::consts::FRAC_PI_4).abs() < 0.3, "{got}");
        }
    }

    #[test]
    fn fast_scores_are_fast9_by_its_definition() {
        // Noise (every kind of pixel), blocks with noise (real corners and edges), and a
        // flat image (none).
        let (w, h) = (96, 72);
        let mut state = 0x1234_5678_9abc_def0u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let noise: Vec<u8> = (0..w * h).map(|_| next() as u8).collect();
        let blocks: Vec<u8> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let base = if (x / 7 + y / 5) % 2 == 0 { 60 } else { 190 };
                (base + (next() % 9) as i32 - 4) as u8
            })
            .collect();
        let flat = vec![128u8; w * h];
        let mut corners = 0;
        for (what, data) in [("noise", noise), ("blocks", blocks), ("flat", flat)] {
            let img = GreyImage {
                width: w,
                height: h,
                data,
            };
            for t in [0u8, 4, 20, 60] {
                let ours = fast_scores(&img, t);
                assert_eq!(ours, fast_by_definition(&img, t), "{what}, threshold {t}");
                corners += ours.iter().filter(|&&s| s > 0).count();
            }
        }
        assert!(
            corners > 500,
            "{corners} corners: the images test too little"
        );
    }
}
