//! The SLAM system: a sans-IO state machine fed with RGB-D frames (and, on a robot, the wheel
//! odometry and the camera's pose on the body), returning the body's pose in the map.
//!
//! Per frame: ORB features with depth; a prediction (odometry increment, or a constant
//! velocity); the landmarks of the keyframes near the prediction projected into the image and
//! matched by descriptor near where they fall; the pose refined on reprojection and disparity
//! errors with the odometry as a prior; a keyframe when the view has changed enough. A keyframe
//! that sees many landmarks of old keyframes closes a loop: its pose from the recent landmarks
//! and from the old ones become two constraints of a pose graph of the keyframes, whose
//! optimisation spreads the drift over the loop; a keyframe also searches the old keyframes'
//! landmarks wider around its pose, so a drift beyond tracking's search is closed too. When
//! matching fails, the odometry carries the pose, and a frame with enough features is matched
//! against every keyframe (relocalisation).
//!
//! The wheels check the camera: a tracked pose that strays from where the odometry since the
//! last anchor (a keyframe that agreed with it) puts the body, beyond the odometry's error, may
//! be on something the robot moves along (a basket its arm pushes fills the view and turns
//! with it); the landmarks seen where the wheels put them then make the pose alone, or none
//! does. For a moment after tracking is lost, relocalisation is held to the wheels as well (a
//! kidnapped robot is relocalised once it has stayed lost a while); where the wheels' motion
//! contradicts what it keeps finding, the map goes on from the wheels' pose.

use ferrobot_perception::{DepthImage, Intrinsics, RgbImage};
use nalgebra::{Isometry3, Point3};

use crate::error::{Error, Result};
use crate::frame::{sample_cloud, DepthUse, FrameFeatures};
use crate::map::{Keyframe, Landmark, Map};
use crate::optimise::{
    align, chi2, is_sound, optimise_graph, optimise_pose, planar, renormalised, to_planar, Dof,
    Edge, Observation, Pinhole, PlanarPrior, CHI2_3,
};
use crate::orb::{hamming, OrbExtractor, OrbSettings};

/// A landmark's position is never trusted beyond this, m (its fused measurements' errors are
/// not all independent).
pub(crate) const MIN_LANDMARK_SIGMA: f64 = 0.001;

/// Tracking agrees with the wheels when it lies within this many of their standard
/// deviations ([`SlamSettings::odometry_agreement`]) of where they put the body.
const AGREEMENT: f64 = 3.0;

/// Fewest matches of old landmarks that close a loop.
const LOOP_MATCHES: usize = 30;

/// Farthest a pose from old landmarks found by the wider search may lie from the tracked one,
/// m and rad, to close a loop: farther is more likely a repeated texture matched wrongly than
/// a drift.
const LOOP_REACH: [f64; 2] = [0.3, 0.15];

/// Farthest two consecutive relocalisations may lie apart to confirm each other, m and rad:
/// a camera at 3 m/s and 6 rad/s between two frames at 30 Hz.
const RELOCALISED_STEP: [f64; 2] = [0.1, 0.2];

/// For this many frames after tracking is lost the wheels' pose is trusted over a
/// relocalisation's (about a third of a second at 30 Hz).
const WHEELS_TRUSTED: usize = 10;

/// A match agrees with the wheels when seen where their pose puts it, give or take this many
/// of their standard deviations.
const WITHIN: f64 = 2.0;

/// Whether planar pose `b` lies within [`AGREEMENT`] standard deviations `sigma` (m, rad) of `a`.
fn agrees(a: &Isometry3<f64>, b: &Isometry3<f64>, sigma: [f64; 2]) -> bool {
    within(a, b, sigma, AGREEMENT)
}

/// Whether planar pose `b` lies within `k` standard deviations `sigma` (m, rad) of `a`.
fn within(a: &Isometry3<f64>, b: &Isometry3<f64>, sigma: [f64; 2], k: f64) -> bool {
    let [x, y, th] = to_planar(&(a.inverse() * b));
    x.hypot(y) <= k * sigma[0] && th.abs() <= k * sigma[1]
}

