//! What the camera and SLAM tell the base's goals, kept by the robot's pump: where SLAM's map
//! lies in the odometry's frame (so a base steers by SLAM's pose at the odometry's rate, as ROS
//! does with `map → odom`), the obstacles the newest depth image shows (cut to PyRobot's
//! 0.1-0.8 m band, in the map's frame), and SLAM's occupancy grid, refreshed every few seconds
//! while a goal plans on it.

use std::time::Duration;

use ferrobot_geometry::Pose2;
use ferrobot_nav::depth_scan::Ball;
use ferrobot_nav::{LiveObstacles, MapImage, Scan};
use nalgebra::Isometry3;

use ferrobot_description::RobotConfig;
use ferrobot_planning::spheres::Sphere;

use crate::error::Result;
use crate::frames::Frames;

/// Scans are taken at most this often, s (the camera gives 30 frames a second).
const SCAN_PERIOD: f64 = 0.1;
use ferrobot_nav::depth_scan::OBSTACLE_BAND;
/// SLAM's occupancy grid is rebuilt at most this often while a goal plans on it, s.
const MAP_PERIOD: f64 = 3.0;

/// What the camera and SLAM tell the base's goals.
#[derive(Default)]
pub(crate) struct Sense {
    /// What scans are made with, once a goal asks for them.
    pub(crate) camera: Option<Eyes>,
    /// SLAM's map in the odometry's frame (`T_map_odom`), from SLAM's newest tracked frame.
    pub(crate) map_from_odom: Option<Pose2>,
    /// The newest scan: its number (counting from 1), its time (s), the scan.
    pub(crate) scan: Option<(u64, f64, Scan)>,
    /// When the next scan may be taken.
    pub(crate) next_scan: Duration,
    /// SLAM's occupancy grid: its number (counting from 1) and the grid, in the map's frame.
    pub(crate) grid: Option<(u64, MapImage)>,
    /// When the grid may next be rebuilt.
    pub(crate) next_grid: Duration,
    /// A goal wants SLAM's next tracked frame to be a keyframe (it stopped to look).
    pub(crate) want_keyframe: std::cell::Cell<bool>,
    /// The live obstacles the last goal on a map saw, for the next (as move_base's obstacle
    /// layer outlives its goals): whether they are in SLAM's map (else the odometry's frame),
    /// and the layer.
    pub(crate) live: std::cell::RefCell<Option<(bool, LiveObstacles)>>,
    /// A correction unlike the one in use, and how many frames in a row have agreed with it.
    candidate: Option<(Pose2, usize)>,
}

/// A SLAM frame's correction (`T_map_odom`) is taken when it lies within this of the one in
/// use (m, rad): the odometry's drift moves it by far less between frames, and a SLAM pose
/// that sticks while the base turns at 0.4 rad/s or faster moves it by more (0.013 rad a frame).
const CORRECTION_GATE: (f64, f64) = (0.02, 0.01);
/// A correction outside the gate is taken once this many frames in a row agree with it (a
/// relocalisation after a kidnap); a SLAM pose that sticks while the wheels turn gives a new
/// correction every frame and is never taken.
const CORRECTION_CONFIRM: usize = 15;

impl std::fmt::Debug for Sense {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Sense")
            .field("map_from_odom", &self.map_from_odom)
            .finish_non_exhaustive()
    }
}

impl Sense {
    /// Takes SLAM's correction from one frame, gated: small changes (the odometry's drift
    /// corrected) at once, a jump only once [`CORRECTION_CONFIRM`] frames agree on it.
    pub(crate) fn offer_correction(&mut self, c: Pose2) {
        let near = |a: &Pose2, b: &Pose2| {
            let d = a.inverse().compose(b);
            d.x.hypot(d.y) < CORRECTION_GATE.0 && d.theta.abs() < CORRECTION_GATE.1
        };
        match self.map_from_odom {
            None => self.map_from_odom = Some(c),
            Some(old) if near(&old, &c) => {
                self.map_from_odom = Some(c);
                self.candidate = None;
            }
            Some(_) => match self.candidate {
                Some((k, n)) if near(&k, &c) => {
                    if n + 1 >= CORRECTION_CONFIRM {
                        self.map_from_odom = Some(c);
                        self.candidate = None;
                    } else {
                        self.candidate = Some((c, n + 1));
                    }
                }
                _ => self.candidate = Some((c, 1)),
            },
        }
    }

    /// Forgets what SLAM said (it is started anew or stopped).
    pub(crate) fn forget_slam(&mut self) {
        let live = self.live.get_mut();
        if live.as_ref().is_some_and(|l| l.0) {
            *live = None;
        }
        self.map_from_odom = None;
        self.candidate = None;
        self.grid = None;
    }

    /// Whether a scan is due at `now`.
    pub(crate) fn scan_due(&self, now: Duration) -> bool {
        now >= self.next_scan
    }

    /// Keeps `scan`, taken at `now`.
    pub(crate) fn keep_scan(&mut self, now: Duration, scan: Scan) {
        let n = self.scan.as_ref().map_or(1, |s| s.0 + 1);
        self.scan = Some((n, now.as_secs_f64(), scan));
        self.next_scan = now + Duration::from_secs_f64(SCAN_PERIOD);
    }

    /// Whether SLAM's grid is due to be rebuilt at `now`.
    pub(crate) fn grid_due(&self, now: Duration) -> bool {
        now >= self.next_grid
    }

    /// Keeps SLAM's grid, rebuilt at `now`.
    pub(crate) fn keep_grid(&mut self, now: Duration, grid: MapImage) {
        let n = self.grid.as_ref().map_or(1, |g| g.0 + 1);
        self.grid = Some((n, grid));
        self.next_grid = now + Duration::from_secs_f64(MAP_PERIOD);
    }

