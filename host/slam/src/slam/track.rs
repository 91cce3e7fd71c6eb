//! Tracking one frame ([`Slam::track`]), step by step: the frame checked and its features
//! found; a prediction; the map's landmarks matched near it and the pose refined on them,
//! checked against the wheels; when that fails, the odometry's pose or a relocalisation; the
//! pose committed; keyframes; the report. Poses are of the body in the map, m and rad.

use nalgebra::Isometry3;

use super::wheels::agrees;
use super::{RgbdInput, Slam, TrackReport, TrackState};
use crate::error::{Error, Result};
use crate::frame::FrameFeatures;
use crate::optimise::{
    chi2, is_sound, optimise_pose, planar, renormalised, to_planar, Dof, PlanarPrior,
};

/// A frame's pose as tracking settles it: the pose, how it was found, and the matches kept
/// `(feature, landmark)`.
struct Found {
    pose: Isometry3<f64>,
    state: TrackState,
    kept: Vec<(usize, usize)>,
}

/// The map's matches of a frame `(feature, landmark)`, each one's verdict, and the pose
/// refined on them with its inlier count.
struct Matched {
    pose: Isometry3<f64>,
    matches: Vec<(usize, usize)>,
    inlier: Vec<bool>,
    inliers: usize,
}

impl Slam {
    /// Takes one frame; returns the body's pose in the map and how it was found.
    pub fn track(&mut self, input: &RgbdInput<'_>) -> Result<TrackReport> {
        self.check_input(input)?;
        self.frames += 1;
        let feats = FrameFeatures::new(
            &self.orb,
            input.rgb,
            input.depth,
            &self.k,
            &input.camera,
            self.depth_use(self.settings.depth_range[1]),
        );
        let (odo_delta, pred) = self.predict(input.odometry);
        if self.map.keyframes.is_empty() {
            return Ok(self.initialise(input, &feats));
        }
        let wheels = self.wheels_pose(input.odometry);
        let matched = self.match_map(input, &feats, odo_delta, &pred, wheels);
        let mut found = if matched.inliers >= self.settings.min_inliers {
            self.take_matches(input, &feats, matched)
        } else {
            self.when_lost(input, &feats, pred, odo_delta.is_some(), wheels)
        };
        let restart = self.restart_due(input, &feats, wheels, &mut found);
        let tentative = self.commit(input, &mut found);
        let (keyframe, loop_closed) =
            self.make_keyframes(input, &feats, found.state, &found.kept, restart, tentative);
        if self.lost == 0 {
            self.refused = None;
        }
        self.log_frame(input.time, found.state != TrackState::Lost && !tentative);
        let residual = self.residual(input, &feats, &found.kept);
        Ok(TrackReport {
            pose: self.pose,
            state: found.state,
            features: feats.len(),
            inliers: found.kept.len(),
            residual,
            keyframe,
            loop_closed,
        })
    }

    fn check_input(&self, input: &RgbdInput<'_>) -> Result<()> {
        let bad = |why: String| Err(Error::InvalidFrame { why });
        let (w, h) = (self.k.width, self.k.height);
        if input.rgb.width != w || input.rgb.height != h {
            return bad(format!(
                "colour image is {}x{} px, the camera's {w}x{h}",
                input.rgb.width, input.rgb.height
            ));
        }
        if input.depth.width != w || input.depth.height != h {
            return bad(format!(
                "depth image is {}x{} px, the camera's {w}x{h}",
                input.depth.width, input.depth.height
            ));
        }
        if input.rgb.data.len() != 3 * (w * h) as usize
            || input.depth.data.len() != (w * h) as usize
        {
            return bad("image buffers do not match their sizes".into());
        }
        if !input.time.is_finite() {
            return bad(format!("time {} s is not finite", input.time));
        }
        let c = &input.camera;
        if !(c
            .translation
            .vector
            .iter()
            .all(|x| x.is_finite() && x.abs() < 100.0)
            && c.rotation.coords.iter().all(|x| x.is_finite()))
        {
            return bad("the camera's pose on the body is not finite (or beyond 100 m)".into());
        }
        if let Some(o) = input.odometry {
            if !o.iter().all(|x| x.is_finite() && x.abs() < 1e6) {
                return bad(format!("odometry {o:?} is not finite (or beyond 1e6)"));
            }
        }
        Ok(())
    }

