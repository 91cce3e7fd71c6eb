//! What the camera and SLAM tell the base's goals, kept by the robot's pump: where SLAM's map
//! lies in the odometry's frame (so a base steers by SLAM's pose at the odometry's rate, as ROS
//! does with `map → odom`), the obstacles the newest depth image shows (cut to PyRobot's
//! 0.1-0.8 m band, in the map's frame), and SLAM's occupancy grid, refreshed every few seconds
//! while a goal plans on it.

use std::time::Duration;

use ferrobot_geometry::Pose2;
use ferrobot_nav::{LiveObstacles, MapImage, Scan};
use ferrobot_perception::{DepthImage, Intrinsics};
use nalgebra::{Isometry3, Point3};

use ferrobot_description::RobotConfig;
use ferrobot_planning::spheres::Sphere;

use crate::error::Result;
use crate::frames::Frames;

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
    pub(crate) fn placed(&self, poses: &[Isometry3<f64>]) -> Vec<Sphere> {
        self.links
            .iter()
            .filter_map(|(i, spheres)| poses.get(*i).map(|p| (p, spheres)))
            .flat_map(|(p, spheres)| {
                spheres.iter().map(move |s| Sphere {
                    centre: p * s.centre,
                    radius: s.radius + SELF_MARGIN,
                })
            })
            .collect()
    }
}

/// The obstacles a depth image shows, as a [`Scan`] in the map's frame: every
/// [`SCAN_STRIDE`]-th pixel with a depth up to [`SCAN_RANGE`], kept when it lies within
/// [`OBSTACLE_BAND`] above the floor and outside the robot's own body `body` (spheres in the
/// base's frame, from [`SelfBody::placed`]). `camera` is the optical frame's pose in the map,
/// `base` the base's pose in it. The scan's near range is where the lowest rays of the image
/// reach down to the band: nearer, a low obstacle is out of view, so nothing there is cleared.
pub(crate) fn obstacle_scan(
    depth: &DepthImage,
    k: &Intrinsics,
    camera: &Isometry3<f64>,
    base: Pose2,
    body: &[Sphere],
) -> Scan {
    let mut points = Vec::new();
    let w = depth.width as usize;
    let h = depth.height as usize;
    // Beyond this from the base's centre no point is the body's.
    let reach = body
        .iter()
        .map(|b| b.centre.x.hypot(b.centre.y) + b.radius)
        .fold(0.0, f64::max);
    let (sin, cos) = base.theta.sin_cos();
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
            let (dx, dy) = (p.x - base.x, p.y - base.y);
            if dx.hypot(dy) < reach {
                let q = Point3::new(cos * dx + sin * dy, cos * dy - sin * dx, p.z);
                if body.iter().any(|b| (q - b.centre).norm() < b.radius) {
                    continue;
                }
            }
            points.push([p.x, p.y]);
        }
    }
    // The optical axis (z) on the floor's plane gives the heading.
    let axis = camera * Point3::new(0.0, 0.0, 1.0) - camera * Point3::origin();
    let at = camera.translation.vector;
    Scan {
        sensor: [at.x, at.y, axis.y.atan2(axis.x)],
        half_fov: (0.5 * k.width as f64 / k.fx).atan(),
        near: blind_distance(camera, k).min(SCAN_RANGE),
        range: SCAN_RANGE,
        points,
    }
}

