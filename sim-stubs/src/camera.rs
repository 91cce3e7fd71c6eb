//! The simulated RGB-D camera: the renderer at the robot's camera, with the depth noise of
//! an active stereo sensor (Intel RealSense D435).
//!
//! The noise model ([`StereoNoise`]) works on disparity, as the sensor does: a point at depth
//! z has disparity d = f·B / z (f the focal length in px, B the stereo baseline); the matcher
//! finds it with a sub-pixel error of standard deviation σ_d, so the depth error has standard
//! deviation σ_z ≈ z² σ_d / (f B): it grows with the square of the distance (D435: B = 50 mm,
//! σ_d = 0.08 px, f = 620 px give 2.6 mm at 1 m and 10.3 mm at 2 m, 0.5 % of the distance, under
//! the datasheet's 2 % at 2 m). Depth is then quantised to 1 mm (the 16-bit millimetre stream)
//! and is zero (invalid) beyond the range, at occluding edges, on the left band the right
//! imager does not see, and in the stereo shadow left of every nearer object.

use ferrobot_description::CameraSection;
use nalgebra::Isometry3;

use crate::body::RobotBody;
use crate::lockstep::Truth;
use crate::render::{PinholeCamera, RenderedImage, Renderer};
use crate::rng::SimRng;
use crate::scene::Scene;

/// Depth noise and invalid pixels of an active stereo camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoNoise {
    /// Baseline between the imagers, m (the right imager sits at +x).
    pub baseline: f64,
    /// Standard deviation of the matcher's disparity error, px.
    pub subpixel: f64,
    /// Nearest valid depth, m.
    pub min_depth: f64,
    /// Farthest valid depth, m.
    pub max_depth: f64,
    /// A jump in depth to a 4-neighbour larger than this fraction of the depth makes a pixel
    /// an occluding edge (invalid).
    pub edge_jump: f64,
    /// Depth quantum, m.
    pub quantum: f64,
}

impl StereoNoise {
    /// The RealSense D435 (baseline 50 mm, 0.08 px sub-pixel error, 0.2-10 m, 1 mm steps).
    pub const D435: StereoNoise = StereoNoise {
        baseline: 0.050,
        subpixel: 0.08,
        min_depth: 0.2,
        max_depth: 10.0,
        edge_jump: 0.05,
        quantum: 0.001,
    };

    /// The model's standard deviation of depth at `z` m for focal length `f` px, m.
    pub fn sigma(&self, z: f64, f: f64) -> f64 {
        z * z * self.subpixel / (f * self.baseline)
    }

