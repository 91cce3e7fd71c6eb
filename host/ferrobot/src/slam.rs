//! SLAM beside the robot: once started ([`Robot::start_slam`]), every camera frame that time
//! passes over is fed to [`ferrobot_slam::Slam`] with the wheel odometry at its instant and the
//! camera's pose on the body from the measured head joints, whoever lets the time pass (a
//! motion's wait, [`Robot::wait`], [`crate::Camera::get_frame`]). The base's pose in the map is
//! then [`crate::Base::get_state_from`]`(Source::Slam)`; the maps are [`Robot::slam_map_3d`]
//! and [`Robot::slam_occupancy_map`].
//!
//! Frames are fed as the pump passes their instants, which a camera that knows its frame times
//! supports (the simulated one); a real driver would need its own capture thread, which does
//! not exist yet: starting SLAM on such a robot is refused.

use std::time::Duration;

/// The SLAM crate: tracking, keyframes, loop closure, the maps, trajectories and their error.
pub use ferrobot_slam::*;

use ferrobot_geometry::Pose2;
use ferrobot_nav::MapImage;
use ferrobot_perception::PointCloud;

use crate::camera::RawFrame;
use crate::frames::Frames;
use crate::hub::Hub;
use crate::robot::Robot;

/// Where a base's pose comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The wheel odometry (its frame starts where the base started).
    Odometry,
    /// SLAM's map (see [`Robot::start_slam`]).
    Slam,
}

/// SLAM as the robot's pump feeds it.
pub(crate) struct SlamRunner {
    slam: Slam,
    frames: Frames,
    optical: String,
    last: Option<TrackReport>,
    /// The last failure to take, place or track a frame, or to refresh the grid, since a
    /// frame was last tracked (a passing hiccup does not stay an error for good).
    error: Option<String>,
    /// The occupancy grid of SLAM's map, kept up to date for the goals that plan on it (each
    /// refresh counts only the keyframes that are new or that a loop closure moved).
    grid: OccupancyGrid,
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

impl Hub {
    /// Takes the frame whose instant time has just passed, if anyone wants it: SLAM, when it
    /// runs, gets every frame; the base's goals that want obstacle scans or SLAM's occupancy
    /// grid get them (see [`crate::sense`]). The pump calls this after every wait. A failure
    /// is kept for [`Robot::slam_report`] (and a goal without scans goes on without them).
    pub(crate) fn feed_camera(&mut self) {
        let now = self.link.now();
        let scans = self.sense.scan_due(now) && self.goals.any(|g| g.wants_scans());
        if self.slam.is_some() && self.sense.grid_due(now) && self.goals.any(|g| g.wants_grid()) {
            self.refresh_grid(now);
        }
        if self.slam.is_none() && !scans {
            return;
        }
        let Some(camera) = self.camera.as_mut() else {
            return;
        };
        if !camera.until_next(now).is_zero() {
            return;
        }
        let got = self
            .link
            .telemetry()
            .and_then(|tel| Ok((camera.capture(self.link.as_mut())?, tel)));
        match got {
            Ok((raw, tel)) => {
                self.feed_frame(&tel, &raw);
                if scans {
                    self.scan_frame(&tel, &raw);
                }
            }
            Err(e) => {
                if let Some(r) = self.slam.as_mut() {
                    r.error = Some(e.to_string());
                }
            }
        }
    }

    /// Rebuilds SLAM's occupancy grid for the goals that plan on it.
    fn refresh_grid(&mut self, now: Duration) {
        let Some(r) = self.slam.as_mut() else {
            return;
        };
        match r.grid.update(r.slam.map()) {
            Ok(Some(image)) => self.sense.keep_grid(now, image),
            Ok(None) => {}
            Err(e) => r.error = Some(e.to_string()),
        }
    }