    /// The live obstacles kept for a goal in SLAM's map (`slam`) or the odometry's frame.
    pub(crate) fn live_for(&self, slam: bool) -> Option<LiveObstacles> {
        self.live
            .borrow()
            .as_ref()
            .filter(|l| l.0 == slam)
            .map(|l| l.1.clone())
    }

    /// Keeps the live obstacles a goal saw, in SLAM's map (`slam`) or the odometry's frame.
    pub(crate) fn keep_live(&self, slam: bool, live: &LiveObstacles) {
        *self.live.borrow_mut() = Some((slam, live.clone()));
    }

    /// The base's pose `[x, y, θ]` in the map's frame from its odometry pose: through SLAM's
    /// correction when `slam`, else the odometry's own. `None` when SLAM has no pose yet.
    pub(crate) fn in_map(&self, odometry: [f64; 3], slam: bool) -> Option<Pose2> {
        let o = Pose2::from(odometry);
        if slam {
            self.map_from_odom.map(|c| c.compose(&o))
        } else {
            Some(o)
        }
    }
}

/// A depth point nearer than this to the robot's own body (its links' covering spheres) is the
/// robot itself, m: the covers hold the collision shapes; the margin takes the depth's noise
/// and the joints' lag behind their telemetry.
pub const SELF_MARGIN: f64 = 0.03;

/// What a goal that wants obstacle scans needs to make them: the robot's frames, its camera's
/// optical frame, and its own body (to leave out of the scans).
#[derive(Debug, Clone)]
pub(crate) struct Eyes {
    pub(crate) frames: Frames,
    pub(crate) optical: String,
    pub(crate) body: SelfBody,
}

/// The robot's own body as its camera may see it: each link's covering spheres (link frame).
#[derive(Debug, Clone)]
pub(crate) struct SelfBody {
    /// Link index (the URDF tree's order) and the link's spheres.
    links: Vec<(usize, Vec<Sphere>)>,
}

impl SelfBody {
    /// The body of `cfg`'s URDF collision shapes.
    pub(crate) fn new(cfg: &RobotConfig) -> Result<Self> {
        let links = ferrobot_planning::config_geometry(cfg)?
            .into_iter()
            .enumerate()
            .filter(|(_, g)| !g.is_empty())
            .map(|(i, g)| (i, g.spheres))
            .collect();
        Ok(SelfBody { links })
    }

    /// How far the links `links` (tree indices) reach from the base's centre across the floor,
    /// m: the largest horizontal distance of their covering spheres (no margin) from the
    /// vertical through the origin of `poses`' frame (the base's), counting only the spheres
    /// that come down into the map's obstacle band ([`OBSTACLE_BAND`]: what is above it
    /// meets nothing the map holds). 0 when none does.
    pub(crate) fn reach(&self, poses: &[Isometry3<f64>], links: &[usize]) -> f64 {
        self.links
            .iter()
            .filter(|(i, _)| links.contains(i))
            .filter_map(|(i, spheres)| poses.get(*i).map(|p| (p, spheres)))
            .flat_map(|(p, spheres)| spheres.iter().map(move |s| (p * s.centre, s.radius)))
            .filter(|(c, r)| c.z - r <= OBSTACLE_BAND[1])
            .map(|(c, r)| c.x.hypot(c.y) + r)
            .fold(0.0, f64::max)
    }

    /// How far the links `links` (tree indices; every link when `None`) reach ahead of the
    /// base's centre, m: the largest x (in the frame of `poses`, the base's) of their
    /// covering spheres (no margin) that come down below `below` (m, that frame's z). 0 when
    /// none does.
    pub(crate) fn ahead(
        &self,
        poses: &[Isometry3<f64>],
        links: Option<&[usize]>,
        below: f64,
    ) -> f64 {
        self.links
            .iter()
            .filter(|(i, _)| links.is_none_or(|l| l.contains(i)))
            .filter_map(|(i, spheres)| poses.get(*i).map(|p| (p, spheres)))
            .flat_map(|(p, spheres)| spheres.iter().map(move |s| (p * s.centre, s.radius)))
            .filter(|(c, r)| c.z - r <= below)
            .map(|(c, r)| c.x + r)
            .fold(0.0, f64::max)
    }

    /// How far the links reach from the base's vertical axis in any direction, m: the
    /// largest horizontal distance (in the frame of `poses`, the base's) of their covering
    /// spheres' far sides (no margin), among those that come down below `below` (m, that
    /// frame's z). The radius of the circle the body sweeps turning in place. 0 when none does.
    pub(crate) fn around(&self, poses: &[Isometry3<f64>], below: f64) -> f64 {
        self.links
            .iter()
            .filter_map(|(i, spheres)| poses.get(*i).map(|p| (p, spheres)))
            .flat_map(|(p, spheres)| spheres.iter().map(move |s| (p * s.centre, s.radius)))
            .filter(|(c, r)| c.z - r <= below)
            .map(|(c, r)| c.x.hypot(c.y) + r)
            .fold(0.0, f64::max)
    }

    /// The spheres grown by [`SELF_MARGIN`], placed by the links' poses `poses` (tree order)
    /// in their frame.
    pub(crate) fn placed(&self, poses: &[Isometry3<f64>]) -> Vec<Ball> {
        self.links
            .iter()
            .filter_map(|(i, spheres)| poses.get(*i).map(|p| (p, spheres)))
            .flat_map(|(p, spheres)| {
                spheres.iter().map(move |s| Ball {
                    centre: p * s.centre,
                    radius: s.radius + SELF_MARGIN,
                })
            })
            .collect()
    }
}
