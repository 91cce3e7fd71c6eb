//! The recording's writer, sans thread: the robot's telemetry, frames and events in, MCAP
//! records out through any `Write + Seek` (a file, or a test's sink that fails). The chunks are
//! compressed with lz4, and one is closed at least every [`Bag::flush_every`] of the robot's
//! time, so that a recording cut short (a crash, `kill -9`, a full disk) reads back to within
//! that of its end.

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::sync::Arc;
use std::time::Duration;

use ferrobot::events::Event;
use ferrobot::frames::Frames;
use ferrobot::{Frame, GripperState, Telemetry};

use crate::error::RecordError;
use crate::ros2::encode::{self, Planar, Transform};
use crate::topics::{self, Topic};

/// What a recording's channels need to know of the robot.
#[derive(Debug, Clone)]
pub struct RobotInfo {
    /// The joint table's names, in its order.
    pub joints: Vec<String>,
    /// The URDF's frames.
    pub frames: Frames,
    /// The URDF, as text.
    pub urdf: String,
    /// Whether it has a mobile base (`/odom`, and `odom` to the root in `/tf`).
    pub base: bool,
    /// Whether it has a gripper (`/gripper/state`).
    pub gripper: bool,
    /// The camera's optical frame, when it has a camera.
    pub optical: Option<String>,
}

/// One item the robot delivered.
#[derive(Debug, Clone)]
pub enum Item {
    /// A telemetry report.
    Telemetry(Telemetry),
    /// A camera frame.
    Frame(Arc<Frame>),
    /// An event: a command, a fault, a link event, a SLAM pose.
    Event(Event),
}

impl Item {
    /// Its time on the robot's clock.
    pub fn time(&self) -> Duration {
        match self {
            Item::Telemetry(t) => Duration::from_micros(t.time_us),
            Item::Frame(f) => f.time,
            Item::Event(e) => e.time(),
        }
    }
}

/// How much a recording holds so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BagStats {
    /// Messages written.
    pub messages: u64,
    /// Camera frames written.
    pub frames: u64,
    /// Telemetry reports written.
    pub telemetry: u64,
    /// Events written.
    pub events: u64,
    /// Payload bytes written (CDR, before compression).
    pub payload_bytes: u64,
    /// The newest message's time on the robot's clock, ns.
    pub last_ns: u64,
}

/// An MCAP recording being written.
pub struct Bag<W: Write + Seek> {
    mcap: mcap::Writer<W>,
    robot: RobotInfo,
    channels: BTreeMap<&'static str, u16>,
    schemas: BTreeMap<&'static str, u16>,
    sequence: u32,
    /// Close a chunk at least this often (the robot's time).
    pub flush_every: Duration,
    last_flush: Duration,
    gripper: Option<GripperState>,
    faults: u16,
    stats: BagStats,
    /// The disk filled: every later write is refused as that.
    full: bool,
}

/// Nanoseconds of `t`, as MCAP's times are.
fn ns(t: Duration) -> u64 {
    t.as_nanos().min(u128::from(u64::MAX)) as u64
}

