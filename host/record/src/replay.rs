//! Replay: a recording fed back as commands to a robot ([`replay_commands`]: the same commands
//! at the same instants of its time; on the simulator, with the same seed, the same states) or
//! as sensor input ([`SensorFrames`]: each camera frame with its intrinsics, the camera's pose
//! on the body and the odometry, as SLAM beside the robot was fed them).

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use ferrobot::perception::{DepthImage, Intrinsics, RgbImage};
use ferrobot::Robot;
use nalgebra::Isometry3;

use crate::decode::{self, DecodeError};
use crate::error::RecordError;
use crate::reader::{Message, Reading};
use crate::topics;

impl From<DecodeError> for RecordError {
    fn from(e: DecodeError) -> RecordError {
        RecordError::Decode(e.to_string())
    }
}

/// How a replay of commands went.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReplayStats {
    /// Commands sent.
    pub sent: u64,
    /// Commands the firmware refused (each is logged to standard error and skipped).
    pub refused: u64,
    /// Whether the recording was cut short.
    pub truncated: bool,
}

/// Sends the commands of the recording at `path` to `robot`, each at the instant of the
/// robot's time it was recorded at (the robot waits, as its program did, in between); a
/// command whose instant has passed is sent at once. The robot should start as the recorded
/// one did (the same robot, at rest, on the simulator with the same seed).
pub fn replay_commands(robot: &Robot, path: impl AsRef<Path>) -> Result<ReplayStats, RecordError> {
    let mut reading = Reading::open(path)?;
    let mut stats = ReplayStats::default();
    for m in reading.by_ref() {
        let m = m?;
        if &*m.topic != topics::COMMANDS.name {
            continue;
        }
        let msg = decode::command(&m.data)?;
        let at = m.time_ns as f64 * 1e-9;
        let now = robot.time();
        if at > now {
            robot.wait(at - now)?;
        }
        match robot.send_command(&msg) {
            Ok(()) => stats.sent += 1,
            Err(e) => {
                eprintln!("replay: {msg:?} at {at:.6} s refused: {e}");
                stats.refused += 1;
            }
        }
    }
    stats.truncated = reading.truncated;
    Ok(stats)
}

/// One camera frame of a recording, as SLAM beside the robot was fed it.
#[derive(Debug, Clone)]
pub struct SensorFrame {
    /// Capture time on the robot's clock.
    pub time: Duration,
    /// Colour.
    pub rgb: RgbImage,
    /// Depth aligned to colour, m (0 invalid).
    pub depth: DepthImage,
    /// The intrinsics.
    pub intrinsics: Intrinsics,
    /// The optical frame in `base_link`.
    pub camera_pose: Isometry3<f64>,
    /// The wheel odometry `[x, y, θ]` (m, rad) carried to the capture time.
    pub odometry: [f64; 3],
}

/// The parts of a frame met so far.
#[derive(Default)]
struct Parts {
    rgb: Option<RgbImage>,
    depth: Option<DepthImage>,
    intrinsics: Option<Intrinsics>,
    camera_pose: Option<Isometry3<f64>>,
    odometry: Option<[f64; 3]>,
}

impl Parts {
    fn take(&mut self, m: &Message) -> Result<(), RecordError> {
        let t = &*m.topic;
        if t == topics::COLOR.name {
            self.rgb = Some(decode::rgb(&m.data)?);
        } else if t == topics::DEPTH.name {
            self.depth = Some(decode::depth(&m.data)?);
        } else if t == topics::CAMERA_INFO.name {
            self.intrinsics = Some(decode::intrinsics(&m.data)?);
        } else if t == topics::CAMERA_POSE.name {
            self.camera_pose = Some(decode::pose_stamped(&m.data)?.2);
        } else if t == topics::CAMERA_ODOM.name {
            let p = decode::pose_stamped(&m.data)?.2;
            let yaw = p.rotation.euler_angles().2;
            self.odometry = Some([p.translation.x, p.translation.y, yaw]);
        }
        Ok(())
    }

    fn whole(&mut self, time: Duration) -> Option<SensorFrame> {
        let all = self.rgb.is_some()
            && self.depth.is_some()
            && self.intrinsics.is_some()
            && self.camera_pose.is_some()
            && self.odometry.is_some();
        if !all {
            return None;
        }
        Some(SensorFrame {
            time,
            rgb: self.rgb.take()?,
            depth: self.depth.take()?,
            intrinsics: self.intrinsics.take()?,
            camera_pose: self.camera_pose.take()?,
            odometry: self.odometry.take()?,
        })
    }
}

/// The camera frames of a recording, in time order ([`SensorFrames::open`]).
pub struct SensorFrames {
    reading: Reading,
    parts: BTreeMap<u64, Parts>,
}

impl SensorFrames {
    /// The frames of the recording at `path`.
    pub fn open(path: impl AsRef<Path>) -> Result<SensorFrames, RecordError> {
        Ok(SensorFrames {
            reading: Reading::open(path)?,
            parts: BTreeMap::new(),
        })
    }

    /// Whether the recording was cut short (known once the frames are read).
    pub fn truncated(&self) -> bool {
        self.reading.truncated
    }
}

impl Iterator for SensorFrames {
    type Item = Result<SensorFrame, RecordError>;

    fn next(&mut self) -> Option<Self::Item> {
        for m in self.reading.by_ref() {
            let m = match m {
                Ok(m) => m,
                Err(e) => return Some(Err(e)),
            };
            let parts = self.parts.entry(m.time_ns).or_default();
            if let Err(e) = parts.take(&m) {
                return Some(Err(e));
            }
            if let Some(f) = parts.whole(Duration::from_nanos(m.time_ns)) {
                // Parts of older frames that never completed are dropped with it.
                self.parts = self.parts.split_off(&(m.time_ns + 1));
                return Some(Ok(f));
            }
        }
        None
    }
}
