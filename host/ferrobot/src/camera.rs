//! The RGB-D camera: PyRobot's camera API (`get_rgb`, `get_depth`, `get_rgb_depth`,
//! `get_intrinsics`, `get_current_pcd`, `pix_to_3dpt`, `get_link_transform`) on a host-side
//! [`CameraDevice`].
//!
//! A camera is a host device (a RealSense is USB on the host computer, not behind the
//! microcontroller), so it sits beside the firmware's link, not behind it. Every [`Frame`]
//! carries its capture time on the robot's clock and the optical frame's pose in `base_link`
//! at that time, from the joint telemetry taken with it: clouds in `base_link` use the head's
//! pose when the picture was taken, not when the call returns.
//!
//! Unlike PyRobot on main (which divides depth by 1000 twice and returns empty clouds, its
//! issues #139 and #153), depth is in metres throughout; rows and columns are named as such.

use std::sync::Arc;

use ferrobot_perception::{DepthImage, DepthRange, Intrinsics, PixelPoints, PointCloud, RgbImage};
use ferrobot_protocol::Telemetry;
use nalgebra::Isometry3;

pub use crate::backend::device::{CameraDevice, DeviceTime, RawFrame, TimeDomain};
use crate::error::{Error, Result};
pub use crate::frame::Frame;
use crate::head::Head;
use crate::robot::Robot;
use crate::subscription::Subscription;

/// The RGB-D camera of a [`Robot`]: a handle (a clone of the robot's).
#[derive(Clone, Debug)]
pub struct Camera {
    robot: Robot,
}

impl Camera {
    pub(crate) fn new(robot: Robot) -> Self {
        Camera { robot }
    }

    /// The next frame with its time and the camera's pose at that time. The time until the
    /// frame passes as any wait does: the motions under way go on meanwhile.
    pub fn get_frame(&self) -> Result<Frame> {
        Ok(self.frame_with_telemetry()?.0)
    }

    /// [`Camera::get_frame`] and the telemetry whose joints placed the camera.
    pub fn frame_with_telemetry(&self) -> Result<(Frame, Telemetry)> {
        let frame = self.robot.optical_frame()?;
        let until = {
            let io = self.robot.lock_hub();
            let device = io
                .camera
                .as_ref()
                .ok_or_else(|| self.robot.missing("camera"))?;
            device.until_next(io.link.now())
        };
        if !until.is_zero() {
            self.robot.wait_for(until);
        }
        let (intrinsics, tel, raw) = {
            let mut guard = self.robot.lock_hub();
            let io = &mut *guard;
            let device = io
                .camera
                .as_mut()
                .ok_or_else(|| self.robot.missing("camera"))?;
            // The joints as the newest report has them, then the next picture (at most one
            // frame period later).
            let tel = io.link.telemetry()?;
            let raw = device.capture(&mut *io.link)?;
            let k = device.intrinsics();
            // SLAM beside the robot and the frame subscriptions see this frame too.
            io.feed_frame(&tel, &raw);
            io.publish_frame(&tel, &raw);
            (k, tel, raw)
        };
        let frame = Frame::placed(raw, intrinsics, self.robot.frames()?, &frame, &tel)?;
        Ok((frame, tel))
    }

    /// Subscribes to every frame the camera takes from now on, placed as
    /// [`Camera::get_frame`]'s are, in a queue of `queue` frames (in
    /// `[1, subscription::MAX_QUEUE]`; a full queue drops its oldest). While a subscription
    /// lives, the camera takes a picture for each of its frame instants, when the robot's time
    /// next passes it (waits step 10 ms), and every [`Camera::get_frame`] is delivered too, so SLAM, recorders and viewers see the
    /// same frames. Needs a camera that tells its frame instants (the simulated one): a device
    /// that only knows by capturing would make every wait wait for a picture.
    ///
    /// [`subscription::MAX_QUEUE`]: crate::subscription::MAX_QUEUE
    pub fn subscribe(&self, queue: usize) -> Result<Subscription<Arc<Frame>>> {
        let mut io = self.robot.lock_hub();
        let device = io
            .camera
            .as_ref()
            .ok_or_else(|| self.robot.missing("camera"))?;
        if !device.knows_frame_instants() {
            return Err(Error::Usage(
                "frame subscriptions need a camera that tells its frame instants (the simulated \
                 one); a real one needs a capture thread, not yet built"
                    .into(),
            ));
        }
        if io.streams.placing.is_none() {
            let placing = (self.robot.frames()?.clone(), self.robot.optical_frame()?);
            io.streams.placing = Some(placing);
        }
        io.streams.frames.subscribe("camera frame", queue)
    }