    /// Apply the noise and the invalid pixels to a row-major depth image (m, 0 = invalid) of
    /// width `w` taken with focal length `fx` px.
    ///
    /// The disparity errors are normal, drawn from a table of 4096 quantiles of the standard
    /// normal by a fast generator seeded from `rng` once per image (one draw of `rng` per
    /// call): the same `rng` state gives the same image.
    pub fn apply(&self, depth: &mut [f32], w: usize, fx: f64, rng: &mut SimRng) {
        if w == 0 {
            return;
        }
        let h = depth.len() / w;
        let fb = (fx * self.baseline) as f32;
        let subpixel = self.subpixel as f32;
        let (zmin, zmax) = (self.min_depth as f32, self.max_depth as f32);
        let edge_jump = self.edge_jump as f32;
        let quantum = self.quantum as f32;
        let fb_steps = (fx * self.baseline / self.quantum) as f32;
        let table = normal_table();
        let mut gen = WyRand(rng.next_u64());
        // Scratch rows: the clean depths of the row above and of this row, this row's
        // disparities, invalid flags and disparity errors.
        let mut above = vec![0.0f32; w];
        let mut row = vec![0.0f32; w];
        let mut disparity = vec![0.0f32; w];
        let mut bad = vec![false; w];
        let mut error = vec![0.0f32; w];
        for r in 0..h {
            row.copy_from_slice(&depth[r * w..(r + 1) * w]);
            for (d, &z) in disparity.iter_mut().zip(&row) {
                *d = if z > 0.0 { fb / z } else { 0.0 };
            }
            // Out of range, or an occluding edge: a jump in depth to a 4-neighbour. Off the
            // image a neighbour is the pixel itself (no jump).
            let up: &[f32] = if r > 0 { &above } else { &row };
            let down = depth.get((r + 1) * w..(r + 2) * w).unwrap_or(&row);
            let flag = |z: f32, u: f32, d: f32, l: f32, r: f32| {
                let t = edge_jump * z;
                let jump = |o: f32| (o <= 0.0) | ((o - z).abs() > t);
                (z <= 0.0) | (z < zmin) | (z > zmax) | jump(u) | jump(d) | jump(l) | jump(r)
            };
            // The interior columns from slices of one length (a loop that vectorises), then
            // the two border columns.
            if w > 2 {
                let n = w - 2;
                let (l, m, rt) = (&row[..n], &row[1..n + 1], &row[2..]);
                let (u, d, b) = (&up[1..n + 1], &down[1..n + 1], &mut bad[1..n + 1]);
                for i in 0..n {
                    b[i] = flag(m[i], u[i], d[i], l[i], rt[i]);
                }
            }
            for c in [0, w - 1] {
                let (l, r) = (row[c.saturating_sub(1)], row[(c + 1).min(w - 1)]);
                bad[c] = flag(row[c], up[c], down[c], l, r);
            }
            stereo_shadow(&row, &disparity, &mut bad);
            disparity_errors(&mut error, &mut gen, table, subpixel);
            let out = &mut depth[r * w..(r + 1) * w];
            for c in 0..w {
                let d = disparity[c] + error[c];
                // Depth in quanta, rounded by adding and taking away 1.5 * 2^23 (exact below
                // 2^22 quanta, far beyond the range; infinity becomes NaN, out of range too).
                let steps = if d > 0.0 { fb_steps / d } else { -1.0 };
                let q = ((steps + ROUND) - ROUND) * quantum;
                out[c] = if bad[c] || !(zmin..=zmax).contains(&q) {
                    0.0
                } else {
                    q
                };
            }
            std::mem::swap(&mut above, &mut row);
        }
    }
}

/// Stereo shadow: scanning right to left, a pixel whose match in the right image lies at or
/// right of a match already taken by a pixel to its right is hidden from the right imager; so
/// is one whose match falls off the right image's left edge. Marks them in `bad`.
fn stereo_shadow(row: &[f32], disparity: &[f32], bad: &mut [bool]) {
    let w = row.len();
    let mut min_right = f32::INFINITY;
    for c in (0..w).rev() {
        if row[c] <= 0.0 {
            continue;
        }
        let ur = c as f32 - disparity[c];
        if ur < 0.0 || ur > min_right + 0.5 {
            bad[c] = true;
        }
        if ur < min_right {
            min_right = ur;
        }
    }
}

/// A row of disparity errors (px): quantiles of `table` scaled by `subpixel`, five 12-bit
/// table indices from each 64-bit draw of `gen`.
fn disparity_errors(error: &mut [f32], gen: &mut WyRand, table: &[f32], subpixel: f32) {
    for chunk in error.chunks_mut(5) {
        let mut bits = gen.next();
        for e in chunk {
            *e = table[(bits & 0xfff) as usize] * subpixel;
            bits >>= 12;
        }
    }
}

/// 1.5 * 2^23: a float of magnitude below 2^22 plus this has no fraction bits left.
const ROUND: f32 = 12_582_912.0;

/// Quantiles of the standard normal at (i + 0.5) / 4096, i = 0..4096: a uniform 12-bit index
/// into it draws a normal (standard deviation 0.9998; tails cut at 3.67). The depth noise's
/// draws.
pub fn normal_table() -> &'static [f32; 4096] {
    static TABLE: std::sync::OnceLock<[f32; 4096]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        // The normal's CDF by integrating its density (Simpson's rule on steps of 1e-4 from
        // -8), then each quantile by linear interpolation in it.
        let step = 1e-4;
        let pdf = |x: f64| (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt();
        let mut t = [0.0f32; 4096];
        let (mut x, mut cdf) = (-8.0f64, 0.0f64);
        for (i, q) in t.iter_mut().enumerate() {
            let p = (i as f64 + 0.5) / 4096.0;
            loop {
                let next = cdf + step / 6.0 * (pdf(x) + 4.0 * pdf(x + step / 2.0) + pdf(x + step));
                if next >= p {
                    *q = (x + step * (p - cdf) / (next - cdf)) as f32;
                    break;
                }
                cdf = next;
                x += step;
            }
        }
        t
    })
}

