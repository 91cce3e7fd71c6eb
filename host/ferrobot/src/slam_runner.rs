//! SLAM as the hub runs it: the SLAM state, the frames and optical frame its camera poses are
//! computed with, its last report and error, and the occupancy grid kept for the base's goals;
//! and where a base's pose comes from ([`Source`]).

use ferrobot_slam::{OccupancyGrid, Slam, TrackReport};

use crate::frames::Frames;

/// Where a base's pose comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The wheel odometry (its frame starts where the base started).
    Odometry,
    /// SLAM's map (see [`crate::Robot::start_slam`]).
    Slam,
}

/// SLAM as the robot's pump feeds it.
pub(crate) struct SlamRunner {
    pub(crate) slam: Slam,
    pub(crate) frames: Frames,
    pub(crate) optical: String,
    pub(crate) last: Option<TrackReport>,
    /// The last failure to take, place or track a frame, or to refresh the grid, since a
    /// frame was last tracked (a passing hiccup does not stay an error for good).
    pub(crate) error: Option<String>,
    /// The occupancy grid of SLAM's map, kept up to date for the goals that plan on it (each
    /// refresh counts only the keyframes that are new or that a loop closure moved).
    pub(crate) grid: OccupancyGrid,
}

impl std::fmt::Debug for SlamRunner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlamRunner").finish_non_exhaustive()
    }
}

/// Points nearer the base's z axis than this are the robot itself, m: the LoCoBot's folded
/// arm reaches 0.41 m ahead of the base's centre.
pub const SELF_RADIUS: f64 = 0.5;

/// The odometry pose `[x, y, θ]` (m, rad, the odometry's frame) of telemetry `tel` carried to
/// time `t` (s, the robot's clock) by its forward speed and yaw rate, at most 0.1 s either way:
/// the odometry at a camera frame's instant.
pub fn odometry_at(tel: &ferrobot_protocol::Telemetry, t: f64) -> [f64; 3] {
    let o = tel.odometry;
    let dt = (t - tel.time_us as f64 * 1e-6).clamp(-0.1, 0.1);
    let (v, w, th) = (o.v as f64, o.w as f64, o.theta as f64);
    let mid = th + 0.5 * w * dt;
    [
        o.x as f64 + v * dt * mid.cos(),
        o.y as f64 + v * dt * mid.sin(),
        th + w * dt,
    ]
}
