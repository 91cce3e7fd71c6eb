//! Loop closure: a keyframe that sees many landmarks of old keyframes (found by tracking, or
//! by a wider search around its pose) adds two constraints to the pose graph, its pose from
//! the recent landmarks and from the old ones; the graph's optimisation moves the loop's
//! keyframes (body poses in the map, m and rad) and their landmarks.

use std::collections::HashMap;

use nalgebra::Isometry3;

use super::{RgbdInput, Slam};
use crate::frame::FrameFeatures;
use crate::optimise::{optimise_graph, optimise_pose, planar, Edge, Observation};

/// Fewest matches of old landmarks that close a loop.
pub(super) const LOOP_MATCHES: usize = 30;

/// Farthest a pose from old landmarks found by the wider search may lie from the tracked one,
/// m and rad, to close a loop: farther is more likely a repeated texture matched wrongly than
/// a drift.
const LOOP_REACH: [f64; 2] = [0.3, 0.15];

impl Slam {
    /// The kept matches of frame `feats` to landmarks of old keyframes (see
    /// [`SlamSettings::loop_age`]) near the current pose, searched wider than tracking does
    /// (no recent landmark among them: their pose is the old landmarks' alone), when at least
    /// [`LOOP_MATCHES`] agree on a pose within [`LOOP_REACH`] of the current one. Features
    /// already matched in `kept` are left out.
    pub(super) fn old_view(
        &mut self,
        feats: &FrameFeatures,
        t_bc: &Isometry3<f64>,
        kept: &[(usize, usize)],
    ) -> Option<Vec<(usize, usize)>> {
        let cut = self
            .map
            .keyframes
            .len()
            .checked_sub(self.settings.loop_age)?;
        let t_wc = self.pose * t_bc;
        let mut kfs = self.map.keyframes_near(&t_wc, 5.0, 1.4);
        kfs.retain(|&k| k < cut);
        kfs.truncate(40);
        if kfs.is_empty() {
            return None;
        }
        let pose = self.pose;
        let taken: std::collections::HashSet<usize> = kept.iter().map(|&(f, _)| f).collect();
        let matches: Vec<(usize, usize)> = self
            .search_in(feats, &pose, t_bc, 2.5 * 15.0, &kfs)
            .into_iter()
            .filter(|(f, _)| !taken.contains(f))
            .collect();
        if matches.len() < LOOP_MATCHES {
            return None;
        }
        let obs = self.observations(feats, &matches);
        let mut t_old = pose;
        let mut ok = Vec::new();
        let n = optimise_pose(
            &self.cam,
            &mut t_old,
            t_bc,
            &obs,
            self.settings.dof,
            None,
            &mut ok,
        );
        let gap = pose.inverse() * t_old;
        if n < LOOP_MATCHES
            || gap.translation.vector.norm() > LOOP_REACH[0]
            || gap.rotation.angle() > LOOP_REACH[1]
        {
            return None;
        }
        Some(
            matches
                .into_iter()
                .zip(ok)
                .filter(|(_, good)| *good)
                .map(|(m, _)| m)
                .collect(),
        )
    }

    /// Closes a loop at the keyframe about to be inserted: the pose from the recent landmarks
    /// alone (or the odometry) is the tracking edge from the previous keyframe, the pose from
    /// the old landmarks alone is the loop edge to their commonest anchor; the pose graph then
    /// moves every keyframe. Returns whether it did.
    pub(super) fn close_loop(
        &mut self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        kept: &[(usize, usize)],
    ) -> bool {
        let n = self.map.keyframes.len();
        let Some((anchor, old_obs, new_obs)) = self.split_by_age(feats, kept) else {
            return false;
        };
        let Some((t_old, t_new, looseness)) = self.loop_poses(input, &old_obs, &new_obs) else {
            return false;
        };
        let gap = t_new.inverse() * t_old;
        if gap.translation.vector.norm() < 0.003 && gap.rotation.angle() < 0.003 {
            self.last_loop = n;
            return false;
        }
        let closing = self.closing_edges(anchor, t_old, t_new, looseness);
        self.move_loop(anchor, t_new, closing)
    }

    /// The observations of the matches `kept` of old landmarks (anchored in keyframes older
    /// than [`SlamSettings::loop_age`](super::SlamSettings::loop_age)) and of recent ones, with
    /// the commonest anchor of the old; `None` without old ones.
    fn split_by_age(
        &self,
        feats: &FrameFeatures,
        kept: &[(usize, usize)],
    ) -> Option<(usize, Vec<Observation>, Vec<Observation>)> {
        let obs: Vec<Observation> = kept
            .iter()
            .map(|&(f, l)| self.observation(feats, f, l))
            .collect();
        let n = self.map.keyframes.len();
        let cut = n.saturating_sub(self.settings.loop_age);
        let (mut old_obs, mut new_obs) = (Vec::new(), Vec::new());
        let mut anchors = HashMap::<usize, usize>::new();
        for (&(_, l), o) in kept.iter().zip(&obs) {
            let a = self.map.landmarks[l].keyframe;
            if a < cut {
                old_obs.push(*o);
                *anchors.entry(a).or_default() += 1;
            } else {
                new_obs.push(*o);
            }
        }
        let (&anchor, _) = anchors.iter().max_by_key(|(&a, &c)| (c, a))?;
        Some((anchor, old_obs, new_obs))
    }