    /// The odometry's increment since the last frame (when both have odometry) and the
    /// predicted pose: the body moved by the increment, else (a free camera) by its last
    /// motion, else where it was.
    fn predict(&self, odometry: Option<[f64; 3]>) -> (Option<Isometry3<f64>>, Isometry3<f64>) {
        let odo_delta = match (odometry, self.last_odometry) {
            (Some(now), Some(before)) => Some(planar(before).inverse() * planar(now)),
            _ => None,
        };
        let pred = match odo_delta {
            Some(d) => self.pose * d,
            None if self.settings.dof == Dof::Free => {
                self.pose * (self.prev_pose.inverse() * self.pose)
            }
            None => self.pose,
        };
        // Composed frame after frame, a pose's quaternion drifts from unit length (and, while
        // lost, a pose composed with itself shrank to zero, then NaN: issue 56).
        let pred = Some(renormalised(&pred))
            .filter(is_sound)
            .unwrap_or(self.pose);
        (odo_delta, pred)
    }

    /// The first frame: the map starts at the start pose, this frame its first keyframe.
    fn initialise(&mut self, input: &RgbdInput<'_>, feats: &FrameFeatures) -> TrackReport {
        self.pose = self.start;
        self.prev_pose = self.start;
        self.last_odometry = input.odometry;
        let n = feats.len();
        self.insert_keyframe(input, feats, &[], n, false);
        self.log_frame(input.time, true);
        TrackReport {
            pose: self.pose,
            state: TrackState::Initialised,
            features: n,
            inliers: 0,
            residual: 0.0,
            keyframe: true,
            loop_closed: false,
        }
    }

    /// The landmarks of the keyframes near the prediction `pred` matched where it puts them,
    /// and the pose refined on them with the odometry's increment `odo_delta` as a prior; then
    /// checked against the wheels' pose `wheels` (and its error, m and rad).
    fn match_map(
        &mut self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        odo_delta: Option<Isometry3<f64>>,
        pred: &Isometry3<f64>,
        wheels: Option<(Isometry3<f64>, [f64; 2])>,
    ) -> Matched {
        let prior = odo_delta.map(|d| {
            let [dx, dy, dth] = to_planar(&d);
            let dist = dx.hypot(dy);
            let [ft, fr] = self.settings.odometry_drift;
            let st = 0.001 + ft * dist;
            PlanarPrior {
                pose: *pred,
                sigma: [st, st, 0.001 + fr * dth.abs() + 0.01 * dist],
            }
        });
        let radius = if odo_delta.is_some() { 15.0 } else { 25.0 };
        // While localising in a loaded map the prediction means nothing: match nothing by it.
        let mut matches = if self.localising {
            Vec::new()
        } else {
            self.search_local(feats, pred, &input.camera, radius)
        };
        if !self.localising && matches.len() < 2 * self.settings.min_inliers {
            matches = self.search_local(feats, pred, &input.camera, 2.5 * radius);
        }
        let obs = self.observations(feats, &matches);
        let mut pose = *pred;
        let mut inlier = Vec::new();
        let dof = self.settings.dof;
        let inliers = optimise_pose(
            &self.cam,
            &mut pose,
            &input.camera,
            &obs,
            dof,
            prior.as_ref(),
            &mut inlier,
        );
        let mut matched = Matched {
            pose,
            matches,
            inlier,
            inliers,
        };
        self.check_with_wheels(input, feats, radius, wheels, &mut matched);
        matched
    }

    /// A pose the wheels disagree with, or none: the matches may be on something the robot
    /// moves (a basket its arm pushes along fills the view and turns with it). When enough
    /// of the landmarks are seen where the wheels put them, they alone make the pose; when
    /// not, the frame is not tracked (the wheels carry it, and a kidnap is found again by
    /// relocalisation, which trusts no prediction).
    fn check_with_wheels(
        &mut self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        radius: f64,
        wheels: Option<(Isometry3<f64>, [f64; 2])>,
        m: &mut Matched,
    ) {
        if self.localising {
            return;
        }
        let Some((wheels, sigma)) = wheels else {
            return;
        };
        if m.inliers < self.settings.min_inliers || !agrees(&wheels, &m.pose, sigma) {
            let split = self.pose_agreeing(feats, &input.camera, &wheels, sigma, radius);
            if let Some((p, matches, ok, n)) = split {
                m.pose = p;
                m.matches = matches;
                m.inlier = ok;
                m.inliers = n;
            } else {
                m.inliers = 0;
            }
        }
    }

    /// A tracked frame: its matches counted on their landmarks, the inliers kept and fused
    /// into them.
    fn take_matches(&mut self, input: &RgbdInput<'_>, feats: &FrameFeatures, m: Matched) -> Found {
        self.lost = 0;
        let mut kept: Vec<(usize, usize)> = Vec::new();
        for (&(f, l), &ok) in m.matches.iter().zip(&m.inlier) {
            self.map.landmarks[l].visible += 1;
            if ok {
                self.map.landmarks[l].found += 1;
                kept.push((f, l));
            }
        }
        // Every tracked frame refines the landmarks it saw.
        let t_wc = m.pose * input.camera;
        for &(f, l) in &kept {
            self.fuse(feats, f, l, &t_wc);
        }
        Found {
            pose: m.pose,
            state: TrackState::Tracking,
            kept,
        }
    }

