//! Relocalisation: a frame matched against every keyframe, with no prediction, its body pose
//! in the map (m, rad) found by RANSAC over rigid fits of matched 3-D points and refined; and
//! the confirmation a relocalisation without odometry waits for from the next frame.

use nalgebra::{Isometry3, Point3};

use super::wheels::agrees;
use super::{Slam, TrackState};
use crate::frame::FrameFeatures;
use crate::optimise::{align, optimise_pose, planar, to_planar, Dof};
use crate::orb::hamming;

/// Farthest two consecutive relocalisations may lie apart to confirm each other, m and rad:
/// a camera at 3 m/s and 6 rad/s between two frames at 30 Hz.
const RELOCALISED_STEP: [f64; 2] = [0.1, 0.2];

/// A pose found without a prediction, with its matches `(feature, landmark)`.
type Located = (Isometry3<f64>, Vec<(usize, usize)>);

impl Slam {
    /// Whether this frame's pose is tentative (asked only without odometry: with it, the
    /// wheels check a relocalisation): a relocalisation (matched against every keyframe, with
    /// no prediction) is trusted only once the next frame agrees with it, by
    /// tracking from it or by relocalising within [`RELOCALISED_STEP`] of it. A tentative pose
    /// has no place in the trajectory and makes no keyframe: a wrong relocalisation (a repeated
    /// texture, the few matches of a fast turn) made into a keyframe corrupts the map, which
    /// then agrees with it. When the next frame confirms it, its frame gets its pose back.
    pub(super) fn confirm(&mut self, state: TrackState, pose: &Isometry3<f64>) -> bool {
        let before = self.last_relocalised.take();
        let agreed = match (state, before) {
            (TrackState::Tracking, Some(_)) => true,
            (TrackState::Relocalised, Some(p)) => {
                let d = p.inverse() * pose;
                d.translation.vector.norm() <= RELOCALISED_STEP[0]
                    && d.rotation.angle() <= RELOCALISED_STEP[1]
            }
            _ => false,
        };
        if agreed {
            if let Some(f) = self.frames_log.last_mut() {
                f.3 = true;
            }
        }
        if state == TrackState::Relocalised && !agreed {
            self.last_relocalised = Some(*pose);
            return true;
        }
        false
    }

    /// The pose of a frame found by matching its features against every keyframe's (no
    /// prediction): the keyframes with the most descriptor matches are tried in turn with a
    /// RANSAC of rigid fits on the matched 3-D points, then the pose is refined. With the
    /// `wheels`' pose (and its error), only a pose that agrees with it is taken; the first one
    /// found and refused is returned too.
    pub(super) fn relocalise(
        &self,
        feats: &FrameFeatures,
        t_bc: &Isometry3<f64>,
        wheels: Option<(Isometry3<f64>, [f64; 2])>,
    ) -> (Option<Located>, Option<Isometry3<f64>>) {
        // The strongest 400 features of the frame.
        let mut order: Vec<usize> = (0..feats.len()).collect();
        order.sort_by(|&a, &b| {
            feats.keypoints[b]
                .score
                .total_cmp(&feats.keypoints[a].score)
        });
        order.truncate(400);
        let mut scored: Vec<(usize, Vec<(usize, usize)>)> = Vec::new();
        for (k, kf) in self.map.keyframes.iter().enumerate() {
            let mut m = Vec::new();
            for &f in &order {
                let (mut d1, mut d2, mut l1) = (u32::MAX, u32::MAX, usize::MAX);
                for (d, l) in kf.descriptors.iter().zip(&kf.landmarks) {
                    let Some(l) = l else { continue };
                    let h = hamming(&feats.descriptors[f], d);
                    if h < d1 {
                        d2 = d1;
                        d1 = h;
                        l1 = *l;
                    } else if h < d2 {
                        d2 = h;
                    }
                }
                if d1 <= 50 && (d1 as f64) < 0.8 * d2 as f64 {
                    m.push((f, l1));
                }
            }
            if m.len() >= self.settings.min_inliers {
                scored.push((k, m));
            }
        }
        scored.sort_by(|a, b| b.1.len().cmp(&a.1.len()).then(a.0.cmp(&b.0)));
        let mut refused = None;
        for (_, m) in scored.into_iter().take(3) {
            let Some(r) = self.ransac_pose(feats, t_bc, &m) else {
                continue;
            };
            if wheels.is_none_or(|(w, sigma)| agrees(&w, &r.0, sigma)) {
                return (Some(r), None);
            }
            refused.get_or_insert(r.0);
        }
        (None, refused)
    }

    /// A body pose from matches by RANSAC over rigid fits of three point pairs (seeded, so
    /// runs repeat), refined on all inliers.
    fn ransac_pose(
        &self,
        feats: &FrameFeatures,
        t_bc: &Isometry3<f64>,
        m: &[(usize, usize)],
    ) -> Option<Located> {
        let mut seed = 0x2545_F491_4F6C_DD1D_u64 ^ m.len() as u64;
        let mut rnd = |n: usize| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % n as u64) as usize
        };
        let cam_pts: Vec<Point3<f64>> = m.iter().map(|&(f, _)| feats.points[f]).collect();
        let world: Vec<Point3<f64>> = m
            .iter()
            .map(|&(_, l)| self.map.landmarks[l].world)
            .collect();
        let tol = |z: f64| 0.02 + 0.01 * z * z;
        let mut best: (usize, Option<Isometry3<f64>>) = (0, None);
        for _ in 0..200 {
            let (a, b, c) = (rnd(m.len()), rnd(m.len()), rnd(m.len()));
            if a == b || b == c || a == c {
                continue;
            }
            let Some(t_wc) = align(
                &[cam_pts[a], cam_pts[b], cam_pts[c]],
                &[world[a], world[b], world[c]],
            ) else {
                continue;
            };
            let n = cam_pts
                .iter()
                .zip(&world)
                .filter(|(p, w)| (t_wc * **p - **w).norm() < tol(p.z))
                .count();
            if n > best.0 {
                best = (n, Some(t_wc));
            }
        }
        let t_wc = best.1?;
        if best.0 < self.settings.min_inliers {
            return None;
        }
        let mut pose = t_wc * t_bc.inverse();
        if self.settings.dof == Dof::Planar {
            let z = self.start.translation.z;
            let p = to_planar(&pose);
            pose = planar(p);
            pose.translation.z = z;
        }
        let obs = self.observations(feats, m);
        let mut inl = Vec::new();
        let n = optimise_pose(
            &self.cam,
            &mut pose,
            t_bc,
            &obs,
            self.settings.dof,
            None,
            &mut inl,
        );
        (n >= self.settings.min_inliers).then(|| {
            let kept = m
                .iter()
                .zip(&inl)
                .filter(|(_, &ok)| ok)
                .map(|(x, _)| *x)
                .collect();
            (pose, kept)
        })
    }
}
