//! SLAM beside the robot: once started ([`Robot::start_slam`]), every camera frame that time
//! passes over is fed to [`ferrobot_slam::Slam`] with the wheel odometry at its instant and the
//! camera's pose on the body from the measured head joints, whoever lets the time pass (a
//! motion's wait, [`Robot::wait`], [`crate::Camera::get_frame`]). The base's pose in the map is
//! then [`crate::base::Base::get_state_from`]`(Source::Slam)`; the maps are [`Robot::slam_map_3d`]
//! and [`Robot::slam_occupancy_map`].
//!
//! Frames are fed as the pump passes their instants, which a camera that knows its frame times
//! supports (the simulated one); a real driver would need its own capture thread, which does
//! not exist yet: starting SLAM on such a robot is refused.

use std::time::Duration;

/// The SLAM crate: tracking, keyframes, loop closure, the maps, trajectories and their error.
pub use ferrobot_slam::*;

use ferrobot_nav::MapImage;
use ferrobot_perception::PointCloud;

use crate::robot::Robot;
use crate::slam_runner::SlamRunner;
pub use crate::slam_runner::{odometry_at, Source, SELF_RADIUS};

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
        #[cfg(feature = "sim")]
        let simulated = crate::backend::world::simulator_of(io.link.as_mut()).is_some();
        #[cfg(not(feature = "sim"))]
        let simulated = false;
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
    /// [`crate::base::Base::get_state`]) or SLAM's, in the map's frame. SLAM's is an error while it
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