    /// A frame the map's landmarks did not place: at the prediction `pred` (the odometry's
    /// when there is `odometry`), or relocalised against every keyframe when that is due.
    fn when_lost(
        &mut self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        pred: Isometry3<f64>,
        odometry: bool,
        wheels: Option<(Isometry3<f64>, [f64; 2])>,
    ) -> Found {
        self.lost += 1;
        let mut found = Found {
            pose: pred,
            state: if odometry && !self.localising {
                TrackState::Odometry
            } else {
                TrackState::Lost
            },
            kept: Vec::new(),
        };
        // Matching against every keyframe is dear: try on frames with texture, every
        // fifth frame while lost (every third while localising in a loaded map).
        let due = if self.localising {
            self.lost % 3 == 1
        } else {
            self.lost % 5 == 1
        };
        if feats.len() >= 4 * self.settings.min_inliers && due {
            let trusted = self.trusted(wheels);
            match self.relocalise(feats, &input.camera, trusted) {
                (Some((p, k)), _) => {
                    found = Found {
                        pose: p,
                        state: TrackState::Relocalised,
                        kept: k,
                    };
                    self.lost = 0;
                    self.localising = false;
                }
                (None, Some(refused)) => {
                    self.refuse(refused, input.odometry);
                }
                (None, None) => {}
            }
        }
        found
    }

    /// Whether a keyframe at the odometry's pose starts the map here. Carried by the odometry
    /// into a view the map does not hold (or cannot match): a keyframe at the odometry's pose
    /// starts the map there, so tracking resumes. Not before this very view failed to match
    /// every keyframe (after a kidnap the odometry's pose is wrong, and a map started there
    /// would be tracked against for good), nor while it matched somewhere the wheels still
    /// refuse. A relocalisation found on the way is taken into `found`.
    fn restart_due(
        &mut self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        wheels: Option<(Isometry3<f64>, [f64; 2])>,
        found: &mut Found,
    ) -> bool {
        let mut restart = found.state == TrackState::Odometry
            && !self.localising
            && self.lost >= 2
            && feats.len() >= 2 * self.settings.min_inliers;
        if restart {
            match self.relocalise(feats, &input.camera, self.trusted(wheels)) {
                (Some((p, k)), _) => {
                    found.pose = p;
                    found.kept = k;
                    found.state = TrackState::Relocalised;
                    self.lost = 0;
                    restart = false;
                }
                (None, Some(refused)) => restart = self.refuse(refused, input.odometry),
                (None, None) => {}
            }
        }
        restart
    }

    /// Makes `found`'s pose the body's; returns whether it is tentative ([`Slam::confirm`]).
    fn commit(&mut self, input: &RgbdInput<'_>, found: &mut Found) -> bool {
        // Without a pose from the map, the constant-velocity model is not carried on.
        self.prev_pose = if matches!(found.state, TrackState::Tracking | TrackState::Odometry) {
            self.pose
        } else {
            found.pose
        };
        // Whatever a solve gave, the pose kept is a sound one: a degenerate one is refused and
        // the last good pose kept, the frame lost.
        let pose = renormalised(&found.pose);
        if is_sound(&pose) {
            found.pose = pose;
        } else {
            found.pose = self.pose;
            found.state = TrackState::Lost;
        }
        if found.state == TrackState::Relocalised {
            self.rebase(found.pose, input.odometry, false);
        }
        self.pose = found.pose;
        self.last_odometry = input.odometry;
        input.odometry.is_none() && self.confirm(found.state, &found.pose)
    }

    /// How well the kept matches fit the pose: the root mean square of their reprojection
    /// and disparity errors, in their standard deviations (0 when nothing was kept).
    fn residual(
        &self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        kept: &[(usize, usize)],
    ) -> f64 {
        let t_wc = self.pose;
        let chi2_sum: f64 = kept
            .iter()
            .map(|&(f, l)| {
                chi2(
                    &self.cam,
                    &t_wc,
                    &input.camera,
                    &self.observation(feats, f, l),
                )
            })
            .filter(|c| c.is_finite())
            .sum();
        if kept.is_empty() {
            0.0
        } else {
            (chi2_sum / (3 * kept.len()) as f64).sqrt()
        }
    }
}