impl<W: Write + Seek> Bag<W> {
    /// A recording of `robot` into `sink`, starting at `start` (the robot's clock): the URDF
    /// and the fixed joints' transforms are written first. lz4 at `level` (1 is fast).
    pub fn new(
        sink: W,
        robot: RobotInfo,
        start: Duration,
        level: u32,
    ) -> Result<Self, RecordError> {
        let mcap = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("ferrobot-record ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Lz4))
            .compression_level(level)
            .chunk_size(Some(4 << 20))
            .create(sink)?;
        let mut bag = Bag {
            mcap,
            robot,
            channels: BTreeMap::new(),
            schemas: BTreeMap::new(),
            sequence: 0,
            flush_every: Duration::from_millis(500),
            last_flush: start,
            gripper: None,
            faults: 0,
            stats: BagStats::default(),
            full: false,
        };
        let urdf = encode::string(&bag.robot.urdf);
        bag.write(topics::ROBOT_DESCRIPTION, start, &urdf)?;
        let fixed = bag.transforms(start, &[], true);
        bag.write(topics::TF_STATIC, start, &encode::tf_message(&fixed))?;
        Ok(bag)
    }

    /// What has been written so far.
    pub fn stats(&self) -> BagStats {
        self.stats
    }

    /// Writes one message on `topic` at `t`; its channel (and its type's schema) first, the
    /// first time.
    fn write(&mut self, topic: Topic, t: Duration, data: &[u8]) -> Result<(), RecordError> {
        let channel = match self.channels.get(topic.name) {
            Some(&c) => c,
            None => {
                let schema = match self.schemas.get(topic.msg.name) {
                    Some(&s) => s,
                    None => {
                        let text = topic.msg.schema();
                        let s = self
                            .mcap
                            .add_schema(topic.msg.name, "ros2msg", text.as_bytes())?;
                        self.schemas.insert(topic.msg.name, s);
                        s
                    }
                };
                let c = self
                    .mcap
                    .add_channel(schema, topic.name, "cdr", &BTreeMap::new())?;
                self.channels.insert(topic.name, c);
                c
            }
        };
        self.sequence = self.sequence.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: ns(t),
            publish_time: ns(t),
        };
        self.mcap.write_to_known_channel(&header, data)?;
        self.stats.messages += 1;
        self.stats.payload_bytes += data.len() as u64;
        self.stats.last_ns = self.stats.last_ns.max(ns(t));
        Ok(())
    }

    /// Writes `item`, then closes the chunk if the last was closed
    /// [`Bag::flush_every`] or longer before it. A full disk is [`RecordError::DiskFull`]:
    /// what was written up to the last closed chunk stays readable.
    pub fn push(&mut self, item: &Item) -> Result<(), RecordError> {
        if self.full {
            return Err(self.disk_full());
        }
        self.push_item(item).map_err(|e| self.typed(e))
    }

    /// `e`, or [`RecordError::DiskFull`] when it is the disk filling (remembered: nothing
    /// more is written).
    fn typed(&mut self, e: RecordError) -> RecordError {
        match e {
            RecordError::Mcap(m) if RecordError::is_disk_full(&m) => {
                self.full = true;
                self.disk_full()
            }
            e => e,
        }
    }

    fn disk_full(&self) -> RecordError {
        RecordError::DiskFull {
            written_s: self.stats.last_ns as f64 * 1e-9,
        }
    }

    fn push_item(&mut self, item: &Item) -> Result<(), RecordError> {
        let t = item.time();
        match item {
            Item::Telemetry(tel) => self.telemetry(tel)?,
            Item::Frame(f) => self.frame(f)?,
            Item::Event(e) => self.event(e)?,
        }
        if t.saturating_sub(self.last_flush) >= self.flush_every {
            self.mcap.flush()?;
            self.last_flush = t;
        }
        Ok(())
    }

