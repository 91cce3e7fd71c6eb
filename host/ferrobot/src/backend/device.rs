//! Camera devices: a host-side source of colour and depth frames ([`CameraDevice`]) and the
//! frames it gives ([`RawFrame`]), stamped with the robot's clock. A device is built with the
//! world it looks at (the simulator's, a socket, a driver).

use std::time::Duration;

use ferrobot_perception::{DepthImage, Intrinsics, RgbImage};

use super::Link;
use crate::error::Result;

/// One picture from a [`CameraDevice`], before the API adds the camera's pose.
#[derive(Debug, Clone, PartialEq)]
pub struct RawFrame {
    /// Colour, H x W x 3.
    pub rgb: RgbImage,
    /// Depth aligned to colour, m (0 = invalid).
    pub depth: DepthImage,
    /// Capture time on the robot's clock (the link's [`Link::now`]).
    pub time: Duration,
    /// The camera's own stamp of the frame, when it has one (a RealSense); `None` for the
    /// simulated camera, whose frames are stamped on the robot's clock itself.
    pub device_time: Option<DeviceTime>,
}

/// A frame's stamp by the camera's own clock and counter, as librealsense reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceTime {
    /// The device's frame counter.
    pub frame_number: u64,
    /// The frame's timestamp, ms, on the clock `domain` names.
    pub time_ms: f64,
    /// The clock `time_ms` is on.
    pub domain: TimeDomain,
}

/// The clock of a [`DeviceTime`] (librealsense's `rs2_timestamp_domain`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum TimeDomain {
    /// The camera's own clock (its firmware's), started at an arbitrary instant.
    HardwareClock,
    /// The host's system clock (ms since the Unix epoch) when the frame reached the host.
    SystemTime,
    /// The camera's clock mapped by librealsense onto the host's system clock (ms since the
    /// Unix epoch): the D400s' default.
    GlobalTime,
    /// A clock this version does not know.
    #[serde(other)]
    Other,
}

/// A source of colour and depth frames on the host: the simulated world's renderer, or (later)
/// a RealSense or UVC driver. `capture` gets the robot's link so that a simulated camera can
/// let simulated time reach its next frame and look at the world; a real driver ignores it
/// and stamps frames with the link's clock.
pub trait CameraDevice: Send {
    /// The camera's intrinsics (depth is aligned to colour, so one set).
    fn intrinsics(&self) -> Intrinsics;
    /// Frames per second.
    fn rate(&self) -> f64;
    /// How long after `now` (the link's clock) the next frame is taken, when the device can
    /// tell (a simulated camera); zero for a device that only knows by capturing.
    fn until_next(&self, _now: Duration) -> Duration {
        Duration::ZERO
    }
    /// Whether [`CameraDevice::until_next`] tells the frame instants (a simulated camera), so
    /// that frames can be taken as time passes without waiting for them; false for a device
    /// that only knows by capturing.
    fn knows_frame_instants(&self) -> bool {
        false
    }
    /// The next frame: waits for it (at most one frame period).
    fn capture(&mut self, link: &mut dyn Link) -> Result<RawFrame>;
}
