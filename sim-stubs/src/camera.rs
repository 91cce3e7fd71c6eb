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
    pub fn apply(&self, depth: &mut [f32], w: usize, fx: f64, rng: &mut SimRng) {
        if w == 0 {
            return;
        }
        let h = depth.len() / w;
        let clean = depth.to_vec();
        let fb = fx * self.baseline;
        let mut invalid = vec![false; depth.len()];
        for r in 0..h {
            let row = &clean[r * w..(r + 1) * w];
            // Stereo shadow: scanning right to left, a pixel whose match in the right image
            // lies at or right of a match already taken by a pixel to its right is hidden
            // from the right imager; so is one whose match falls off the right image's left
            // edge.
            let mut min_right = f64::INFINITY;
            for c in (0..w).rev() {
                let z = f64::from(row[c]);
                if z <= 0.0 {
                    continue;
                }
                let ur = c as f64 - fb / z;
                if ur < 0.0 || ur > min_right + 0.5 {
                    invalid[r * w + c] = true;
                }
                min_right = min_right.min(ur);
            }
            for c in 0..w {
                let z = f64::from(row[c]);
                if z <= 0.0 {
                    continue;
                }
                if !(self.min_depth..=self.max_depth).contains(&z) {
                    invalid[r * w + c] = true;
                    continue;
                }
                let jump = |o: f32| o <= 0.0 || (f64::from(o) - z).abs() > self.edge_jump * z;
                let up = r > 0 && jump(clean[(r - 1) * w + c]);
                let down = r + 1 < h && jump(clean[(r + 1) * w + c]);
                let left = c > 0 && jump(row[c - 1]);
                let right = c + 1 < w && jump(row[c + 1]);
                if up || down || left || right {
                    invalid[r * w + c] = true;
                }
            }
        }
        for (d, bad) in depth.iter_mut().zip(invalid) {
            let z = f64::from(*d);
            if bad || z <= 0.0 {
                *d = 0.0;
                continue;
            }
            let disparity = fb / z + rng.normal(self.subpixel);
            let noisy = if disparity > 0.0 { fb / disparity } else { 0.0 };
            let q = (noisy / self.quantum).round() * self.quantum;
            *d = if (self.min_depth..=self.max_depth).contains(&q) {
                q as f32
            } else {
                0.0
            };
        }
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
}

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
        })
    }

    /// The camera's description (intrinsics, rate, optical frame).
    pub fn section(&self) -> &CameraSection {
        &self.section
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
        self.renderer.render(&cam, &truth.bodies, &truth.links, out);
        if let Some(n) = self.noise {
            n.apply(&mut out.depth, cam.width as usize, cam.fx, &mut self.rng);
        }
        cam
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
