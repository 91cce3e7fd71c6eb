//! Keyframes of [`Slam`]: when a frame becomes one (the view changed enough, matches thinning,
//! a loop due or asked for), what it adds to the map (new landmarks, a pose-graph edge, a
//! depth sample), and the frames' log tied to them, from which the trajectory (body poses in
//! the map, m) is read as the map stands now.

use super::loop_closure::LOOP_MATCHES;
use super::{RgbdInput, Slam, TrackState};
use crate::frame::{sample_cloud, FrameFeatures};
use crate::map::{Keyframe, Landmark};
use crate::optimise::Edge;

impl Slam {
    /// The keyframe this frame makes, if any (in `state`, with the matches `kept`): the
    /// odometry's at a `restart`, or a tracked or confirmed relocalised frame's when the view
    /// has changed enough, closing a loop when one is due. Returns whether a keyframe was made
    /// and whether a loop was closed.
    pub(super) fn make_keyframes(
        &mut self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        state: TrackState,
        kept: &[(usize, usize)],
        restart: bool,
        tentative: bool,
    ) -> (bool, bool) {
        if restart {
            self.lost = 0;
            self.insert_keyframe(input, feats, &[], feats.len(), true);
            return (true, false);
        }
        if state == TrackState::Tracking || (state == TrackState::Relocalised && !tentative) {
            return self.keyframe_if_due(input, feats, state, kept);
        }
        (false, false)
    }

    /// A keyframe of a placed frame when the view has changed enough (see
    /// [`Slam::make_keyframes`]).
    fn keyframe_if_due(
        &mut self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        state: TrackState,
        kept: &[(usize, usize)],
    ) -> (bool, bool) {
        let last = self.map.keyframes.len() - 1;
        let d = self.map.keyframes[last].pose.inverse() * self.pose;
        let moved = d.translation.vector.norm();
        let turned = d.rotation.angle();
        let old = self.old_anchor_count(kept);
        // A relocalised frame matched old landmarks only: nothing recent to compare with.
        let may_close =
            state == TrackState::Tracking && last + 1 >= self.last_loop + self.settings.loop_age;
        let mut loop_due = may_close && old >= LOOP_MATCHES;
        // Without odometry to bridge a view that is thinning out (a wall's edge seen at an
        // angle), a keyframe is made while enough matches remain to anchor it (issue 56's
        // loss; with odometry the wheels bridge it, and such keyframes of a view the robot
        // carries along, a basket its arm holds, would drag the pose).
        let thinning = input.odometry.is_none() && kept.len() < 2 * self.settings.min_inliers;
        if !(loop_due
            || moved > self.settings.keyframe_distance
            || turned > self.settings.keyframe_angle
            || (kept.len() < self.last_keyframe_inliers * 6 / 10)
            || thinning
            || self.keyframe_wanted)
        {
            return (false, false);
        }
        self.keyframe_wanted = false;
        // Tracking sees old landmarks only near where the recent ones put them: a drift beyond
        // its search (or its outlier test) would never be closed. So a keyframe also looks for
        // the old keyframes' landmarks wider around its pose.
        let mut seen = kept.to_vec();
        if may_close && !loop_due {
            if let Some(more) = self.old_view(feats, &input.camera, kept) {
                seen.extend(more);
                loop_due = true;
            }
        }
        let loop_closed = loop_due && self.close_loop(input, feats, &seen);
        self.insert_keyframe(input, feats, kept, kept.len(), false);
        if loop_closed {
            // The loop moved the pose: what the wheels say is measured from there.
            self.rebase(self.pose, input.odometry, true);
        }
        (true, loop_closed)
    }

    /// How many kept matches are landmarks of old keyframes.
    fn old_anchor_count(&self, kept: &[(usize, usize)]) -> usize {
        let n = self.map.keyframes.len();
        if n <= self.settings.loop_age {
            return 0;
        }
        let cut = n - self.settings.loop_age;
        kept.iter()
            .filter(|&&(_, l)| self.map.landmarks[l].keyframe < cut)
            .count()
    }

