//! ROS 2 messages written as CDR from the robot's values (SI units; quaternions `[x, y, z,
//! w]`; times on the robot's clock, as `builtin_interfaces/Time` since its zero).

use std::time::Duration;

use ferrobot_perception::{DepthImage, Intrinsics, RgbImage};
use nalgebra::Isometry3;

use crate::cdr::CdrWriter;

/// `sensor_msgs/PointCloud2` of an RGB-D frame, in the camera's optical frame `frame` (x
/// right, y down, z forward, m): every `stride`-th pixel of every `stride`-th row with a valid
/// depth (> 0), unordered (height 1) and dense. Fields `x`, `y`, `z` (float32) and `rgb` (a
/// float32 holding `0x00RRGGBB`, as PCL and rviz pack it); 16 bytes a point.
pub fn point_cloud(
    t: Duration,
    frame: &str,
    depth: &DepthImage,
    rgb: &RgbImage,
    c: &Intrinsics,
    stride: u32,
) -> Vec<u8> {
    let stride = stride.max(1) as usize;
    let (w, h) = (depth.width as usize, depth.height as usize);
    let mut data = Vec::with_capacity(w * h / (stride * stride) * 16);
    let mut n = 0u32;
    for v in (0..h).step_by(stride) {
        for u in (0..w).step_by(stride) {
            let i = v * w + u;
            let z = depth.data.get(i).copied().unwrap_or(0.0);
            if !(z > 0.0 && z.is_finite()) {
                continue;
            }
            let x = ((u as f64 - c.cx) / c.fx * f64::from(z)) as f32;
            let y = ((v as f64 - c.cy) / c.fy * f64::from(z)) as f32;
            let px = rgb.data.get(3 * i..3 * i + 3).unwrap_or(&[0, 0, 0]);
            let packed = u32::from(px[0]) << 16 | u32::from(px[1]) << 8 | u32::from(px[2]);
            for f in [x, y, z] {
                data.extend_from_slice(&f.to_le_bytes());
            }
            data.extend_from_slice(&packed.to_le_bytes());
            n += 1;
        }
    }
    let mut w = CdrWriter::with_capacity(data.len() + 200);
    header(&mut w, t, frame);
    w.u32(1);
    w.u32(n);
    w.seq_len(4);
    for (k, name) in ["x", "y", "z", "rgb"].iter().enumerate() {
        w.string(name);
        w.u32(4 * k as u32);
        w.u8(7); // FLOAT32
        w.u32(1);
    }
    w.u8(0);
    w.u32(16);
    w.u32(16 * n);
    w.bytes(&data);
    w.u8(1);
    w.into_bytes()
}

/// A `rosgraph_msgs/Clock` at `t`.
pub fn clock(t: Duration) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(16);
    time(&mut w, t);
    w.into_bytes()
}

/// A `builtin_interfaces/Time` (or `Duration`) of `t`.
pub fn time(w: &mut CdrWriter, t: Duration) {
    w.i32(t.as_secs().min(i32::MAX as u64) as i32);
    w.u32(t.subsec_nanos());
}

/// A `std_msgs/Header` stamped `t` in frame `frame`.
pub fn header(w: &mut CdrWriter, t: Duration, frame: &str) {
    time(w, t);
    w.string(frame);
}

/// A pose as `geometry_msgs/Point` (or `Vector3`) and `Quaternion`.
pub(crate) fn pose(w: &mut CdrWriter, p: &Isometry3<f64>) {
    let t = p.translation.vector;
    let q = p.rotation.coords; // [x, y, z, w]
    w.f64_array(&[t.x, t.y, t.z, q.x, q.y, q.z, q.w]);
}

/// `std_msgs/String`.
pub fn string(s: &str) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(s.len() + 16);
    w.string(s);
    w.into_bytes()
}

/// `ferrobot_msgs/Command`: the kind and the postcard bytes of a command.
pub fn command(kind: &str, postcard: &[u8]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(32 + kind.len() + postcard.len());
    w.string(kind);
    w.bytes(postcard);
    w.into_bytes()
}

/// `std_msgs/Int8`.
pub fn int8(v: i8) -> Vec<u8> {
    let mut w = CdrWriter::default();
    w.i8(v);
    w.into_bytes()
}

/// `sensor_msgs/JointState`: positions (rad or m), velocities (rad/s or m/s), efforts (N·m or
/// N), one per name.
pub fn joint_state(
    t: Duration,
    names: &[String],
    position: &[f64],
    velocity: &[f64],
    effort: &[f64],
) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(64 + names.len() * 48);
    header(&mut w, t, "");
    w.string_seq(names);
    w.f64_seq(position);
    w.f64_seq(velocity);
    w.f64_seq(effort);
    w.into_bytes()
}

/// An image's layout: `sensor_msgs/Image`'s fields but its data.
#[derive(Debug, Clone, Copy)]
pub struct ImageLayout<'a> {
    /// Rows, px.
    pub height: u32,
    /// Columns, px.
    pub width: u32,
    /// `rgb8`, `32FC1`, … (ROS's `sensor_msgs/image_encodings`).
    pub encoding: &'a str,
    /// Bytes per row.
    pub step: u32,
}

impl<'a> ImageLayout<'a> {
    /// Rows without padding: `width` pixels of `bytes_per_pixel` bytes each.
    pub fn packed(width: u32, height: u32, encoding: &'a str, bytes_per_pixel: u32) -> Self {
        ImageLayout {
            height,
            width,
            encoding,
            step: width * bytes_per_pixel,
        }
    }
}

