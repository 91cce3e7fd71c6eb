//! One RGB-D frame as the API gives it: colour, depth, intrinsics, its capture time on the
//! robot's clock and the optical frame's pose in `base_link` at that time.

use std::time::Duration;

use ferrobot_perception::{
    backproject, pixels_to_points, DepthImage, DepthRange, Intrinsics, PixelPoints, PointCloud,
    RgbImage,
};
use ferrobot_protocol::Telemetry;
use nalgebra::Isometry3;

use crate::backend::device::RawFrame;
use crate::error::Result;
use crate::frames::Frames;

/// One RGB-D frame with its time and the camera's pose.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Colour, H x W x 3.
    pub rgb: RgbImage,
    /// Depth aligned to colour, m (0 = invalid).
    pub depth: DepthImage,
    /// The intrinsics.
    pub intrinsics: Intrinsics,
    /// Capture time on the robot's clock (since the firmware started).
    pub time: Duration,
    /// Pose of the optical frame (x right, y down, z forward) in `base_link` at capture, from
    /// the measured joints.
    pub camera_pose: Isometry3<f64>,
    /// The base's wheel-odometry pose `[x, y, θ]` (m, rad, the odometry's frame) carried to the
    /// capture time ([`crate::slam::odometry_at`]): what SLAM beside the robot is fed with it.
    pub odometry: [f64; 3],
}

impl Frame {
    /// The frame of `raw`, taken with telemetry `tel` (whose joints place the optical frame
    /// `optical` in `base_link` through `frames`), seen through `intrinsics`.
    pub(crate) fn placed(
        raw: RawFrame,
        intrinsics: Intrinsics,
        frames: &Frames,
        optical: &str,
        tel: &Telemetry,
    ) -> Result<Frame> {
        let camera_pose = frames.transform_at(tel, optical, "base_link")?;
        Ok(Frame {
            rgb: raw.rgb,
            depth: raw.depth,
            intrinsics,
            odometry: crate::slam_runner::odometry_at(tel, raw.time.as_secs_f64()),
            time: raw.time,
            camera_pose,
        })
    }

    /// The cloud of the pixels whose depth `range` keeps, with colours: in the optical frame
    /// (`in_cam`) or in `base_link`.
    pub fn cloud(&self, range: DepthRange, in_cam: bool) -> Result<PointCloud> {
        let c = backproject(&self.intrinsics, &self.depth, Some(&self.rgb), range)?;
        Ok(if in_cam {
            c
        } else {
            c.transformed(&self.camera_pose)
        })
    }

    /// The points seen at pixels (`rows[i]`, `cols[i]`), in the optical frame (`in_cam`) or in
    /// `base_link`; `None` where the depth is invalid.
    pub fn pixels(&self, rows: &[i64], cols: &[i64], in_cam: bool) -> Result<PixelPoints> {
        let p = pixels_to_points(&self.intrinsics, &self.depth, Some(&self.rgb), rows, cols)?;
        Ok(if in_cam {
            p
        } else {
            p.transformed(&self.camera_pose)
        })
    }
}
