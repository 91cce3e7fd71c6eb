//! The messages replay reads back, decoded from CDR into the robot's types.

use std::time::Duration;

use ferrobot::events::HostMsg;
use ferrobot::perception::{DepthImage, Intrinsics, RgbImage};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use crate::cdr::{CdrError, CdrReader};

/// Why a message could not be decoded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DecodeError {
    /// Malformed CDR.
    #[error(transparent)]
    Cdr(#[from] CdrError),
    /// A command whose wire bytes do not decode.
    #[error("a recorded command does not decode: {0}")]
    Command(#[from] postcard::Error),
    /// A value the robot's type refuses (an image whose size and data disagree, intrinsics
    /// out of range).
    #[error("{0}")]
    Invalid(String),
}

/// A `builtin_interfaces/Time`.
fn time(r: &mut CdrReader<'_>) -> Result<Duration, CdrError> {
    let sec = r.i32()?;
    let nanosec = r.u32()?;
    Ok(Duration::new(sec.max(0) as u64, nanosec.min(999_999_999)))
}

/// A `std_msgs/Header`: its stamp and frame.
fn header(r: &mut CdrReader<'_>) -> Result<(Duration, String), CdrError> {
    Ok((time(r)?, r.string()?))
}

/// The stamp of a message that starts with a `std_msgs/Header` (images, camera info, joint
/// states, odometry, poses).
pub fn stamp(data: &[u8]) -> Result<Duration, DecodeError> {
    let mut r = CdrReader::new(data)?;
    Ok(time(&mut r)?)
}

/// A `ferrobot_msgs/Command`'s message.
pub fn command(data: &[u8]) -> Result<HostMsg, DecodeError> {
    let mut r = CdrReader::new(data)?;
    let _kind = r.string()?;
    Ok(postcard::from_bytes(r.bytes()?)?)
}

/// A `geometry_msgs/Pose`: position, then orientation `[x, y, z, w]`.
fn pose(r: &mut CdrReader<'_>) -> Result<Isometry3<f64>, CdrError> {
    let v = r.f64_array(7)?;
    let q = UnitQuaternion::from_quaternion(Quaternion::new(v[6], v[3], v[4], v[5]));
    Ok(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        q,
    ))
}

/// A `geometry_msgs/PoseStamped`: stamp, frame and pose.
pub fn pose_stamped(data: &[u8]) -> Result<(Duration, String, Isometry3<f64>), DecodeError> {
    let mut r = CdrReader::new(data)?;
    let (t, frame) = header(&mut r)?;
    Ok((t, frame, pose(&mut r)?))
}

/// A `sensor_msgs/Image` up to its pixels: stamp, size (width, height, px) and encoding.
fn image_head(r: &mut CdrReader<'_>) -> Result<(Duration, u32, u32, String), CdrError> {
    let (t, _) = header(r)?;
    let height = r.u32()?;
    let width = r.u32()?;
    Ok((t, width, height, r.string()?))
}

/// A `sensor_msgs/Image`: stamp, size (width, height), encoding and bytes.
fn image(data: &[u8]) -> Result<(Duration, u32, u32, String, Vec<u8>), DecodeError> {
    let mut r = CdrReader::new(data)?;
    let (t, width, height, encoding) = image_head(&mut r)?;
    let _big_endian = r.u8()?;
    let _step = r.u32()?;
    Ok((t, width, height, encoding, r.bytes()?.to_vec()))
}

/// A `sensor_msgs/Image`'s size (width, height, px) and encoding, without its pixels.
pub fn image_size(data: &[u8]) -> Result<(u32, u32, String), DecodeError> {
    let (_, width, height, encoding) = image_head(&mut CdrReader::new(data)?)?;
    Ok((width, height, encoding))
}

/// A `nav_msgs/Odometry`'s planar pose: x, y (m) and yaw (rad) in its frame.
pub fn odometry_pose(data: &[u8]) -> Result<[f64; 3], DecodeError> {
    let mut r = CdrReader::new(data)?;
    let _ = header(&mut r)?;
    let _child = r.string()?;
    let p = pose(&mut r)?;
    Ok([
        p.translation.x,
        p.translation.y,
        p.rotation.euler_angles().2,
    ])
}

/// A `geometry_msgs/Twist`'s planar part: forward speed (m/s) and yaw rate (rad/s).
pub fn twist(data: &[u8]) -> Result<[f64; 2], DecodeError> {
    let mut r = CdrReader::new(data)?;
    let v = r.f64_array(6)?;
    Ok([v[0], v[5]])
}

/// An `rgb8` image.
pub fn rgb(data: &[u8]) -> Result<RgbImage, DecodeError> {
    let (_, w, h, enc, bytes) = image(data)?;
    if enc != "rgb8" {
        return Err(DecodeError::Invalid(format!(
            "a colour image in {enc}, not rgb8"
        )));
    }
    RgbImage::new(w, h, bytes).map_err(|e| DecodeError::Invalid(e.to_string()))
}

/// A `32FC1` depth image, m.
pub fn depth(data: &[u8]) -> Result<DepthImage, DecodeError> {
    let (_, w, h, enc, bytes) = image(data)?;
    if enc != "32FC1" {
        return Err(DecodeError::Invalid(format!(
            "a depth image in {enc}, not 32FC1"
        )));
    }
    let d = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    DepthImage::new(w, h, d).map_err(|e| DecodeError::Invalid(e.to_string()))
}

/// A `sensor_msgs/CameraInfo`'s pinhole intrinsics.
pub fn intrinsics(data: &[u8]) -> Result<Intrinsics, DecodeError> {
    let mut r = CdrReader::new(data)?;
    let _ = header(&mut r)?;
    let height = r.u32()?;
    let width = r.u32()?;
    let _model = r.string()?;
    let _d = r.f64_seq()?;
    let k = r.f64_array(9)?;
    Intrinsics::new(width, height, k[0], k[4], k[2], k[5])
        .map_err(|e| DecodeError::Invalid(e.to_string()))
}

/// A `sensor_msgs/JointState`: stamp, names, positions, velocities, efforts.
pub type JointStates = (Duration, Vec<String>, Vec<f64>, Vec<f64>, Vec<f64>);

/// A `sensor_msgs/JointState`.
pub fn joint_state(data: &[u8]) -> Result<JointStates, DecodeError> {
    let mut r = CdrReader::new(data)?;
    let (t, _) = header(&mut r)?;
    Ok((t, r.string_seq()?, r.f64_seq()?, r.f64_seq()?, r.f64_seq()?))
}

/// A `trajectory_msgs/JointTrajectory`: its joint names, and each point's positions with its
/// time from the trajectory's start.
pub type JointTrajectoryGoal = (Vec<String>, Vec<(Vec<f64>, Duration)>);

/// A `trajectory_msgs/JointTrajectory`'s names and points (positions and times; the
/// velocities, accelerations and efforts are read past).
pub fn joint_trajectory(data: &[u8]) -> Result<JointTrajectoryGoal, DecodeError> {
    let mut r = CdrReader::new(data)?;
    let _ = header(&mut r)?;
    let names = r.string_seq()?;
    let n = r.u32()? as usize;
    let mut points = Vec::with_capacity(n.min(1024));
    for _ in 0..n {
        let positions = r.f64_seq()?;
        let _velocities = r.f64_seq()?;
        let _accelerations = r.f64_seq()?;
        let _effort = r.f64_seq()?;
        points.push((positions, time(&mut r)?));
    }
    Ok((names, points))
}