/// wyrand: a fast 64-bit generator (one multiply a draw) for the per-pixel noise.
struct WyRand(u64);

impl WyRand {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0xa076_1d64_78bd_642f);
        let t = u128::from(self.0) * u128::from(self.0 ^ 0xe703_7ed1_a0b4_28db);
        (t >> 64) as u64 ^ t as u64
    }
}

/// One captured frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Capture {
    /// Colour, depth and labels.
    pub image: RenderedImage,
    /// The camera at capture time (intrinsics and the optical frame's true world pose).
    pub camera: PinholeCamera,
    /// Capture time, simulated µs.
    pub time_us: u64,
}

/// The simulated camera of one robot in one scene.
#[derive(Debug, Clone)]
pub struct SimCamera {
    renderer: Renderer,
    section: CameraSection,
    optical: usize,
    /// Depth noise, `None` for exact depth.
    pub noise: Option<StereoNoise>,
    rng: SimRng,
    /// A pose offset of the camera against its URDF mount (optical frame, for calibration
    /// studies): the true optical frame is `mount * offset`.
    pub mount_offset: Isometry3<f64>,
    /// The robot's decals (its fiducial marker): link index, and the box's pose in the link
    /// and half extents, m. Their pixels are rendered with area coverage ([`SUPERSAMPLE`]).
    decals: Vec<(usize, Isometry3<f64>, [f64; 3])>,
    /// Scratch image of the supersampled crops.
    crop: RenderedImage,
    /// The other robots the renderer draws ([`Truth::others`]' bodies, in order).
    others: Vec<std::sync::Arc<RobotBody>>,
}

/// Where the other robots' links are in `truth`, robot by robot.
fn others_links(truth: &Truth) -> Vec<&[Isometry3<f64>]> {
    truth.others.iter().map(|o| o.links.as_slice()).collect()
}

/// Sub-pixels per pixel side where a decal (the calibration marker) is in view: a real
/// camera's pixel integrates the light over its area, so a marker's edge gives a grey level
/// that places it to a fraction of a pixel; rendering at the pixels' centres alone would put
/// every edge on a half-pixel. The crop around each decal is rendered at this many times the
/// resolution and averaged down (colour only; depth and labels stay sampled at the centres).
pub const SUPERSAMPLE: usize = 8;

impl SimCamera {
    /// The camera of `section` on `body` in `scene`, with the D435's depth noise seeded by
    /// `seed`; `None` if the URDF has no such optical frame.
    pub fn new(
        scene: &Scene,
        body: &RobotBody,
        section: &CameraSection,
        seed: u64,
    ) -> Option<Self> {
        let optical = body.tree.link_index(&section.frame)?;
        Some(SimCamera {
            renderer: Renderer::new(scene, Some(body)),
            section: section.clone(),
            optical,
            noise: Some(StereoNoise::D435),
            rng: SimRng::new(seed, 0x00ca_3e2a),
            mount_offset: Isometry3::identity(),
            decals: body
                .decals
                .iter()
                .filter_map(|(link, s)| match s.shape {
                    crate::scene::Shape::Box(e) => Some((*link, s.origin, e.map(|v| v / 2.0))),
                    _ => None,
                })
                .collect(),
            crop: RenderedImage::new(0, 0),
            others: Vec::new(),
        })
    }

    /// The camera's description (intrinsics, rate, optical frame).
    pub fn section(&self) -> &CameraSection {
        &self.section
    }

    /// Mount the camera off its URDF pose by `error`, a pose in the frame of the optical
    /// frame's parent link (the camera's body, `camera_link`): the true camera link is the
    /// URDF's times `error` (the host keeps believing the URDF, or its calibration).
    pub fn set_mount_error(&mut self, body: &RobotBody, error: &Isometry3<f64>) {
        // The optical frame's pose in the camera link (its fixed joint's origin).
        let link_to_optical = body
            .tree
            .link_origin(self.optical)
            .unwrap_or_else(Isometry3::identity);
        self.mount_offset = link_to_optical.inverse() * error * link_to_optical;
    }