    /// The transforms of the URDF's joints at joint values `q` (the tree's order): the fixed
    /// ones (`fixed`) or the moving ones.
    fn transforms(&self, t: Duration, q: &[f64], fixed: bool) -> Vec<Transform<'_>> {
        let tree = self.robot.frames.tree();
        let mut q = q.to_vec();
        q.resize(tree.joints().len(), 0.0);
        let poses = tree.poses(&q);
        let names: Vec<&str> = tree.links().collect();
        (0..names.len())
            .filter_map(|link| {
                let parent = tree.parent(link)?;
                if tree.link_joint(link).is_some() == fixed {
                    return None;
                }
                Some(Transform {
                    time: t,
                    parent: names[parent],
                    child: names[link],
                    pose: poses[parent].inverse() * poses[link],
                })
            })
            .collect()
    }

    fn telemetry(&mut self, tel: &Telemetry) -> Result<(), RecordError> {
        let t = Duration::from_micros(tel.time_us);
        let n = self.robot.joints.len().min(tel.joints.len());
        let joints = &tel.joints[..n];
        let msg = encode::joint_state(
            t,
            &self.robot.joints[..n],
            &joints
                .iter()
                .map(|j| f64::from(j.position))
                .collect::<Vec<_>>(),
            &joints
                .iter()
                .map(|j| f64::from(j.velocity))
                .collect::<Vec<_>>(),
            &joints
                .iter()
                .map(|j| f64::from(j.effort))
                .collect::<Vec<_>>(),
        );
        self.write(topics::JOINT_STATES, t, &msg)?;
        let q = self.robot.frames.joint_values(tel);
        let mut tf = self.transforms(t, &q, false);
        let o = tel.odometry;
        let base = Planar {
            pose: [f64::from(o.x), f64::from(o.y), f64::from(o.theta)],
            v: f64::from(o.v),
            w: f64::from(o.w),
        };
        let root = self.robot.frames.tree().root().to_string();
        if self.robot.base {
            tf.push(Transform {
                time: t,
                parent: topics::ODOM_FRAME,
                child: &root,
                pose: encode::planar_pose(base.pose),
            });
        }
        let tf = encode::tf_message(&tf);
        self.write(topics::TF, t, &tf)?;
        if self.robot.base {
            let odom = encode::odometry(t, topics::ODOM_FRAME, &root, &base);
            self.write(topics::ODOM, t, &odom)?;
        }
        if self.robot.gripper && self.gripper != Some(tel.gripper) {
            self.gripper = Some(tel.gripper);
            self.write(
                topics::GRIPPER_STATE,
                t,
                &encode::int8(tel.gripper.pyrobot_code()),
            )?;
        }
        if tel.faults != self.faults {
            let msg = crate::events::fault_flags(self.faults, tel.faults);
            self.faults = tel.faults;
            let log = encode::log(t, encode::level::WARN, "firmware", &msg);
            self.write(topics::ROSOUT, t, &log)?;
        }
        self.stats.telemetry += 1;
        Ok(())
    }

    fn frame(&mut self, f: &Frame) -> Result<(), RecordError> {
        let t = f.time;
        let frame_id = self.robot.optical.clone().unwrap_or_default();
        let (rgb, d) = (&f.rgb, &f.depth);
        let layout = encode::ImageLayout::packed(rgb.width, rgb.height, "rgb8", 3);
        let color = encode::image(t, &frame_id, layout, &rgb.data);
        self.write(topics::COLOR, t, &color)?;
        let bytes: Vec<u8> = d.data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let layout = encode::ImageLayout::packed(d.width, d.height, "32FC1", 4);
        let depth = encode::image(t, &frame_id, layout, &bytes);
        self.write(topics::DEPTH, t, &depth)?;
        let info = encode::camera_info(t, &frame_id, &f.intrinsics);
        self.write(topics::CAMERA_INFO, t, &info)?;
        let pose = encode::pose_stamped(t, ferrobot::frames::BASE_FRAME, &f.camera_pose);
        self.write(topics::CAMERA_POSE, t, &pose)?;
        let odom = encode::pose_stamped(t, topics::ODOM_FRAME, &encode::planar_pose(f.odometry));
        self.write(topics::CAMERA_ODOM, t, &odom)?;
        self.stats.frames += 1;
        Ok(())
    }

    fn event(&mut self, e: &Event) -> Result<(), RecordError> {
        for (topic, data) in crate::events::encode(&self.robot, e) {
            self.write(topic, e.time(), &data)?;
        }
        self.stats.events += 1;
        Ok(())
    }

    /// Ends the recording: the last chunk, the summary (indexes, statistics) and the footer.
    pub fn finish(mut self) -> Result<BagStats, RecordError> {
        if self.full {
            return Err(self.disk_full());
        }
        match self.mcap.finish() {
            Ok(_) => Ok(self.stats),
            Err(m) => Err(self.typed(m.into())),
        }
    }
}
