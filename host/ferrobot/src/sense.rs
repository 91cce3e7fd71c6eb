//! What the camera and SLAM tell the base's goals, kept by the robot's pump: where SLAM's map
//! lies in the odometry's frame (so a base steers by SLAM's pose at the odometry's rate, as ROS
//! does with `map → odom`), the obstacles the newest depth image shows (cut to PyRobot's
//! 0.1-0.8 m band, in the map's frame), and SLAM's occupancy grid, refreshed every few seconds
//! while a goal plans on it.

use std::time::Duration;

use ferrobot_geometry::Pose2;
use ferrobot_nav::{MapImage, Scan};
use ferrobot_perception::{DepthImage, Intrinsics};
use nalgebra::{Isometry3, Point3};

use crate::frames::Frames;
use crate::slam::SELF_RADIUS;

/// Scans are taken at most this often, s (the camera gives 30 frames a second).
const SCAN_PERIOD: f64 = 0.1;
/// Depth beyond this is not reported, m (a D435's error grows with the square of the range).
pub const SCAN_RANGE: f64 = 2.5;
/// Every this many rows and columns of the depth image are scanned.
const SCAN_STRIDE: usize = 4;
/// Heights above the floor that are obstacles, m (PyRobot's occupancy band).
pub const OBSTACLE_BAND: [f64; 2] = [0.1, 0.8];
/// SLAM's occupancy grid is rebuilt at most this often while a goal plans on it, s.
const MAP_PERIOD: f64 = 3.0;

/// What the camera and SLAM tell the base's goals.
#[derive(Default)]
pub(crate) struct Sense {
    /// The robot's kinematic frames and its camera's optical frame, once a goal asks for scans.
    pub(crate) camera: Option<(Frames, String)>,
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

/// The obstacles a depth image shows, as a [`Scan`] in the map's frame: every
/// [`SCAN_STRIDE`]-th pixel with a depth up to [`SCAN_RANGE`], kept when it lies within
/// [`OBSTACLE_BAND`] above the floor and at least [`SELF_RADIUS`] from the base's centre (nearer
/// is the robot's own arm). `camera` is the optical frame's pose in the map, `base` the base's
/// pose in it.
pub(crate) fn obstacle_scan(
    depth: &DepthImage,
    k: &Intrinsics,
    camera: &Isometry3<f64>,
    base: Pose2,
) -> Scan {
    let mut points = Vec::new();
    let w = depth.width as usize;
    let h = depth.height as usize;
    for row in (0..h).step_by(SCAN_STRIDE) {
        for col in (0..w).step_by(SCAN_STRIDE) {
            let Some(z) = depth.get(row, col) else {
                continue;
            };
            let z = z as f64;
            if !(z > 0.0 && z <= SCAN_RANGE) {
                continue;
            }
            let p = camera * k.unproject(row as f64, col as f64, z);
            if !(OBSTACLE_BAND[0]..=OBSTACLE_BAND[1]).contains(&p.z) {
                continue;
            }
            if (p.x - base.x).hypot(p.y - base.y) < SELF_RADIUS {
                continue;
            }
            points.push([p.x, p.y]);
        }
    }
    // The optical axis (z) on the floor's plane gives the heading.
    let axis = camera * Point3::new(0.0, 0.0, 1.0) - camera * Point3::origin();
    let at = camera.translation.vector;
    let off = (at.x - base.x).hypot(at.y - base.y);
    Scan {
        sensor: [at.x, at.y, axis.y.atan2(axis.x)],
        half_fov: (0.5 * k.width as f64 / k.fx).atan(),
        // Nothing nearer the base than the self-mask is reported, so nothing there is cleared.
        near: SELF_RADIUS + off,
        range: SCAN_RANGE,
        points,
    }
}