    /// Adds this frame as a keyframe: its kept matches stay tied to their landmarks; its other
    /// features within the map depth become new landmarks.
    pub(super) fn insert_keyframe(
        &mut self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        kept: &[(usize, usize)],
        inliers: usize,
        from_odometry: bool,
    ) {
        let id = self.map.keyframes.len();
        let mut landmarks = vec![None; feats.len()];
        let t_wc = self.pose * input.camera;
        // (Tracked frames fused their matches already.)
        for &(f, l) in kept {
            landmarks[f] = Some(l);
        }
        let mut created = 0;
        for (f, slot) in landmarks.iter_mut().enumerate() {
            if slot.is_some() || feats.points[f].z > self.settings.map_depth {
                continue;
            }
            *slot = Some(self.map.landmarks.len());
            self.map.landmarks.push(Landmark {
                keyframe: id,
                local: feats.points[f],
                world: t_wc * feats.points[f],
                descriptor: feats.descriptors[f],
                level: feats.keypoints[f].level,
                sigma: self.depth_sigma(feats.points[f].z),
                found: 1,
                visible: 1,
            });
            created += 1;
        }
        let _ = created;
        if let Some(prev) = self.map.keyframes.last() {
            let z = prev.pose.inverse() * self.pose;
            let dist = z.translation.vector.norm();
            let ang = z.rotation.angle();
            // A keyframe-to-keyframe edge from tracking, unless the loop closure set it.
            if !self.map.edges.iter().any(|e| e.b == id && e.a == id - 1) {
                // The odometry's edge is looser than tracking's.
                let k = if from_odometry { 5.0 } else { 1.0 };
                self.map.edges.push(Edge {
                    a: id - 1,
                    b: id,
                    z,
                    sigma_t: k * (0.002 + 0.01 * dist),
                    sigma_r: k * (0.001 + 0.01 * ang),
                });
            }
        }
        self.map.keyframes.push(Keyframe {
            time: input.time,
            pose: self.pose,
            camera: input.camera,
            descriptors: feats.descriptors.clone(),
            landmarks,
            cloud: sample_cloud(
                input.rgb,
                input.depth,
                &self.k,
                &input.camera,
                self.depth_use(self.settings.map_depth),
                self.settings.cloud_stride,
            ),
        });
        self.kf_odometry.push(input.odometry);
        self.rebase(self.pose, input.odometry, false);
        self.last_keyframe_inliers = inliers.max(self.settings.min_inliers);
    }

    /// Records the latest pose relative to the newest keyframe, and whether it is confirmed.
    pub(super) fn log_frame(&mut self, time: f64, confirmed: bool) {
        let k = self.map.keyframes.len() - 1;
        let rel = self.map.keyframes[k].pose.inverse() * self.pose;
        self.frames_log.push((time, k, rel, confirmed));
    }

    /// Every confirmed frame's body pose as the map stands now: each frame's pose relative to
    /// the keyframe it was tracked after, on that keyframe's current pose (so loop closures
    /// correct the frames before them, as ORB-SLAM2 writes its trajectory). A lost frame
    /// ([`TrackState::Lost`]: no match, no odometry) has no pose here rather than a made-up
    /// one; [`Slam::tracking_gaps`] says where they were.
    pub fn trajectory(&self) -> Vec<crate::trajectory::Stamped> {
        self.frames_log
            .iter()
            .filter(|f| f.3)
            .map(|&(time, k, rel, _)| crate::trajectory::Stamped {
                time,
                pose: self.map.keyframes[k].pose * rel,
            })
            .collect()
    }

    /// The stretches of lost frames so far: (time of the first, of the last, frames), oldest
    /// first.
    pub fn tracking_gaps(&self) -> Vec<(f64, f64, usize)> {
        let mut gaps: Vec<(f64, f64, usize)> = Vec::new();
        let mut open = false;
        for &(time, _, _, confirmed) in &self.frames_log {
            match (confirmed, open, gaps.last_mut()) {
                (false, true, Some(g)) => {
                    g.1 = time;
                    g.2 += 1;
                }
                (false, _, _) => gaps.push((time, time, 1)),
                _ => {}
            }
            open = !confirmed;
        }
        gaps
    }
}