/// Settings of [`Slam`].
#[derive(Debug, Clone, PartialEq)]
pub struct SlamSettings {
    /// Which motions are estimated: [`Dof::Planar`] for a ground robot, [`Dof::Free`] for a
    /// hand-held camera.
    pub dof: Dof,
    /// The feature extractor's settings.
    pub orb: OrbSettings,
    /// The depth sensor's baseline, m (D435: 0.05).
    pub baseline: f64,
    /// Standard deviation of a feature's position, px at full resolution.
    pub sigma_px: f64,
    /// Standard deviation of a feature's disparity `fx b / z`, px.
    pub sigma_disparity: f64,
    /// Depths that make features, m.
    pub depth_range: [f64; 2],
    /// Farthest depth that makes new landmarks and dense map points, m.
    pub map_depth: f64,
    /// Points within this radius (m) of the body's z axis are the robot itself: dropped.
    pub self_radius: f64,
    /// A new keyframe after this much travel, m ...
    pub keyframe_distance: f64,
    /// ... or this much turn, rad.
    pub keyframe_angle: f64,
    /// Fewest inlier matches that make a pose, 6 to [`MAX_INLIERS`].
    pub min_inliers: usize,
    /// Keyframes older than this many are "old": seeing many of their landmarks closes a loop;
    /// 1 to [`MAX_LOOP_AGE`].
    pub loop_age: usize,
    /// Odometry's error per metre driven (fraction) and per radian turned (fraction).
    pub odometry_drift: [f64; 2],
    /// How far tracking may stray from where the wheels put the body (carried from the last
    /// pose that agreed with them) before the matches are asked whether some of them moved
    /// with the robot: the standard deviation of that prediction's error, m and rad as a floor
    /// (the pose's own noise and the odometry's timing) and a fraction of the distance driven
    /// and the angle turned.
    pub odometry_agreement: [f64; 2],
    /// Pixel stride of the depth sample kept per keyframe for the dense maps.
    pub cloud_stride: usize,
}

impl SlamSettings {
    /// For a ground robot with a D435 (planar, the body masked within `self_radius` m).
    pub fn ground_robot(self_radius: f64) -> Self {
        SlamSettings {
            dof: Dof::Planar,
            self_radius,
            ..Self::handheld()
        }
    }

    /// For a hand-held RGB-D camera (all six motions, nothing masked).
    pub fn handheld() -> Self {
        SlamSettings {
            dof: Dof::Free,
            orb: OrbSettings::default(),
            baseline: 0.05,
            sigma_px: 1.0,
            sigma_disparity: 0.2,
            depth_range: [0.3, 4.0],
            map_depth: 3.0,
            self_radius: 0.0,
            keyframe_distance: 0.25,
            keyframe_angle: 0.35,
            min_inliers: 25,
            loop_age: 15,
            odometry_drift: [0.2, 0.2],
            odometry_agreement: [0.006, 0.05],
            cloud_stride: 4,
        }
    }

    fn check(&self) -> Result<()> {
        let bad = |why: String| Err(Error::InvalidSettings { why });
        let pos = |x: f64| x.is_finite() && x > 0.0;
        if !(pos(self.baseline) && pos(self.sigma_px) && pos(self.sigma_disparity)) {
            return bad("baseline and sigmas must be finite and positive".into());
        }
        let [a, b] = self.depth_range;
        if !(a.is_finite() && b.is_finite() && 0.0 < a && a < b && b <= 100.0) {
            return bad(format!("depth range {a}..{b} m is not within (0, 100] m"));
        }
        if !(pos(self.map_depth) && self.self_radius.is_finite() && self.self_radius >= 0.0) {
            return bad("map depth and self radius must be finite (positive, non-negative)".into());
        }
        if !(pos(self.keyframe_distance) && pos(self.keyframe_angle)) {
            return bad("keyframe spacing must be finite and positive".into());
        }
        if !(6..=MAX_INLIERS).contains(&self.min_inliers)
            || self.cloud_stride == 0
            || self.cloud_stride > 64
        {
            return bad(format!(
                "min_inliers must be in 6..={MAX_INLIERS} and cloud_stride in 1..=64"
            ));
        }
        // A loop needs keyframes older than the ones tracking sees: at 0 every keyframe would
        // be old, and every frame would close a loop with its neighbours.
        if !(1..=MAX_LOOP_AGE).contains(&self.loop_age) {
            return bad(format!("loop_age must be in 1..={MAX_LOOP_AGE} keyframes"));
        }
        if !self.odometry_drift.iter().all(|&x| pos(x))
            || !self.odometry_agreement.iter().all(|&x| pos(x))
        {
            return bad("odometry drift must be finite and positive".into());
        }
        Ok(())
    }
}