    /// Makes the obstacle scan of a frame taken with telemetry `tel`, in the map's frame (SLAM's
    /// when it runs and has a pose, else the odometry's).
    fn scan_frame(&mut self, tel: &ferrobot_protocol::Telemetry, raw: &RawFrame) {
        let (Some(eyes), Some(camera)) = (self.sense.camera.as_ref(), self.camera.as_ref()) else {
            return;
        };
        let Ok(poses) = eyes.frames.poses_in(tel, crate::frames::BASE_FRAME) else {
            return;
        };
        let Some(on_base) = eyes
            .frames
            .link_index(&eyes.optical)
            .and_then(|i| poses.get(i))
            .copied()
        else {
            return;
        };
        let odometry = odometry_at(tel, raw.time.as_secs_f64());
        let Some(base) = self.sense.in_map(odometry, self.slam.is_some()) else {
            return;
        };
        let camera_pose = optimise::planar(base.to_array()) * on_base;
        let body = eyes.body.placed(&poses);
        let scan = ferrobot_nav::depth_scan::obstacle_scan(
            &raw.depth,
            &camera.intrinsics(),
            &camera_pose,
            base,
            &body,
        );
        self.sense.keep_scan(raw.time, scan);
    }

    /// Feeds SLAM a frame taken with telemetry `tel` (the joints and odometry of its time);
    /// a tracked frame updates where the map lies in the odometry's frame.
    pub(crate) fn feed_frame(&mut self, tel: &ferrobot_protocol::Telemetry, raw: &RawFrame) {
        let Some(runner) = self.slam.as_mut() else {
            return;
        };
        let t = raw.time.as_secs_f64();
        let camera_pose = match runner
            .frames
            .transform_at(tel, &runner.optical, "base_link")
        {
            Ok(p) => p,
            Err(e) => {
                runner.error = Some(e.to_string());
                return;
            }
        };
        let odometry = odometry_at(tel, t);
        if self.sense.want_keyframe.take() {
            runner.slam.request_keyframe();
        }
        match runner.slam.track(&RgbdInput {
            time: t,
            rgb: &raw.rgb,
            depth: &raw.depth,
            camera: camera_pose,
            odometry: Some(odometry),
        }) {
            Ok(r) => {
                runner.last = Some(r);
                runner.error = None;
                if r.state != TrackState::Lost {
                    let map = Pose2::from(optimise::to_planar(&r.pose));
                    self.sense
                        .offer_correction(map.compose(&Pose2::from(odometry).inverse()));
                }
            }
            Err(e) => runner.error = Some(e.to_string()),
        }
    }
}

impl Robot {
    /// Starts SLAM beside the robot. The map's frame: `start` is the base's pose in it now
    /// (`[x, y, θ]`, m and rad; the odometry's frame has the base at its current odometry pose),
    /// or, with a saved `map` ([`Map::load`]), the saved map's frame, the base's place in it
    /// unknown until a frame matches. Errors: no camera or base, a camera that cannot be fed
    /// by time (not simulated), a start that is not finite.
    pub fn start_slam(&self, start: [f64; 3], map: Option<Map>) -> crate::Result<()> {
        crate::error::check_finite("SLAM start pose", &start)?;
        let cfg = self.config();
        let radius = cfg
            .base
            .as_ref()
            .ok_or_else(|| self.missing("base"))?
            .footprint_radius;
        let optical = cfg
            .camera
            .as_ref()
            .ok_or_else(|| self.missing("camera"))?
            .frame
            .clone();
        let frames = self.frames()?.clone();
        let settings = SlamSettings::ground_robot(radius.max(SELF_RADIUS));
        let mut io = self.lock_hub();
        let simulated = io.link.simulator().is_some();
        let now = io.link.now();
        let k = {
            let camera = io.camera.as_ref().ok_or_else(|| self.missing("camera"))?;
            // A device that knows when its next frame comes (a simulated one) says so with a
            // wait within one frame period.
            if camera.until_next(now) > Duration::from_secs_f64(1.0 / camera.rate()) || !simulated {
                return Err(crate::Error::Usage(
                    "SLAM beside the robot needs the simulated camera (a real one needs a capture thread, not yet built)".into(),
                ));
            }
            camera.intrinsics()
        };
        let slam = match map {
            Some(m) => Slam::with_map(settings, k, m)?,
            None => Slam::new(settings, k, optimise::planar(start))?,
        };
        io.sense.forget_slam();
        io.slam = Some(SlamRunner {
            slam,
            frames,
            optical,
            last: None,
            error: None,
            grid: OccupancyGrid::new(GridSettings::default())?,
        });
        Ok(())
    }