    /// Draw the robot's decals (the description's hand-eye marker; default off).
    pub fn show_decals(&mut self, on: bool) {
        self.renderer.decals = on;
    }

    /// The renderer (labels, triangle count).
    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    /// The pinhole camera at the optical frame of `truth`.
    pub fn pinhole(&self, truth: &Truth) -> PinholeCamera {
        let s = &self.section;
        let pose = truth
            .links
            .get(self.optical)
            .copied()
            .unwrap_or_else(Isometry3::identity)
            * self.mount_offset;
        PinholeCamera {
            width: s.width,
            height: s.height,
            fx: s.fx,
            fy: s.fy,
            cx: s.cx,
            cy: s.cy,
            pose,
        }
    }

    /// Render the world of `truth` into `out` (reusing its buffers) and return the camera.
    pub fn capture_into(&mut self, truth: &Truth, out: &mut RenderedImage) -> PinholeCamera {
        let cam = self.pinhole(truth);
        self.meet_others(truth);
        let others = others_links(truth);
        self.renderer
            .render_among(&cam, &truth.bodies, &truth.links, &others, out);
        if self.renderer.decals {
            for i in 0..self.decals.len() {
                self.supersample_decal(i, &cam, truth, out);
            }
        }
        if let Some(n) = self.noise {
            n.apply(&mut out.depth, cam.width as usize, cam.fx, &mut self.rng);
        }
        cam
    }

    /// Draw the other robots of `truth` from now on, when they are not those drawn so far.
    fn meet_others(&mut self, truth: &Truth) {
        let same = self.others.len() == truth.others.len()
            && self
                .others
                .iter()
                .zip(&truth.others)
                .all(|(a, b)| std::sync::Arc::ptr_eq(a, &b.body));
        if !same {
            self.others = truth.others.iter().map(|o| o.body.clone()).collect();
            let bodies: Vec<&RobotBody> = self.others.iter().map(|b| b.as_ref()).collect();
            self.renderer.set_others(&bodies);
        }
    }

    /// Re-render the colour of the pixels round decal `i` with [`SUPERSAMPLE`]² samples each,
    /// averaged.
    fn supersample_decal(
        &mut self,
        i: usize,
        cam: &PinholeCamera,
        truth: &Truth,
        out: &mut RenderedImage,
    ) {
        let (link, origin, h) = self.decals[i];
        let Some(pose) = truth.links.get(link).map(|l| l * origin) else {
            return;
        };
        // The decal's pixel bounds, a pixel wider each side.
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for k in 0..8 {
            let sign = |bit: usize| if k & bit == 0 { -1.0 } else { 1.0 };
            let p = pose * nalgebra::Point3::new(sign(1) * h[0], sign(2) * h[1], sign(4) * h[2]);
            let Some((u, v)) = cam.project(&p) else {
                return;
            };
            lo = [lo[0].min(u), lo[1].min(v)];
            hi = [hi[0].max(u), hi[1].max(v)];
        }
        let (w, ht) = (cam.width as f64, cam.height as f64);
        let c0 = (lo[0].floor() - 1.0).max(0.0);
        let r0 = (lo[1].floor() - 1.0).max(0.0);
        let c1 = (hi[0].ceil() + 1.0).min(w - 1.0);
        let r1 = (hi[1].ceil() + 1.0).min(ht - 1.0);
        // Nothing in view, or absurdly large (a decal at the lens): leave it sampled.
        if c0 > c1 || r0 > r1 || (c1 - c0) * (r1 - r0) > 40_000.0 {
            return;
        }
        let (cw, ch) = ((c1 - c0) as usize + 1, (r1 - r0) as usize + 1);
        let s = SUPERSAMPLE;
        // Sub-pixel (i, j) of the crop samples image point (c0 - 0.5 + (i + 0.5) / s, ...).
        let sf = s as f64;
        let crop = PinholeCamera {
            width: (cw * s) as u32,
            height: (ch * s) as u32,
            fx: cam.fx * sf,
            fy: cam.fy * sf,
            cx: sf * (cam.cx - c0 + 0.5) - 0.5,
            cy: sf * (cam.cy - r0 + 0.5) - 0.5,
            pose: cam.pose,
        };
        self.renderer.render_among(
            &crop,
            &truth.bodies,
            &truth.links,
            &others_links(truth),
            &mut self.crop,
        );
        let (c0, r0, w) = (c0 as usize, r0 as usize, cam.width as usize);
        let cw_s = cw * s;
        for r in 0..ch {
            for c in 0..cw {
                let mut sum = [0u32; 3];
                for j in 0..s {
                    let row = (r * s + j) * cw_s + c * s;
                    for px in self.crop.rgb[3 * row..3 * (row + s)].chunks_exact(3) {
                        for (acc, &v) in sum.iter_mut().zip(px) {
                            *acc += u32::from(v);
                        }
                    }
                }
                let n = (s * s) as u32;
                let o = 3 * ((r0 + r) * w + c0 + c);
                for (dst, acc) in out.rgb[o..o + 3].iter_mut().zip(sum) {
                    *dst = ((acc + n / 2) / n) as u8;
                }
            }
        }
    }