/// Largest [`SlamSettings::min_inliers`]: far more than any frame's features (a multiple of
/// it is compared with feature counts).
pub const MAX_INLIERS: usize = 100_000;
/// Largest [`SlamSettings::loop_age`], keyframes.
pub const MAX_LOOP_AGE: usize = 100_000;

/// One RGB-D frame and what the robot knew when it was taken.
#[derive(Debug, Clone, Copy)]
pub struct RgbdInput<'a> {
    /// Capture time, s.
    pub time: f64,
    /// Colour.
    pub rgb: &'a RgbImage,
    /// Depth aligned to colour, m (0 = invalid).
    pub depth: &'a DepthImage,
    /// Pose of the optical frame (x right, y down, z forward) in the body (`base_link`), from
    /// the head's joints; the identity for a hand-held camera.
    pub camera: Isometry3<f64>,
    /// The wheel odometry's pose `[x, y, θ]` (m, rad) in its own frame, when there is one.
    pub odometry: Option<[f64; 3]>,
}

/// How a frame's pose was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackState {
    /// The first frame: the map starts at the start pose.
    Initialised,
    /// Matched to the map.
    Tracking,
    /// Too few matches: carried by the wheel odometry.
    Odometry,
    /// Too few matches and no odometry: the prediction, unconfirmed.
    Lost,
    /// Found again by matching against every keyframe.
    Relocalised,
}

/// What one frame did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackReport {
    /// The body's pose in the map.
    pub pose: Isometry3<f64>,
    /// How it was found.
    pub state: TrackState,
    /// Features with depth.
    pub features: usize,
    /// Landmarks matched and kept.
    pub inliers: usize,
    /// How well the kept landmarks fit the pose: the root mean square of their reprojection
    /// and disparity errors, in their standard deviations (about 1 when tracking is sound;
    /// 0 when nothing was kept).
    pub residual: f64,
    /// A keyframe was made of this frame.
    pub keyframe: bool,
    /// This frame closed a loop (the keyframes moved).
    pub loop_closed: bool,
}

/// A pose found without a prediction, with its matches `(feature, landmark)`.
type Located = (Isometry3<f64>, Vec<(usize, usize)>);

/// A pose found from the matches that agree with the wheels: the pose, the matches
/// `(feature, landmark)`, each one's verdict and the inlier count.
type Agreeing = (Isometry3<f64>, Vec<(usize, usize)>, Vec<bool>, usize);

/// RGB-D SLAM fused with wheel odometry.
#[derive(Debug, Clone)]
pub struct Slam {
    settings: SlamSettings,
    k: Intrinsics,
    cam: Pinhole,
    orb: OrbExtractor,
    map: Map,
    /// Odometry of each keyframe, when given.
    kf_odometry: Vec<Option<[f64; 3]>>,
    start: Isometry3<f64>,
    pose: Isometry3<f64>,
    prev_pose: Isometry3<f64>,
    last_odometry: Option<[f64; 3]>,
    last_keyframe_inliers: usize,
    lost: usize,
    /// The newest pose the map confirmed (a keyframe's, a relocalised frame's) and the
    /// odometry then: what the wheels say since is measured from it.
    anchor: Option<(Isometry3<f64>, [f64; 3])>,
    /// While lost, the first pose relocalisation found that the wheels refused, and the
    /// odometry then: a later one that the wheels' motion since contradicts is on something
    /// that moves with the robot.
    refused: Option<(Isometry3<f64>, [f64; 3])>,
    last_loop: usize,
    loops: usize,
    frames: usize,
    /// A saved map is loaded and the pose in it not yet found.
    localising: bool,
    /// Every frame: its time, the keyframe it was last tied to, and its pose relative to it.
    /// Per frame: time, the keyframe it was tracked after, its pose relative to that keyframe,
    /// and whether the map confirmed it (not [`TrackState::Lost`]).
    frames_log: Vec<(f64, usize, Isometry3<f64>, bool)>,
    /// The pose of the last frame when it was a tentative relocalisation ([`Slam::confirm`]).
    last_relocalised: Option<Isometry3<f64>>,
    /// Per landmark, the last search that considered it (to visit each once per search).
    stamp: Vec<usize>,
    searches: usize,
    /// The next tracked frame becomes a keyframe.
    keyframe_wanted: bool,
}

