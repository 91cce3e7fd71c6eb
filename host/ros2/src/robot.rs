//! A robot's streams as ROS 2 messages: its telemetry, camera frames and events in, each
//! message out with its topic ([`crate::topics`]). One mapping for everything that speaks ROS 2
//! for Ferrobot: the recorder writes the messages to MCAP, the zenoh bridge publishes them.

use std::sync::Arc;
use std::time::Duration;

use ferrobot::events::Event;
use ferrobot::frames::Frames;
use ferrobot::subscription::{Bell, Subscription};
use ferrobot::{Frame, GripperState, Robot, Telemetry};

use crate::encode::{self, Planar, Transform};
use crate::topics::{self, Topic};

/// What the messages of a robot need to know of it.
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

impl RobotInfo {
    /// What the messages of `robot` need to know of it.
    pub fn of(robot: &Robot) -> ferrobot::Result<RobotInfo> {
        let cfg = robot.config();
        // The URDF the robot was built from, as it was parsed.
        let urdf = urdf_rs::write_to_string(&cfg.urdf).unwrap_or_default();
        Ok(RobotInfo {
            joints: cfg.joints.iter().map(|j| j.name.clone()).collect(),
            frames: robot.frames()?.clone(),
            urdf,
            base: cfg.base.is_some(),
            gripper: cfg.gripper.is_some(),
            optical: cfg.camera.as_ref().map(|c| c.frame.clone()),
        })
    }
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

/// A robot's streams a reader subscribed to: its telemetry, its camera's frames (when it has a
/// camera and the reader asked) and its events.
pub struct Feeds {
    /// The telemetry reports.
    pub telemetry: Subscription<Telemetry>,
    /// The camera's frames.
    pub frames: Option<Subscription<Arc<Frame>>>,
    /// The events.
    pub events: Subscription<Event>,
}

impl Feeds {
    /// Subscribes to `robot`'s streams, each queue `queue` items long; to its camera's frames
    /// when `camera` and it has one.
    pub fn subscribe(robot: &Robot, queue: usize, camera: bool) -> ferrobot::Result<Feeds> {
        Ok(Feeds {
            telemetry: robot.subscribe_telemetry(queue)?,
            frames: match robot.config().camera.is_some() && camera {
                true => Some(robot.camera()?.subscribe(queue)?),
                false => None,
            },
            events: robot.subscribe_events(queue)?,
        })
    }

    /// Subscribes to `robot`'s camera frames (`on`, when it has a camera) or lets them go
    /// (the camera then renders or reads nothing for this reader), each queue `queue` frames
    /// long; the new subscription rings `bell`.
    pub fn set_camera(
        &mut self,
        robot: &Robot,
        on: bool,
        queue: usize,
        bell: &Arc<Bell>,
    ) -> ferrobot::Result<()> {
        match (on && robot.config().camera.is_some(), self.frames.is_some()) {
            (true, false) => {
                let frames = robot.camera()?.subscribe(queue)?;
                frames.ring(bell.clone());
                self.frames = Some(frames);
            }
            (false, true) => self.frames = None,
            _ => {}
        }
        Ok(())
    }

    /// Rings `bell` at every delivery to any of them.
    pub fn ring(&self, bell: &Arc<Bell>) {
        self.telemetry.ring(bell.clone());
        self.events.ring(bell.clone());
        if let Some(f) = &self.frames {
            f.ring(bell.clone());
        }
    }

    /// Everything waiting, in time order.
    pub fn take(&self) -> Vec<Item> {
        let mut items: Vec<Item> = self
            .telemetry
            .drain()
            .into_iter()
            .map(Item::Telemetry)
            .collect();
        if let Some(f) = &self.frames {
            items.extend(f.drain().into_iter().map(Item::Frame));
        }
        items.extend(self.events.drain().into_iter().map(Item::Event));
        items.sort_by_key(Item::time);
        items
    }
}

/// A message: its topic and its CDR payload (with the encapsulation header).
pub type Message = (Topic, Vec<u8>);

/// The mapping from a robot's items to messages; it remembers what is sent only on change (the
/// gripper's state, the fault flags).
#[derive(Debug, Clone)]
pub struct Messages {
    robot: RobotInfo,
    gripper: Option<GripperState>,
    faults: u16,
    points: Option<u32>,
}

impl Messages {
    /// The messages of `robot`.
    pub fn new(robot: RobotInfo) -> Self {
        Messages {
            robot,
            gripper: None,
            faults: 0,
            points: None,
        }
    }