    /// Stops SLAM; its map is returned.
    pub fn stop_slam(&self) -> Option<Map> {
        let mut io = self.lock_hub();
        io.sense.forget_slam();
        io.slam.take().map(|r| r.slam.map().clone())
    }

    /// SLAM's latest report (the base's pose in the map and how it was found); `None` before
    /// the first frame. An error when SLAM is not running.
    pub fn slam_report(&self) -> crate::Result<Option<TrackReport>> {
        let io = self.lock_hub();
        let r = io.slam.as_ref().ok_or_else(not_running)?;
        if let Some(e) = &r.error {
            return Err(crate::Error::Link(format!(
                "SLAM could not take a frame: {e}"
            )));
        }
        Ok(r.last)
    }

    /// The dense coloured map so far: keyframes' depth averaged in voxels of `voxel` m, in the
    /// map's frame.
    pub fn slam_map_3d(&self, voxel: f64) -> crate::Result<PointCloud> {
        let io = self.lock_hub();
        let r = io.slam.as_ref().ok_or_else(not_running)?;
        Ok(r.slam.map().cloud(voxel)?)
    }

    /// The occupancy grid so far (PyRobot's 0.02 m cells, obstacles 0.1-0.8 m above the floor),
    /// in the map's frame; `None` before the first keyframe.
    pub fn slam_occupancy_map(&self) -> crate::Result<Option<MapImage>> {
        let mut io = self.lock_hub();
        let r = io.slam.as_mut().ok_or_else(not_running)?;
        // The grid the goals plan on, brought up to date (the same image as a fresh one).
        Ok(r.grid.update(r.slam.map())?)
    }

    /// How many frames in a row, up to the latest, SLAM has had no confirmed pose for (0 while
    /// it tracks).
    pub fn slam_lost_frames(&self) -> crate::Result<usize> {
        let io = self.lock_hub();
        let r = io.slam.as_ref().ok_or_else(not_running)?;
        let lost_now = r.last.is_some_and(|l| l.state == TrackState::Lost);
        Ok(if lost_now {
            r.slam.tracking_gaps().last().map_or(0, |g| g.2)
        } else {
            0
        })
    }

    /// The SLAM map so far (to save with [`Map::save`]).
    pub fn slam_map(&self) -> crate::Result<Map> {
        let io = self.lock_hub();
        let r = io.slam.as_ref().ok_or_else(not_running)?;
        Ok(r.slam.map().clone())
    }
}

impl crate::base::Base {
    /// The base's pose `[x, y, θ]` (m, rad) from `source`: the odometry's (as
    /// [`crate::Base::get_state`]) or SLAM's, in the map's frame. SLAM's is an error while it
    /// has no confirmed pose (before the first frame, or still localising in a saved map).
    pub fn get_state_from(&self, source: Source) -> crate::Result<[f64; 3]> {
        match source {
            Source::Odometry => self.get_state(),
            Source::Slam => {
                let r = self
                    .robot
                    .slam_report()?
                    .ok_or_else(|| crate::Error::Usage("SLAM has taken no frame yet".into()))?;
                if r.state == TrackState::Lost {
                    return Err(crate::Error::SlamLost {
                        frames: self.robot.slam_lost_frames()?,
                    });
                }
                Ok(optimise::to_planar(&r.pose))
            }
        }
    }
}

fn not_running() -> crate::Error {
    crate::Error::Usage("SLAM is not running: Robot::start_slam first".into())
}