impl Slam {
    /// A SLAM system for a camera of intrinsics `k`; the map's frame is where the body is at
    /// the first frame, posed at `start` in it (the identity, or the robot's known start).
    pub fn new(settings: SlamSettings, k: Intrinsics, start: Isometry3<f64>) -> Result<Self> {
        settings.check()?;
        k.validate()
            .map_err(|e| Error::InvalidSettings { why: e.to_string() })?;
        if !(start.translation.vector.iter().all(|x| x.is_finite())
            && start.rotation.coords.iter().all(|x| x.is_finite()))
        {
            return Err(Error::InvalidSettings {
                why: "the start pose is not finite".into(),
            });
        }
        Ok(Slam {
            cam: Pinhole {
                fx: k.fx,
                fy: k.fy,
                cx: k.cx,
                cy: k.cy,
                baseline: settings.baseline,
            },
            orb: OrbExtractor::new(settings.orb),
            settings,
            k,
            map: Map::default(),
            kf_odometry: Vec::new(),
            start,
            pose: start,
            prev_pose: start,
            last_odometry: None,
            last_keyframe_inliers: 0,
            lost: 0,
            anchor: None,
            refused: None,
            last_loop: 0,
            loops: 0,
            frames: 0,
            stamp: Vec::new(),
            searches: 0,
            keyframe_wanted: false,
            frames_log: Vec::new(),
            last_relocalised: None,
            localising: false,
        })
    }

    /// A SLAM system that localises in a saved `map` (see [`Map::load`]) from an unknown
    /// start: until a frame matches the map its poses are unconfirmed ([`TrackState::Lost`],
    /// carried by the odometry from the identity); from then on it tracks in the map's frame
    /// and extends the map.
    pub fn with_map(settings: SlamSettings, k: Intrinsics, map: Map) -> Result<Self> {
        let mut s = Self::new(settings, k, Isometry3::identity())?;
        s.kf_odometry = vec![None; map.keyframes.len()];
        s.localising = !map.keyframes.is_empty();
        s.map = map;
        Ok(s)
    }

    /// Whether the pose in a loaded map is still unknown.
    pub fn is_localising(&self) -> bool {
        self.localising
    }

    /// The map so far.
    pub fn map(&self) -> &Map {
        &self.map
    }

    /// The settings.
    pub fn settings(&self) -> &SlamSettings {
        &self.settings
    }