    /// The next colour image (H x W x 3, 8-bit RGB).
    pub fn get_rgb(&self) -> Result<RgbImage> {
        Ok(self.get_frame()?.rgb)
    }

    /// The next depth image (f32 metres, 0 = invalid), aligned to colour.
    pub fn get_depth(&self) -> Result<DepthImage> {
        Ok(self.get_frame()?.depth)
    }

    /// The next colour and depth images, from one capture.
    pub fn get_rgb_depth(&self) -> Result<(RgbImage, DepthImage)> {
        let f = self.get_frame()?;
        Ok((f.rgb, f.depth))
    }

    /// The camera's intrinsics.
    pub fn intrinsics(&self) -> Result<Intrinsics> {
        let io = self.robot.lock_hub();
        let device = io
            .camera
            .as_ref()
            .ok_or_else(|| self.robot.missing("camera"))?;
        Ok(device.intrinsics())
    }

    /// The 3x3 camera matrix K, rows `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`, px.
    pub fn get_intrinsics(&self) -> Result<[[f64; 3]; 3]> {
        Ok(self.intrinsics()?.rows())
    }

    /// The depth range clouds keep by default: the description's `camera.depth_min` and
    /// `camera.depth_max` (PyRobot's (0.2, 1.5) m for the LoCoBot; override with
    /// `RobotBuilder::set`).
    pub fn depth_range(&self) -> Result<DepthRange> {
        let c = self
            .robot
            .config()
            .camera
            .as_ref()
            .ok_or_else(|| self.robot.missing("camera"))?;
        Ok(DepthRange::new(c.depth_min, c.depth_max)?)
    }

    /// The cloud of the next frame (points in m with colours), depths filtered by
    /// [`Camera::depth_range`]: in the optical frame (`in_cam`) or in `base_link`.
    pub fn get_current_pcd(&self, in_cam: bool) -> Result<PointCloud> {
        self.get_current_pcd_in(self.depth_range()?, in_cam)
    }

    /// [`Camera::get_current_pcd`] with an explicit depth range.
    pub fn get_current_pcd_in(&self, range: DepthRange, in_cam: bool) -> Result<PointCloud> {
        self.get_frame()?.cloud(range, in_cam)
    }

    /// The points seen now at pixels (`rows[i]`, `cols[i]`) (row 0 at the top), in the optical
    /// frame (`in_cam`) or in `base_link`, with their colours; `None` where the depth is
    /// invalid. Pixels outside the image are an error naming the first.
    pub fn pix_to_3dpt(&self, rows: &[i64], cols: &[i64], in_cam: bool) -> Result<PixelPoints> {
        self.get_frame()?.pixels(rows, cols, in_cam)
    }

    /// Pose of URDF frame `src` in frame `dst` now (maps points of `src` into `dst`), from the
    /// measured joints.
    pub fn get_link_transform(&self, src: &str, dst: &str) -> Result<Isometry3<f64>> {
        self.robot.link_transform(src, dst)
    }

    /// The pan-tilt head that carries the camera.
    pub fn head(&self) -> Result<Head> {
        self.robot.head()
    }
}

/// The camera's errors from perception's.
impl From<ferrobot_perception::PerceptionError> for Error {
    fn from(e: ferrobot_perception::PerceptionError) -> Self {
        Error::Perception(e)
    }
}
