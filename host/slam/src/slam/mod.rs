//! The SLAM system ([`Slam`]): a sans-IO state machine fed with RGB-D frames (and, on a robot,
//! the wheel odometry and the camera's pose on the body), returning the body's pose in the map
//! (m, rad; the map's frame is the world's). How it tracks, makes keyframes, closes loops,
//! relocalises and lets the wheels check the camera: `docs/design/slam.md`.
//!
//! One state, its methods in files by concern: `track` (a frame, step by step), `matching`
//! (landmarks searched and measured), `wheels` (the odometry's word), `keyframes`,
//! `loop_closure` and `relocalise`; its settings in `settings`.

use ferrobot_perception::{DepthImage, Intrinsics, RgbImage};
use nalgebra::Isometry3;

use crate::error::{Error, Result};
use crate::frame::DepthUse;
use crate::map::Map;
use crate::optimise::Pinhole;
use crate::orb::OrbExtractor;

mod keyframes;
mod loop_closure;
mod matching;
mod relocalise;
mod settings;
mod track;
mod wheels;

pub use settings::{SlamSettings, MAX_INLIERS, MAX_LOOP_AGE};

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

    /// Makes the next tracked frame a keyframe (its view enters the maps), however little the
    /// camera has moved: an explorer that stopped to look at something asks for this.
    pub fn request_keyframe(&mut self) {
        self.keyframe_wanted = true;
    }
}