/// How far from the camera (m, along the floor) its image's lowest rays come down to the
/// bottom of [`OBSTACLE_BAND`]: nearer, an obstacle of the band's least height is out of view.
/// The lower corners are the farthest-reaching rays of the bottom row; a camera that looks
/// level or up never sees the band's bottom ahead ([`f64::INFINITY`]).
fn blind_distance(camera: &Isometry3<f64>, k: &Intrinsics) -> f64 {
    let above = camera.translation.z - OBSTACLE_BAND[0];
    if above <= 0.0 {
        return 0.0;
    }
    let row = f64::from(k.height) - 1.0;
    [0.0, f64::from(k.width) - 1.0]
        .into_iter()
        .map(|col| {
            let d = camera.rotation * k.unproject(row, col, 1.0).coords;
            if d.z >= 0.0 {
                f64::INFINITY
            } else {
                above / -d.z * d.x.hypot(d.y)
            }
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

    fn intrinsics() -> Intrinsics {
        Intrinsics {
            width: 64,
            height: 48,
            fx: 60.0,
            fy: 60.0,
            cx: 31.5,
            cy: 23.5,
        }
    }

    /// An optical frame at `at` (m, base frame) looking along the base's x, pitched down by
    /// `pitch` rad.
    fn camera(at: [f64; 3], pitch: f64) -> Isometry3<f64> {
        // Optical x right (-y), y down (-z), z ahead (x).
        let optical = Rotation3::from_matrix_unchecked(Matrix3::new(
            0.0, 0.0, 1.0, //
            -1.0, 0.0, 0.0, //
            0.0, -1.0, 0.0,
        ));
        let tilt = Rotation3::from_axis_angle(&Vector3::y_axis(), pitch);
        Isometry3::from_parts(
            Translation3::new(at[0], at[1], at[2]),
            UnitQuaternion::from_rotation_matrix(&(tilt * optical)),
        )
    }

    #[test]
    fn nearer_than_the_blind_distance_the_band_s_bottom_is_out_of_view() {
        let k = intrinsics();
        let cam = camera([0.1, 0.0, 0.6], 0.45);
        let d = blind_distance(&cam, &k);
        assert!(d > 0.2 && d < 1.0, "{d}");
        // Along the lower corners' bearing, a point at the band's bottom just beyond the
        // distance is above the image's bottom edge, just nearer it is below it.
        let corner = cam.rotation * k.unproject(47.0, 0.0, 1.0).coords;
        let bearing = corner.y.atan2(corner.x);
        let in_view = |r: f64| {
            let p = Point3::new(0.1 + r * bearing.cos(), r * bearing.sin(), OBSTACLE_BAND[0]);
            let (_, v) = k.project(&(cam.inverse() * p)).expect("ahead");
            v <= 47.0
        };
        assert!(in_view(d + 0.01), "beyond {d}");
        assert!(!in_view(d - 0.01), "before {d}");
        // Level, the band's bottom is never seen ahead; below it, nothing hides it.
        assert_eq!(
            blind_distance(&camera([0.0, 0.0, 0.6], -0.5), &k),
            f64::INFINITY
        );
        assert_eq!(blind_distance(&camera([0.0, 0.0, 0.05], 0.3), &k), 0.0);
    }

    #[test]
    fn the_robot_s_own_body_is_left_out_of_a_scan_and_what_lies_beyond_is_kept() {
        let k = intrinsics();
        // A level camera 0.4 m up, a wall 1 m ahead, and in front of the image's centre a
        // link (a 0.05 m sphere 0.4 m ahead) whose pixels read its depth.
        let cam = camera([0.0, 0.0, 0.4], 0.0);
        let link = Sphere {
            centre: Point3::new(0.4, 0.0, 0.4),
            radius: 0.05,
        };
        let mut data = vec![1.0f32; 64 * 48];
        for row in 0..48 {
            for col in 0..64 {
                let ray = k.unproject(row as f64, col as f64, 1.0);
                if ray.x.hypot(ray.y) < 0.1 {
                    data[row * 64 + col] = 0.4;
                }
            }
        }
        let depth = DepthImage::new(64, 48, data).expect("depth");
        let placed = Sphere {
            radius: link.radius + SELF_MARGIN,
            ..link
        };
        // The base at (2, 1) turned a quarter: the scan is in the map's frame.
        let base = Pose2::new(2.0, 1.0, std::f64::consts::FRAC_PI_2);
        let in_map = optimise_planar(base) * cam;
        let masked = obstacle_scan(&depth, &k, &in_map, base, &[placed]);
        let blind = obstacle_scan(&depth, &k, &in_map, base, &[]);
        let near = |s: &Scan| {
            s.points
                .iter()
                .filter(|p| (p[0] - 2.0).hypot(p[1] - 1.4) < 0.02)
                .count()
        };
        assert!(
            near(&blind) > 0,
            "the link's pixels are points without the mask"
        );
        assert_eq!(near(&masked), 0, "the link is the robot's own");
        // The wall's points (1 m ahead, +y in the map) are kept either way.
        let wall = |s: &Scan| {
            s.points
                .iter()
                .filter(|p| (p[1] - 2.0).abs() < 0.02)
                .count()
        };
        assert!(wall(&masked) > 0);
        assert_eq!(wall(&masked), wall(&blind));
        assert!((masked.sensor[2] - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    }

    fn optimise_planar(p: Pose2) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(p.x, p.y, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), p.theta),
        )
    }
}