    /// The camera's intrinsics.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.k
    }

    /// The body's latest pose in the map.
    pub fn pose(&self) -> Isometry3<f64> {
        self.pose
    }

    /// Loops closed so far.
    pub fn loops_closed(&self) -> usize {
        self.loops
    }

    fn depth_use(&self, max: f64) -> DepthUse {
        DepthUse {
            min: self.settings.depth_range[0],
            max,
            self_radius: self.settings.self_radius,
        }
    }

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
        // Prediction.
        let odo_delta = match (input.odometry, self.last_odometry) {
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
        if self.map.keyframes.is_empty() {
            self.pose = self.start;
            self.prev_pose = self.start;
            self.last_odometry = input.odometry;
            let n = feats.len();
            self.insert_keyframe(input, &feats, &[], n, false);
            self.log_frame(input.time, true);
            return Ok(TrackReport {
                pose: self.pose,
                state: TrackState::Initialised,
                features: n,
                inliers: 0,
                residual: 0.0,
                keyframe: true,
                loop_closed: false,
            });
        }
        let prior = odo_delta.map(|d| {
            let [dx, dy, dth] = to_planar(&d);
            let dist = dx.hypot(dy);
            let [ft, fr] = self.settings.odometry_drift;
            let st = 0.001 + ft * dist;
            PlanarPrior {
                pose: pred,
                sigma: [st, st, 0.001 + fr * dth.abs() + 0.01 * dist],
            }
        });
        let radius = if odo_delta.is_some() { 15.0 } else { 25.0 };
        // While localising in a loaded map the prediction means nothing: match nothing by it.
        let mut matches = if self.localising {
            Vec::new()
        } else {
            self.search_local(&feats, &pred, &input.camera, radius)
        };
        if !self.localising && matches.len() < 2 * self.settings.min_inliers {
            matches = self.search_local(&feats, &pred, &input.camera, 2.5 * radius);
        }
        let obs = self.observations(&feats, &matches);
        let mut pose = pred;
        let mut inlier = Vec::new();
        let dof = self.settings.dof;
        let mut inliers = optimise_pose(
            &self.cam,
            &mut pose,
            &input.camera,
            &obs,
            dof,
            prior.as_ref(),
            &mut inlier,
        );
        // A pose the wheels disagree with, or none: the matches may be on something the robot
        // moves (a basket its arm pushes along fills the view and turns with it). When enough
        // of the landmarks are seen where the wheels put them, they alone make the pose; when
        // not, the frame is not tracked (the wheels carry it, and a kidnap is found again by
        // relocalisation, which trusts no prediction).
        let wheels = self.wheels_pose(input.odometry);
        if !self.localising {
            if let Some((wheels, sigma)) = wheels {
                if inliers < self.settings.min_inliers || !agrees(&wheels, &pose, sigma) {
                    let split = self.pose_agreeing(&feats, &input.camera, &wheels, sigma, radius);
                    if let Some((p, m, ok, n)) = split {
                        pose = p;
                        matches = m;
                        inlier = ok;
                        inliers = n;
                    } else {
                        inliers = 0;
                    }
                }
            }
        }
        let mut state = TrackState::Tracking;
        let mut kept: Vec<(usize, usize)> = Vec::new();
        if inliers >= self.settings.min_inliers {
            self.lost = 0;
            for (&(f, l), &ok) in matches.iter().zip(&inlier) {
                self.map.landmarks[l].visible += 1;
                if ok {
                    self.map.landmarks[l].found += 1;
                    kept.push((f, l));
                }
            }
            // Every tracked frame refines the landmarks it saw.
            let t_wc = pose * input.camera;
            for &(f, l) in &kept {
                self.fuse(&feats, f, l, &t_wc);
            }
        } else {
            self.lost += 1;
            pose = pred;
            state = if odo_delta.is_some() && !self.localising {
                TrackState::Odometry
            } else {
                TrackState::Lost
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
                match self.relocalise(&feats, &input.camera, trusted) {
                    (Some((p, k)), _) => {
                        pose = p;
                        kept = k;
                        state = TrackState::Relocalised;
                        self.lost = 0;
                        self.localising = false;
                    }
                    (None, Some(refused)) => {
                        self.refuse(refused, input.odometry);
                    }
                    (None, None) => {}
                }
            }
        }
        // Carried by the odometry into a view the map does not hold (or cannot match): a
        // keyframe at the odometry's pose starts the map there, so tracking resumes. Not
        // before this very view failed to match every keyframe (after a kidnap the odometry's
        // pose is wrong, and a map started there would be tracked against for good), nor while
        // it matched somewhere the wheels still refuse.
        let mut restart = state == TrackState::Odometry
            && !self.localising
            && self.lost >= 2
            && feats.len() >= 2 * self.settings.min_inliers;
        if restart {
            match self.relocalise(&feats, &input.camera, self.trusted(wheels)) {
                (Some((p, k)), _) => {
                    pose = p;
                    kept = k;
                    state = TrackState::Relocalised;
                    self.lost = 0;
                    restart = false;
                }
                (None, Some(refused)) => restart = self.refuse(refused, input.odometry),
                (None, None) => {}
            }
        }
        // Without a pose from the map, the constant-velocity model is not carried on.
        self.prev_pose = if matches!(state, TrackState::Tracking | TrackState::Odometry) {
            self.pose
        } else {
            pose
        };
        // Whatever a solve gave, the pose kept is a sound one: a degenerate one is refused and
        // the last good pose kept, the frame lost.
        let pose = renormalised(&pose);
        let (pose, state) = if is_sound(&pose) {
            (pose, state)
        } else {
            (self.pose, TrackState::Lost)
        };
        if state == TrackState::Relocalised {
            self.rebase(pose, input.odometry, false);
        }
        self.pose = pose;
        self.last_odometry = input.odometry;
        let tentative = input.odometry.is_none() && self.confirm(state, &pose);
        let mut keyframe = false;
        let mut loop_closed = false;
        if restart {
            keyframe = true;
            self.lost = 0;
            self.insert_keyframe(input, &feats, &[], feats.len(), true);
        } else if state == TrackState::Tracking || (state == TrackState::Relocalised && !tentative)
        {
            let last = self.map.keyframes.len() - 1;
            let d = self.map.keyframes[last].pose.inverse() * self.pose;
            let moved = d.translation.vector.norm();
            let turned = d.rotation.angle();
            let old = self.old_anchor_count(&kept);
            // A relocalised frame matched old landmarks only: nothing recent to compare with.
            let may_close = state == TrackState::Tracking
                && last + 1 >= self.last_loop + self.settings.loop_age;
            let mut loop_due = may_close && old >= LOOP_MATCHES;
            // Without odometry to bridge a view that is thinning out (a wall's edge seen at an
            // angle), a keyframe is made while enough matches remain to anchor it (issue 56's
            // loss; with odometry the wheels bridge it, and such keyframes of a view the robot
            // carries along, a basket its arm holds, would drag the pose).
            let thinning = input.odometry.is_none() && kept.len() < 2 * self.settings.min_inliers;
            if loop_due
                || moved > self.settings.keyframe_distance
                || turned > self.settings.keyframe_angle
                || (kept.len() < self.last_keyframe_inliers * 6 / 10)
                || thinning
                || self.keyframe_wanted
            {
                keyframe = true;
                self.keyframe_wanted = false;
                // Tracking sees old landmarks only near where the recent ones put them: a
                // drift beyond its search (or its outlier test) would never be closed. So a
                // keyframe also looks for the old keyframes' landmarks wider around its pose.
                let mut seen = kept.clone();
                if may_close && !loop_due {
                    if let Some(more) = self.old_view(&feats, &input.camera, &kept) {
                        seen.extend(more);
                        loop_due = true;
                    }
                }
                if loop_due {
                    loop_closed = self.close_loop(input, &feats, &seen);
                }
                self.insert_keyframe(input, &feats, &kept, kept.len(), false);
                if loop_closed {
                    // The loop moved the pose: what the wheels say is measured from there.
                    self.rebase(self.pose, input.odometry, true);
                }
            }
        }
        if self.lost == 0 {
            self.refused = None;
        }
        self.log_frame(input.time, state != TrackState::Lost && !tentative);
        let t_wc = self.pose;
        let chi2_sum: f64 = kept
            .iter()
            .map(|&(f, l)| {
                chi2(
                    &self.cam,
                    &t_wc,
                    &input.camera,
                    &self.observation(&feats, f, l),
                )
            })
            .filter(|c| c.is_finite())
            .sum();
        let residual = if kept.is_empty() {
            0.0
        } else {
            (chi2_sum / (3 * kept.len()) as f64).sqrt()
        };
        Ok(TrackReport {
            pose: self.pose,
            state,
            features: feats.len(),
            inliers: kept.len(),
            residual,
            keyframe,
            loop_closed,
        })
    }

    /// Makes the next tracked frame a keyframe (its view enters the maps), however little the
    /// camera has moved: an explorer that stopped to look at something asks for this.
    pub fn request_keyframe(&mut self) {
        self.keyframe_wanted = true;
    }

    /// Records the latest pose relative to the newest keyframe, and whether it is confirmed.
    fn log_frame(&mut self, time: f64, confirmed: bool) {
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

    /// Matches of frame features to landmarks `(feature, landmark)`: landmarks of the keyframes
    /// near `pred` projected into the image and matched within `radius` px (times the level's
    /// scale) by Hamming distance, best below 64 bits and clearly better than the runner-up.
    fn search_local(
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

    /// The kept matches of frame `feats` to landmarks of old keyframes (see
    /// [`SlamSettings::loop_age`]) near the current pose, searched wider than tracking does
    /// (no recent landmark among them: their pose is the old landmarks' alone), when at least
    /// [`LOOP_MATCHES`] agree on a pose within [`LOOP_REACH`] of the current one. Features
    /// already matched in `kept` are left out.
    fn old_view(
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

    /// Matches of frame features to the landmarks of keyframes `kfs` (see
    /// [`Slam::search_local`]).
    fn search_in(
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

    /// Whether this frame's pose is tentative (asked only without odometry: with it, the
    /// wheels check a relocalisation): a relocalisation (matched against every keyframe, with
    /// no prediction) is trusted only once the next frame agrees with it, by
    /// tracking from it or by relocalising within [`RELOCALISED_STEP`] of it. A tentative pose
    /// has no place in the trajectory and makes no keyframe: a wrong relocalisation (a repeated
    /// texture, the few matches of a fast turn) made into a keyframe corrupts the map, which
    /// then agrees with it. When the next frame confirms it, its frame gets its pose back.
    fn confirm(&mut self, state: TrackState, pose: &Isometry3<f64>) -> bool {
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

    fn observations(&self, feats: &FrameFeatures, matches: &[(usize, usize)]) -> Vec<Observation> {
        matches
            .iter()
            .map(|&(f, l)| self.observation(feats, f, l))
            .collect()
    }

    /// Standard deviation of a depth `z` (m) measured by the sensor, m.
    fn depth_sigma(&self, z: f64) -> f64 {
        z * z * self.settings.sigma_disparity / (self.cam.fx * self.cam.baseline)
    }

    /// Feature `f` seen as landmark `l`: its measurement, with the errors of the measurement
    /// and of the landmark's position (as seen from the feature's depth) combined.
    fn observation(&self, feats: &FrameFeatures, f: usize, l: usize) -> Observation {
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

    /// Makes `pose` (at `odometry`) the anchor the wheels' word is measured from: when
    /// `force`d, when it agrees closely with the wheels (within one standard deviation), or
    /// when it lies beyond their word (a relocalisation after a kidnap). A pose between those
    /// is not: the anchor stays, so a drag by something moving with the robot, each step
    /// within the wheels' error, still adds up against it.
    fn rebase(&mut self, pose: Isometry3<f64>, odometry: Option<[f64; 3]>, force: bool) {
        let Some(now) = odometry else {
            self.anchor = None;
            return;
        };
        let keep = !force
            && self.wheels_pose(Some(now)).is_some_and(|(w, sigma)| {
                !within(&w, &pose, sigma, 1.0) && agrees(&w, &pose, sigma)
            });
        if !keep {
            self.anchor = Some((pose, now));
        }
    }

    /// Where the wheels put the body now: the anchor moved by the odometry since, with the
    /// standard deviations (m, rad) of that prediction's error.
    fn wheels_pose(&self, odometry: Option<[f64; 3]>) -> Option<(Isometry3<f64>, [f64; 2])> {
        let (at, then) = self.anchor?;
        self.carried(at, then, odometry?)
    }

    /// Pose `at` (odometry `then`) carried by the odometry to `now`, with the standard
    /// deviations (m, rad) of the carried pose's error.
    fn carried(
        &self,
        at: Isometry3<f64>,
        then: [f64; 3],
        now: [f64; 3],
    ) -> Option<(Isometry3<f64>, [f64; 2])> {
        let d = planar(then).inverse() * planar(now);
        let [dx, dy, dth] = to_planar(&d);
        let dist = dx.hypot(dy);
        let [floor, f] = self.settings.odometry_agreement;
        Some((
            at * d,
            [floor + f * dist, floor + f * dth.abs() + 0.01 * dist],
        ))
    }

    /// Notes a relocalised pose the wheels refused (`pose`, at odometry `odometry`); returns
    /// whether the wheels' motion since the first one refused this time contradicts it (it
    /// is on something that moved with the robot, so the wheels are right).
    fn refuse(&mut self, pose: Isometry3<f64>, odometry: Option<[f64; 3]>) -> bool {
        let Some(now) = odometry else {
            return false;
        };
        match self.refused {
            None => {
                self.refused = Some((pose, now));
                false
            }
            Some((first, then)) => self
                .carried(first, then, now)
                .is_some_and(|(p, sigma)| !agrees(&p, &pose, sigma)),
        }
    }

    /// The pose from the matches that agree with the wheels' pose `wheels`: the landmarks
    /// searched for where it puts them (within `radius` px), kept when seen there give or
    /// take its error `sigma` (m, rad), the pose refined on them with the wheels as a prior.
    /// Returns the pose, the matches, each one's verdict and the inlier count; `None` when too
    /// few agree or their pose strays from the wheels' as well.
    fn pose_agreeing(
        &mut self,
        feats: &FrameFeatures,
        t_bc: &Isometry3<f64>,
        wheels: &Isometry3<f64>,
        sigma: [f64; 2],
        radius: f64,
    ) -> Option<Agreeing> {
        let matches = self.search_local(feats, wheels, t_bc, radius);
        let obs = self.observations(feats, &matches);
        let fb = self.cam.fx * self.cam.baseline;
        let agreeing: Vec<usize> = obs
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                let z = fb / o.measured.z;
                let px = self.cam.fx * WITHIN * (sigma[1] + sigma[0] / z);
                let disparity = fb * WITHIN * sigma[0] / (z * z);
                let wide = Observation {
                    sigma_px: o.sigma_px.hypot(px),
                    sigma_disparity: o.sigma_disparity.hypot(disparity),
                    ..**o
                };
                chi2(&self.cam, wheels, t_bc, &wide) <= CHI2_3
            })
            .map(|(i, _)| i)
            .collect();
        if agreeing.len() < self.settings.min_inliers {
            return None;
        }
        let sub: Vec<Observation> = agreeing.iter().map(|&i| obs[i]).collect();
        let prior = PlanarPrior {
            pose: *wheels,
            sigma: [sigma[0], sigma[0], sigma[1]],
        };
        let mut pose = *wheels;
        let mut ok = Vec::new();
        let n = optimise_pose(
            &self.cam,
            &mut pose,
            t_bc,
            &sub,
            self.settings.dof,
            Some(&prior),
            &mut ok,
        );
        if n < self.settings.min_inliers || !agrees(wheels, &pose, sigma) {
            return None;
        }
        let mut all = vec![false; obs.len()];
        for (&i, &good) in agreeing.iter().zip(&ok) {
            all[i] = good;
        }
        Some((pose, matches, all, n))
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
    fn insert_keyframe(
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

    /// Fuses feature `f`'s measurement (its depth, from camera pose `t_wc`) into landmark `l`:
    /// inverse-variance weights, in the landmark's anchor frame.
    fn fuse(&mut self, feats: &FrameFeatures, f: usize, l: usize, t_wc: &Isometry3<f64>) {
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

    /// Closes a loop at the keyframe about to be inserted: the pose from the recent landmarks
    /// alone (or the odometry) is the tracking edge from the previous keyframe, the pose from
    /// the old landmarks alone is the loop edge to their commonest anchor; the pose graph then
    /// moves every keyframe. Returns whether it did.
    fn close_loop(
        &mut self,
        input: &RgbdInput<'_>,
        feats: &FrameFeatures,
        kept: &[(usize, usize)],
    ) -> bool {
        let obs: Vec<Observation> = kept
            .iter()
            .map(|&(f, l)| self.observation(feats, f, l))
            .collect();
        let n = self.map.keyframes.len();
        let cut = n.saturating_sub(self.settings.loop_age);
        let (mut old_obs, mut new_obs) = (Vec::new(), Vec::new());
        let mut anchors = std::collections::HashMap::<usize, usize>::new();
        for (&(_, l), o) in kept.iter().zip(&obs) {
            let a = self.map.landmarks[l].keyframe;
            if a < cut {
                old_obs.push(*o);
                *anchors.entry(a).or_default() += 1;
            } else {
                new_obs.push(*o);
            }
        }
        let Some((&anchor, _)) = anchors.iter().max_by_key(|(&a, &c)| (c, a)) else {
            return false;
        };
        let dof = self.settings.dof;
        let mut inl = Vec::new();
        let mut t_old = self.pose;
        if optimise_pose(
            &self.cam,
            &mut t_old,
            &input.camera,
            &old_obs,
            dof,
            None,
            &mut inl,
        ) < self.settings.min_inliers
        {
            return false;
        }
        let prev = n - 1;
        let mut t_new = self.pose;
        let recent_ok = optimise_pose(
            &self.cam,
            &mut t_new,
            &input.camera,
            &new_obs,
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
                _ => return false,
            }
        }
        let gap = t_new.inverse() * t_old;
        if gap.translation.vector.norm() < 0.003 && gap.rotation.angle() < 0.003 {
            self.last_loop = n;
            return false;
        }
        let z_seq = self.map.keyframes[prev].pose.inverse() * t_new;
        let dist = z_seq.translation.vector.norm();
        let closing = [
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
        ];
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

    /// The wheels' pose while it is still trusted over a relocalisation's: for the first
    /// [`WHEELS_TRUSTED`] frames lost. (A relocalisation far from it then is more likely on
    /// something the robot moved than a kidnap; a kidnapped robot stays lost longer.)
    fn trusted(
        &self,
        wheels: Option<(Isometry3<f64>, [f64; 2])>,
    ) -> Option<(Isometry3<f64>, [f64; 2])> {
        wheels.filter(|_| self.lost < WHEELS_TRUSTED)
    }

    /// The pose of a frame found by matching its features against every keyframe's (no
    /// prediction): the keyframes with the most descriptor matches are tried in turn with a
    /// RANSAC of rigid fits on the matched 3-D points, then the pose is refined. With the
    /// `wheels`' pose (and its error), only a pose that agrees with it is taken; the first one
    /// found and refused is returned too.
    fn relocalise(
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