    /// Each frame's points too ([`topics::POINTS`]), every `stride`-th pixel of every
    /// `stride`-th row: for live viewers, which draw points but not depth images.
    pub fn with_points(mut self, stride: u32) -> Self {
        self.points = Some(stride.max(1));
        self
    }

    /// The robot it maps.
    pub fn robot(&self) -> &RobotInfo {
        &self.robot
    }

    /// What is said once and holds (ROS 2's transient-local topics): the URDF on
    /// `/robot_description` and the fixed joints' transforms on `/tf_static`, stamped `t`.
    pub fn latched(&self, t: Duration) -> Vec<Message> {
        let fixed = self.transforms(t, &[], true);
        vec![
            (topics::ROBOT_DESCRIPTION, encode::string(&self.robot.urdf)),
            (topics::TF_STATIC, encode::tf_message(&fixed)),
        ]
    }

    /// The messages of `item`, all stamped with its time.
    pub fn of(&mut self, item: &Item) -> Vec<Message> {
        match item {
            Item::Telemetry(tel) => self.telemetry(tel),
            Item::Frame(f) => self.frame(f),
            Item::Event(e) => crate::events::encode(&self.robot, e),
        }
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

    fn telemetry(&mut self, tel: &Telemetry) -> Vec<Message> {
        let t = Duration::from_micros(tel.time_us);
        let n = self.robot.joints.len().min(tel.joints.len());
        let joints = &tel.joints[..n];
        let field = |f: fn(&ferrobot_protocol::JointState) -> f32| -> Vec<f64> {
            joints.iter().map(|j| f64::from(f(j))).collect()
        };
        let mut out = vec![(
            topics::JOINT_STATES,
            encode::joint_state(
                t,
                &self.robot.joints[..n],
                &field(|j| j.position),
                &field(|j| j.velocity),
                &field(|j| j.effort),
            ),
        )];
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
        out.push((topics::TF, encode::tf_message(&tf)));
        if self.robot.base {
            let odom = encode::odometry(t, topics::ODOM_FRAME, &root, &base);
            out.push((topics::ODOM, odom));
        }
        if self.robot.gripper && self.gripper != Some(tel.gripper) {
            self.gripper = Some(tel.gripper);
            let code = encode::int8(tel.gripper.pyrobot_code());
            out.push((topics::GRIPPER_STATE, code));
        }
        if tel.faults != self.faults {
            let msg = crate::events::fault_flags(self.faults, tel.faults);
            self.faults = tel.faults;
            let log = encode::log(t, encode::level::WARN, "firmware", &msg);
            out.push((topics::ROSOUT, log));
        }
        out
    }

    fn frame(&self, f: &Frame) -> Vec<Message> {
        let t = f.time;
        let frame_id = self.robot.optical.clone().unwrap_or_default();
        let (rgb, d) = (&f.rgb, &f.depth);
        let layout = encode::ImageLayout::packed(rgb.width, rgb.height, "rgb8", 3);
        let color = encode::image(t, &frame_id, layout, &rgb.data);
        let bytes: Vec<u8> = d.data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let layout = encode::ImageLayout::packed(d.width, d.height, "32FC1", 4);
        let depth = encode::image(t, &frame_id, layout, &bytes);
        let info = encode::camera_info(t, &frame_id, &f.intrinsics);
        let pose = encode::pose_stamped(t, ferrobot::frames::BASE_FRAME, &f.camera_pose);
        let odom = encode::pose_stamped(t, topics::ODOM_FRAME, &encode::planar_pose(f.odometry));
        let mut out = vec![
            (topics::COLOR, color),
            (topics::DEPTH, depth),
            (topics::CAMERA_INFO, info),
            (topics::CAMERA_POSE, pose),
            (topics::CAMERA_ODOM, odom),
        ];
        if let Some(stride) = self.points {
            let cloud = encode::point_cloud(t, &frame_id, d, rgb, &f.intrinsics, stride);
            out.push((topics::POINTS, cloud));
        }
        out
    }
}