    /// Render the world of `truth`.
    pub fn capture(&mut self, truth: &Truth) -> Capture {
        let mut image = RenderedImage::new(self.section.width, self.section.height);
        let camera = self.capture_into(truth, &mut image);
        Capture {
            image,
            camera,
            time_us: truth.time_us,
        }
    }
}

/// When a camera's frames are taken: at whole multiples of its period on the simulated clock,
/// each instant once.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameClock {
    period_us: u64,
    /// The index of the last frame taken.
    last: Option<u64>,
}

impl FrameClock {
    /// Frames at `rate` Hz; `None` unless the rate is finite and in (0, 1000].
    pub fn new(rate: f64) -> Option<Self> {
        (rate.is_finite() && rate > 0.0 && rate <= 1000.0).then(|| FrameClock {
            period_us: (1e6 / rate).round() as u64,
            last: None,
        })
    }

    /// Frames per second.
    pub fn rate(&self) -> f64 {
        1e6 / self.period_us as f64
    }

    /// The instant (µs) of the first frame not taken yet at or after `now_us`, or up to half
    /// a period before it (a caller that overshot an instant while it let time pass still
    /// gets that frame, late, instead of skipping it); it is taken.
    pub fn next(&mut self, now_us: u64) -> u64 {
        let index = self.next_index(now_us);
        self.last = Some(index);
        index * self.period_us
    }

    /// The instant (µs) [`FrameClock::next`] would return, without taking it.
    pub fn peek(&self, now_us: u64) -> u64 {
        self.next_index(now_us) * self.period_us
    }

    fn next_index(&self, now_us: u64) -> u64 {
        let index = now_us
            .saturating_sub(self.period_us / 2)
            .div_ceil(self.period_us);
        match self.last {
            Some(last) => index.max(last + 1),
            None => index,
        }
    }
}

/// One band of rows of a [`BandedCamera`].
#[derive(Debug, Clone)]
struct Band {
    camera: SimCamera,
    image: RenderedImage,
    /// The full image's row of the band's first row.
    first: usize,
    /// The full image's rows this band provides.
    keep: std::ops::Range<usize>,
}

/// A [`SimCamera`] rendered as two bands of rows on two threads: the top and bottom halves,
/// each with one extra row across the seam so that the depth noise's edge test sees the same
/// neighbours as in one image. Always two bands, whatever the machine, so a seed gives the same
/// frames everywhere; each band's noise has its own seeded stream.
#[derive(Debug, Clone)]
pub struct BandedCamera {
    bands: [Band; 2],
    width: usize,
    height: usize,
    section: CameraSection,
}

