//! Landmarks matched to a frame's features: the landmarks of nearby keyframes projected into
//! the image at a predicted pose and matched by descriptor near where they fall (px); a
//! match's measurement and its errors (px, disparity px); a tracked match fused into its
//! landmark (m).

use nalgebra::{Isometry3, Point3};

use super::Slam;
use crate::frame::FrameFeatures;
use crate::map::MIN_LANDMARK_SIGMA;
use crate::optimise::Observation;
use crate::orb::hamming;

impl Slam {
    /// Matches of frame features to landmarks `(feature, landmark)`: landmarks of the keyframes
    /// near `pred` projected into the image and matched within `radius` px (times the level's
    /// scale) by Hamming distance, best below 64 bits and clearly better than the runner-up.
    pub(super) fn search_local(
        &mut self,
        feats: &FrameFeatures,
        pred: &Isometry3<f64>,
        t_bc: &Isometry3<f64>,
        radius: f64,
    ) -> Vec<(usize, usize)> {
        let t_wc = pred * t_bc;
        let mut kfs = self.map.keyframes_near(&t_wc, 5.0, 1.4);
        kfs.truncate(40);
        let last = self.map.keyframes.len() - 1;
        if !kfs.contains(&last) {
            kfs.push(last);
        }
        self.search_in(feats, pred, t_bc, radius, &kfs)
    }

    /// Matches of frame features to the landmarks of keyframes `kfs` (see
    /// [`Slam::search_local`]).
    pub(super) fn search_in(
        &mut self,
        feats: &FrameFeatures,
        pred: &Isometry3<f64>,
        t_bc: &Isometry3<f64>,
        radius: f64,
        kfs: &[usize],
    ) -> Vec<(usize, usize)> {
        let t_wc = pred * t_bc;
        self.stamp.resize(self.map.landmarks.len(), 0);
        self.searches += 1;
        let frame = self.searches;
        // Best landmark per feature: (distance, landmark).
        let mut best: Vec<(u32, usize)> = vec![(u32::MAX, usize::MAX); feats.len()];
        let mut near = Vec::new();
        let (w, h) = (self.k.width as f64, self.k.height as f64);
        let inv = t_wc.inverse();
        for &kf in kfs {
            for l in self.map.keyframes[kf].landmarks.iter().flatten().copied() {
                if self.stamp[l] == frame {
                    continue;
                }
                self.stamp[l] = frame;
                let lm = &self.map.landmarks[l];
                let pc = inv * lm.world;
                if pc.z < 0.1 || pc.z > 8.0 {
                    continue;
                }
                let u = self.k.fx * pc.x / pc.z + self.k.cx;
                let v = self.k.fy * pc.y / pc.z + self.k.cy;
                if !(0.0..w).contains(&u) || !(0.0..h).contains(&v) {
                    continue;
                }
                let scale = self.orb.level_scale(lm.level) as f64;
                let lo = lm.level.saturating_sub(2);
                let hi = lm.level.saturating_add(2);
                feats.near(u, v, radius * scale, (lo, hi), &mut near);
                let (mut d1, mut d2, mut i1) = (u32::MAX, u32::MAX, usize::MAX);
                for &i in &near {
                    let d = hamming(&lm.descriptor, &feats.descriptors[i as usize]);
                    if d < d1 {
                        d2 = d1;
                        d1 = d;
                        i1 = i as usize;
                    } else if d < d2 {
                        d2 = d;
                    }
                }
                if d1 <= 64 && (d2 == u32::MAX || (d1 as f64) < 0.9 * d2 as f64) && d1 < best[i1].0
                {
                    best[i1] = (d1, l);
                }
            }
        }
        best.iter()
            .enumerate()
            .filter(|(_, b)| b.1 != usize::MAX)
            .map(|(f, b)| (f, b.1))
            .collect()
    }

    pub(super) fn observations(
        &self,
        feats: &FrameFeatures,
        matches: &[(usize, usize)],
    ) -> Vec<Observation> {
        matches
            .iter()
            .map(|&(f, l)| self.observation(feats, f, l))
            .collect()
    }

    /// Standard deviation of a depth `z` (m) measured by the sensor, m.
    pub(super) fn depth_sigma(&self, z: f64) -> f64 {
        z * z * self.settings.sigma_disparity / (self.cam.fx * self.cam.baseline)
    }

    /// Feature `f` seen as landmark `l`: its measurement, with the errors of the measurement
    /// and of the landmark's position (as seen from the feature's depth) combined.
    pub(super) fn observation(&self, feats: &FrameFeatures, f: usize, l: usize) -> Observation {
        let kp = &feats.keypoints[f];
        let lm = &self.map.landmarks[l];
        let z = feats.points[f].z;
        let fb = self.cam.fx * self.cam.baseline;
        let px = self.settings.sigma_px * self.orb.level_scale(kp.level) as f64;
        let sd = self.settings.sigma_disparity;
        Observation {
            point: lm.world,
            measured: nalgebra::Vector3::new(kp.u as f64, kp.v as f64, fb / z),
            sigma_px: px.hypot(self.cam.fx * lm.sigma / z),
            sigma_disparity: sd.hypot(fb * lm.sigma / (z * z)),
        }
    }

    /// Fuses feature `f`'s measurement (its depth, from camera pose `t_wc`) into landmark `l`:
    /// inverse-variance weights, in the landmark's anchor frame.
    pub(super) fn fuse(
        &mut self,
        feats: &FrameFeatures,
        f: usize,
        l: usize,
        t_wc: &Isometry3<f64>,
    ) {
        let sm = self.depth_sigma(feats.points[f].z);
        let lm = &self.map.landmarks[l];
        let anchor = self.map.keyframes[lm.keyframe].camera_pose();
        let measured = anchor.inverse() * (t_wc * feats.points[f]);
        let (wl, wm) = (1.0 / (lm.sigma * lm.sigma), 1.0 / (sm * sm));
        let local = Point3::from((lm.local.coords * wl + measured.coords * wm) / (wl + wm));
        let lm = &mut self.map.landmarks[l];
        lm.local = local;
        lm.world = anchor * local;
        lm.sigma = (wl + wm).recip().sqrt().max(MIN_LANDMARK_SIGMA);
    }
}