    /// The body's pose from the old landmarks' observations `old_obs` alone and from the
    /// recent ones `new_obs` (or, with too few of those, from the odometry since the previous
    /// keyframe), and how many times looser than tracking's the latter is; `None` when either
    /// pose cannot be had.
    fn loop_poses(
        &self,
        input: &RgbdInput<'_>,
        old_obs: &[Observation],
        new_obs: &[Observation],
    ) -> Option<(Isometry3<f64>, Isometry3<f64>, f64)> {
        let n = self.map.keyframes.len();
        let dof = self.settings.dof;
        let mut inl = Vec::new();
        let mut t_old = self.pose;
        if optimise_pose(
            &self.cam,
            &mut t_old,
            &input.camera,
            old_obs,
            dof,
            None,
            &mut inl,
        ) < self.settings.min_inliers
        {
            return None;
        }
        let prev = n - 1;
        let mut t_new = self.pose;
        let recent_ok = optimise_pose(
            &self.cam,
            &mut t_new,
            &input.camera,
            new_obs,
            dof,
            None,
            &mut inl,
        ) >= self.settings.min_inliers;
        // Too few recent landmarks: the odometry since the previous keyframe, trusted as the
        // odometry is (five times looser than tracking).
        let mut looseness = 1.0;
        if !recent_ok {
            match (self.kf_odometry[prev], input.odometry) {
                (Some(a), Some(b)) => {
                    t_new = self.map.keyframes[prev].pose * (planar(a).inverse() * planar(b));
                    looseness = 5.0;
                }
                _ => return None,
            }
        }
        Some((t_old, t_new, looseness))
    }

    /// The loop's two edges to the keyframe about to be inserted: from the previous keyframe
    /// to its pose `t_new` from the recent landmarks (`looseness` times looser than
    /// tracking's), and from the old landmarks' `anchor` to its pose `t_old` from them.
    fn closing_edges(
        &self,
        anchor: usize,
        t_old: Isometry3<f64>,
        t_new: Isometry3<f64>,
        looseness: f64,
    ) -> [Edge; 2] {
        let n = self.map.keyframes.len();
        let prev = n - 1;
        let z_seq = self.map.keyframes[prev].pose.inverse() * t_new;
        let dist = z_seq.translation.vector.norm();
        [
            Edge {
                a: prev,
                b: n,
                z: z_seq,
                sigma_t: looseness * (0.002 + 0.01 * dist),
                sigma_r: looseness * (0.001 + 0.01 * z_seq.rotation.angle()),
            },
            Edge {
                a: anchor,
                b: n,
                z: self.map.keyframes[anchor].pose.inverse() * t_old,
                sigma_t: 0.002,
                sigma_r: 0.001,
            },
        ]
    }

    /// Optimises the pose graph of the loop's keyframes, from `anchor` (held) to the one about
    /// to be inserted (at `t_new`), with the `closing` edges; moves the keyframes, their
    /// landmarks and the body there. Returns whether it did (a degenerate solve closes
    /// nothing: the map stays as it was).
    fn move_loop(&mut self, anchor: usize, t_new: Isometry3<f64>, closing: [Edge; 2]) -> bool {
        let n = self.map.keyframes.len();
        let dof = self.settings.dof;
        // The loop's keyframes move, from the anchor (held) to this one: the graph stays the
        // size of the loop, not of the map.
        let mut nodes: Vec<Isometry3<f64>> = self.map.keyframes[anchor..]
            .iter()
            .map(|k| k.pose)
            .collect();
        nodes.push(t_new);
        let edges: Vec<Edge> = self
            .map
            .edges
            .iter()
            .chain(&closing)
            .filter(|e| e.a >= anchor && e.b >= anchor)
            .map(|e| Edge {
                a: e.a - anchor,
                b: e.b - anchor,
                ..*e
            })
            .collect();
        // A degenerate solve closes nothing: the map stays as it was.
        if optimise_graph(&mut nodes, &edges, dof, 10).is_none() {
            return false;
        }
        self.map.edges.extend(closing);
        for (kf, p) in self.map.keyframes[anchor..].iter_mut().zip(&nodes) {
            kf.pose = *p;
        }
        self.pose = nodes[n - anchor];
        self.prev_pose = self.pose;
        self.map.refresh_landmarks();
        self.last_loop = n;
        self.loops += 1;
        true
    }
}