impl BandedCamera {
    /// The camera of `section` on `body` in `scene`, with the D435's depth noise (`noise`)
    /// seeded by `seed`; `None` if the URDF has no such optical frame or the image is under 4
    /// rows.
    pub fn new(
        scene: &Scene,
        body: &RobotBody,
        section: &CameraSection,
        seed: u64,
        noise: bool,
    ) -> Option<Self> {
        let (w, h) = (section.width as usize, section.height as usize);
        if h < 4 {
            return None;
        }
        let mid = h / 2;
        // Band rows: [0, mid + 1) and [mid - 1, h), keeping [0, mid) and [mid, h).
        let band = |first: usize, rows: usize, keep: std::ops::Range<usize>, salt: u64| {
            let mut s = section.clone();
            s.height = rows as u32;
            s.cy = section.cy - first as f64;
            let mut camera = SimCamera::new(scene, body, &s, seed ^ salt)?;
            if !noise {
                camera.noise = None;
            }
            Some(Band {
                camera,
                image: RenderedImage::new(s.width, s.height),
                first,
                keep,
            })
        };
        Some(BandedCamera {
            bands: [
                band(0, mid + 1, 0..mid, 0)?,
                band(mid - 1, h - mid + 1, mid..h, 0x0bad_5eed)?,
            ],
            width: w,
            height: h,
            section: section.clone(),
        })
    }

    /// The camera's description (the whole image's intrinsics and rate).
    pub fn section(&self) -> &CameraSection {
        &self.section
    }

    /// Draw the robot's decals ([`SimCamera::show_decals`]).
    pub fn show_decals(&mut self, on: bool) {
        for b in &mut self.bands {
            b.camera.show_decals(on);
        }
    }

    /// Mount the camera off its URDF pose by `error` ([`SimCamera::set_mount_error`]).
    pub fn set_mount_error(&mut self, body: &RobotBody, error: &Isometry3<f64>) {
        for b in &mut self.bands {
            b.camera.set_mount_error(body, error);
        }
    }

    /// What a label of a captured image shows ([`Renderer::label_name`]; both bands share
    /// one label table).
    pub fn label_name(&self, label: u32) -> Option<&str> {
        self.bands[0].camera.renderer().label_name(label)
    }

    /// The whole image's width and height, px.
    pub fn width_height(&self) -> (u32, u32) {
        (self.width as u32, self.height as u32)
    }

    /// Render both bands of the world of `truth`, at once.
    fn render(&mut self, truth: &Truth) {
        let [top, bottom] = &mut self.bands;
        std::thread::scope(|s| {
            let worker = s.spawn(|| {
                bottom.camera.capture_into(truth, &mut bottom.image);
            });
            top.camera.capture_into(truth, &mut top.image);
            // A panic in the worker is a bug of the renderer: carry it over.
            if let Err(p) = worker.join() {
                std::panic::resume_unwind(p);
            }
        });
    }

    /// The colour (RGB, row-major) and depth (m, 0 = invalid) of the world of `truth`, in new
    /// buffers of the whole image's size.
    pub fn capture(&mut self, truth: &Truth) -> (Vec<u8>, Vec<f32>) {
        self.render(truth);
        let w = self.width;
        let mut rgb = Vec::with_capacity(3 * w * self.height);
        let mut depth = Vec::with_capacity(w * self.height);
        for b in &self.bands {
            let (from, to) = (b.keep.start - b.first, b.keep.end - b.first);
            rgb.extend_from_slice(&b.image.rgb[3 * from * w..3 * to * w]);
            depth.extend_from_slice(&b.image.depth[from * w..to * w]);
        }
        (rgb, depth)
    }

    /// Render the world of `truth` into `out` (the whole image: colour, depth and labels; its
    /// buffers reused).
    pub fn capture_into(&mut self, truth: &Truth, out: &mut RenderedImage) {
        if out.width as usize != self.width || out.height as usize != self.height {
            *out = RenderedImage::new(self.width as u32, self.height as u32);
        }
        self.render(truth);
        let w = self.width;
        for b in &self.bands {
            let (from, to) = (b.keep.start - b.first, b.keep.end - b.first);
            let dst = b.keep.start * w..b.keep.end * w;
            out.rgb[3 * dst.start..3 * dst.end]
                .copy_from_slice(&b.image.rgb[3 * from * w..3 * to * w]);
            out.depth[dst.clone()].copy_from_slice(&b.image.depth[from * w..to * w]);
            out.labels[dst].copy_from_slice(&b.image.labels[from * w..to * w]);
        }
    }
}