/// `sensor_msgs/Image` (little-endian data).
pub fn image(t: Duration, frame: &str, layout: ImageLayout<'_>, data: &[u8]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(data.len() + 96);
    header(&mut w, t, frame);
    w.u32(layout.height);
    w.u32(layout.width);
    w.string(layout.encoding);
    w.u8(0);
    w.u32(layout.step);
    w.bytes(data);
    w.into_bytes()
}

/// `sensor_msgs/CameraInfo` of an undistorted pinhole (`plumb_bob` with zero coefficients;
/// `k` and `p` from the intrinsics, `r` the identity).
pub fn camera_info(t: Duration, frame: &str, c: &Intrinsics) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(400);
    header(&mut w, t, frame);
    w.u32(c.height);
    w.u32(c.width);
    w.string("plumb_bob");
    w.f64_seq(&[0.0; 5]);
    w.f64_array(&[c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0]);
    w.f64_array(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    w.f64_array(&[
        c.fx, 0.0, c.cx, 0.0, 0.0, c.fy, c.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
    ]);
    w.u32(0);
    w.u32(0);
    // roi: offsets, size, do_rectify.
    for _ in 0..4 {
        w.u32(0);
    }
    w.u8(0);
    w.into_bytes()
}

/// A planar base's state: pose `[x, y, θ]` (m, rad) in the odometry's frame, forward speed
/// (m/s) and yaw rate (rad/s).
#[derive(Debug, Clone, Copy)]
pub struct Planar {
    /// Pose `[x, y, θ]`, m and rad.
    pub pose: [f64; 3],
    /// Forward speed, m/s.
    pub v: f64,
    /// Yaw rate, rad/s.
    pub w: f64,
}

/// The pose of a planar `[x, y, θ]` in 3D.
pub fn planar_pose(p: [f64; 3]) -> Isometry3<f64> {
    Isometry3::new(
        nalgebra::Vector3::new(p[0], p[1], 0.0),
        nalgebra::Vector3::new(0.0, 0.0, p[2]),
    )
}

/// `nav_msgs/Odometry` of `base` in `frame`, the body `child` (covariances zero: unknown).
pub fn odometry(t: Duration, frame: &str, child: &str, base: &Planar) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(720);
    header(&mut w, t, frame);
    w.string(child);
    pose(&mut w, &planar_pose(base.pose));
    w.f64_array(&[0.0; 36]);
    w.f64_array(&[base.v, 0.0, 0.0, 0.0, 0.0, base.w]);
    w.f64_array(&[0.0; 36]);
    w.into_bytes()
}

/// `geometry_msgs/Twist` of a planar base's command: forward speed (m/s), yaw rate (rad/s).
pub fn twist(v: f64, yaw_rate: f64) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(56);
    w.f64_array(&[v, 0.0, 0.0, 0.0, 0.0, yaw_rate]);
    w.into_bytes()
}

/// One transform: `child`'s pose in `parent` at `t`.
#[derive(Debug, Clone)]
pub struct Transform<'a> {
    /// Stamp.
    pub time: Duration,
    /// The parent frame.
    pub parent: &'a str,
    /// The child frame.
    pub child: &'a str,
    /// The child's pose in the parent (maps child points into the parent).
    pub pose: Isometry3<f64>,
}

/// `tf2_msgs/TFMessage`.
pub fn tf_message(transforms: &[Transform<'_>]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(16 + transforms.len() * 120);
    w.seq_len(transforms.len());
    for tr in transforms {
        header(&mut w, tr.time, tr.parent);
        w.string(tr.child);
        pose(&mut w, &tr.pose);
    }
    w.into_bytes()
}

/// `geometry_msgs/PoseStamped`.
pub fn pose_stamped(t: Duration, frame: &str, p: &Isometry3<f64>) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(120);
    header(&mut w, t, frame);
    pose(&mut w, p);
    w.into_bytes()
}

/// One knot of a joint trajectory: positions (rad or m), velocities, efforts, and its time
/// after the trajectory's start.
#[derive(Debug, Clone, Default)]
pub struct Knot {
    /// Positions.
    pub positions: Vec<f64>,
    /// Velocities (empty: not given).
    pub velocities: Vec<f64>,
    /// Efforts (empty: not given).
    pub effort: Vec<f64>,
    /// When, after the trajectory's start.
    pub time_from_start: Duration,
}

/// `trajectory_msgs/JointTrajectory` for the joints `names`.
pub fn joint_trajectory(t: Duration, names: &[String], knots: &[Knot]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(128 + names.len() * 40 * (1 + knots.len()));
    header(&mut w, t, "");
    w.string_seq(names);
    w.seq_len(knots.len());
    for k in knots {
        w.f64_seq(&k.positions);
        w.f64_seq(&k.velocities);
        w.f64_seq(&[]);
        w.f64_seq(&k.effort);
        time(&mut w, k.time_from_start);
    }
    w.into_bytes()
}

/// `rcl_interfaces/Log`'s levels.
pub mod level {
    /// Information.
    pub const INFO: u8 = 20;
    /// A warning.
    pub const WARN: u8 = 30;
    /// An error.
    pub const ERROR: u8 = 40;
}

/// `rcl_interfaces/Log` from the logger `name` at `level`.
pub fn log(t: Duration, level: u8, name: &str, msg: &str) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(64 + name.len() + msg.len());
    time(&mut w, t);
    w.u8(level);
    w.string(name);
    w.string(msg);
    w.string("");
    w.string("");
    w.u32(0);
    w.into_bytes()
}
