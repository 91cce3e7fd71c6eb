//! A robot served on zenoh as a ROS 2 node ([`Server`]): a thread publishes the robot's
//! streams, as [`ferrobot_ros2::robot`] maps them, as they arrive, and the world's bodies and
//! map as [`WorldFeed`] reads them; `/cmd_vel` drives the base, and `/goal_pose` and
//! `/arm/joint_trajectory` set goals ([`crate::inputs`]).
//!
//! The robot's time must pass for its streams to flow: on the simulator, whoever serves it
//! lets it pass (`ferrobot serve` waits in a loop, paced to the wall clock), or, served in
//! lockstep ([`ServeOptions::lockstep`]), its remote clients do as they wait; a real robot's
//! passes by itself.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use ferrobot::{Bell, Robot};
use ferrobot_ros2::robot::{Feeds, Item, Messages, RobotInfo};
use ferrobot_ros2::topics::{self, Topic};
use ferrobot_ros2::view::WorldFeed;
use parking_lot::Mutex;

use crate::error::BridgeError;
use crate::inputs::Inputs;
use crate::node::{RosNode, RosPublisher};
use crate::remote::wire::{self, RemoteCamera, RemoteInfo};
use crate::remote::{RemoteService, RemoteStats};

/// Each frame's points are every this many pixels of every this many rows (160 × 120 of a
/// 640 × 480 frame: 300 kB at most).
pub const POINTS_STRIDE: u32 = 4;

/// How a robot is served.
#[derive(Debug, Clone, PartialEq)]
pub struct ServeOptions {
    /// The ROS domain (`ROS_DOMAIN_ID`).
    pub domain: u32,
    /// The robot's namespace: `/` for none, `/locobot` to serve two robots side by side.
    pub namespace: String,
    /// The node's name.
    pub node: String,
    /// Publish the camera's frames (colour, depth, intrinsics).
    pub camera: bool,
    /// Each stream's queue, items: what the publisher may fall behind before the oldest is
    /// dropped.
    pub queue: usize,
    /// How long one `/cmd_vel` message drives the base (s): a teleoperator that falls silent
    /// stops it within this.
    pub cmd_vel_hold: f64,
    /// Serve the remote backend too ([`crate::remote`]): other programs drive the robot through
    /// the API.
    pub remote: bool,
    /// The robot's time passes only while a remote client waits (a simulator not paced to the
    /// wall clock, which nobody else lets pass): virtual time, as in-process, so that what a
    /// client does is the same on a busy machine as on a quiet one. Off for a robot whose time
    /// runs by itself (a real one, or a simulator paced to the wall clock and waited on).
    pub lockstep: bool,
}

impl Default for ServeOptions {
    fn default() -> Self {
        ServeOptions {
            domain: 0,
            namespace: "/".into(),
            node: "ferrobot".into(),
            camera: true,
            queue: 256,
            cmd_vel_hold: 0.5,
            remote: true,
            lockstep: false,
        }
    }
}

/// What a server has done so far.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ServeStats {
    /// Samples published, by topic name.
    pub published: BTreeMap<String, u64>,
    /// Samples that could not be published (zenoh refused).
    pub failed: u64,
    /// `/cmd_vel` messages that drive the base.
    pub cmd_vel_accepted: u64,
    /// `/cmd_vel` messages refused (malformed, beyond the base's limits), and the last reason.
    pub cmd_vel_refused: u64,
    /// `/goal_pose` and `/arm/joint_trajectory` messages taken as goals.
    pub goals_accepted: u64,
    /// Goals refused (malformed, not finite, beyond the robot's limits, unknown joints), or
    /// that the arm refused or ended with an error on the way.
    pub goals_refused: u64,
    /// Why the last `/cmd_vel` message or goal was refused.
    pub last_refusal: Option<String>,
    /// Items dropped because the publisher fell behind.
    pub dropped: u64,
    /// The remote backend's service.
    pub remote: RemoteStats,
}

/// A robot served on zenoh; dropping it (or [`Server::stop`]) ends it.
pub struct Server {
    stop: Arc<AtomicBool>,
    bell: Arc<Bell>,
    stats: Arc<Mutex<ServeStats>>,
    thread: Option<JoinHandle<()>>,
    _inputs: Inputs,
    node: Arc<RosNode>,
    remote: Option<Arc<RemoteService>>,
}

/// The topics a robot publishes from the start (others are declared when first sent).
fn announced(info: &RobotInfo, camera: bool) -> Vec<Topic> {
    let mut t = vec![
        topics::ROBOT_DESCRIPTION,
        topics::TF_STATIC,
        topics::TF,
        topics::JOINT_STATES,
        topics::ROSOUT,
        topics::CLOCK,
    ];
    if info.base {
        t.push(topics::ODOM);
    }
    if info.gripper {
        t.push(topics::GRIPPER_STATE);
    }
    if camera && info.optical.is_some() {
        t.extend([
            topics::COLOR,
            topics::DEPTH,
            topics::CAMERA_INFO,
            topics::POINTS,
        ]);
    }
    t
}

impl Server {
    /// Serves `robot` on `session`.
    pub fn start(
        robot: &Robot,
        session: &zenoh::Session,
        opts: ServeOptions,
    ) -> Result<Server, BridgeError> {
        if !(opts.cmd_vel_hold.is_finite() && opts.cmd_vel_hold > 0.0 && opts.cmd_vel_hold <= 10.0)
        {
            return Err(BridgeError::Usage(format!(
                "cmd_vel_hold {} s: between 0 and 10 s",
                opts.cmd_vel_hold
            )));
        }
        if opts.lockstep && !opts.remote {
            return Err(BridgeError::Usage(
                "lockstep serving needs the remote backend: its clients let the robot's time pass"
                    .into(),
            ));
        }
        let node = Arc::new(RosNode::new(
            session,
            opts.domain,
            &opts.namespace,
            &opts.node,
        )?);
        let info = RobotInfo::of(robot)?;
        let camera = opts.camera && info.optical.is_some() && robot.camera().is_ok();
        let mut publishers = BTreeMap::new();
        for t in announced(&info, camera) {
            publishers.insert(t.name, node.publisher(&t)?);
        }
        let messages = Messages::new(info).with_points(POINTS_STRIDE);
        let start = Duration::from_secs_f64(robot.time());
        let stats = Arc::new(Mutex::new(ServeStats::default()));
        let mut publish = Publish {
            node: node.clone(),
            publishers,
            stats: stats.clone(),
        };
        for (topic, data) in messages.latched(start) {
            publish.put(topic, data);
        }
        // The camera's frames are read (rendered, on the simulator) only while someone
        // subscribes to its topics ([`Serving::camera_on_demand`]).
        let feeds = Feeds::subscribe(robot, opts.queue.clamp(1, 100_000), false)?;
        let bell = Bell::new();
        feeds.ring(&bell);
        let inputs = Inputs::subscribe(robot, &node, opts.cmd_vel_hold, &stats)?;
        let remote = match opts.remote {
            true => Some(Arc::new(remote(robot, session, &opts, camera)?)),
            false => None,
        };
        let stop = Arc::new(AtomicBool::new(false));
        let (their_stop, their_bell) = (stop.clone(), bell.clone());
        let serving = Serving {
            robot: robot.clone(),
            camera: camera.then(|| (opts.queue.clamp(1, 100_000), None)),
            feeds,
            messages,
            world: WorldFeed::default(),
            publish,
            remote: remote.clone(),
        };
        let thread = std::thread::Builder::new()
            .name("ferrobot-serve".into())
            .spawn(move || serving.run(their_stop, their_bell))
            .map_err(|e| BridgeError::Usage(format!("starting the server's thread: {e}")))?;
        Ok(Server {
            stop,
            bell,
            stats,
            thread: Some(thread),
            _inputs: inputs,
            node,
            remote,
        })
    }

    /// What it has done so far.
    pub fn stats(&self) -> ServeStats {
        let mut s = self.stats.lock().clone();
        s.remote = self.remote.as_ref().map(|r| r.stats()).unwrap_or_default();
        s
    }

    /// The ROS 2 node it serves as.
    pub fn node(&self) -> &RosNode {
        &self.node
    }

    /// Publishes what is left and ends; what it did.
    pub fn stop(mut self) -> ServeStats {
        self.end();
        self.stats()
    }

    fn end(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        self.bell.ring();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.end();
    }
}

/// The publishers, declared as topics are first sent.
struct Publish {
    node: Arc<RosNode>,
    publishers: BTreeMap<&'static str, RosPublisher>,
    stats: Arc<Mutex<ServeStats>>,
}

impl Publish {
    /// Whether anyone subscribes to any of `topics`.
    fn matched(&self, topics: &[Topic]) -> bool {
        topics.iter().any(|t| {
            self.publishers
                .get(t.name)
                .is_some_and(RosPublisher::matched)
        })
    }

    fn put(&mut self, topic: Topic, data: Vec<u8>) {
        if !self.publishers.contains_key(topic.name) {
            match self.node.publisher(&topic) {
                Ok(p) => {
                    self.publishers.insert(topic.name, p);
                }
                Err(_) => {
                    self.stats.lock().failed += 1;
                    return;
                }
            }
        }
        let ok = self.publishers.get(topic.name).map(|p| p.put(data).is_ok());
        let mut s = self.stats.lock();
        match ok {
            Some(true) => *s.published.entry(topic.name.to_string()).or_default() += 1,
            _ => s.failed += 1,
        }
    }
}

/// The serving thread's work: the robot's items to messages, published; the remote backend's
/// telemetry, faults and watchdog.
struct Serving {
    robot: Robot,
    /// With a camera served: its frames' queue, and when its subscribers were last looked for.
    camera: Option<(usize, Option<std::time::Instant>)>,
    feeds: Feeds,
    messages: Messages,
    world: WorldFeed,
    publish: Publish,
    remote: Option<Arc<RemoteService>>,
}

/// How often the camera's subscribers are looked for, wall time.
const CAMERA_LOOK: Duration = Duration::from_millis(100);

impl Serving {
    /// Reads the camera's frames while anyone subscribes to its topics, and lets them go when
    /// nobody does: a served simulator renders no frame nobody takes (a remote client reads its
    /// camera's topics only once it captures).
    fn camera_on_demand(&mut self, bell: &Arc<Bell>) {
        let Some((queue, looked)) = &mut self.camera else {
            return;
        };
        if looked.is_some_and(|at| at.elapsed() < CAMERA_LOOK) {
            return;
        }
        *looked = Some(std::time::Instant::now());
        let wanted = self.publish.matched(&topics::CAMERA);
        if self
            .feeds
            .set_camera(&self.robot, wanted, *queue, bell)
            .is_err()
        {
            self.camera = None;
        }
    }

    fn run(mut self, stop: Arc<AtomicBool>, bell: Arc<Bell>) {
        loop {
            let stopping = stop.load(Ordering::SeqCst);
            self.camera_on_demand(&bell);
            if let Some(r) = &self.remote {
                r.publish_faults();
            }
            for item in self.feeds.take() {
                if let Item::Telemetry(t) = &item {
                    let at = Duration::from_micros(t.time_us);
                    self.publish
                        .put(topics::CLOCK, ferrobot_ros2::encode::clock(at));
                }
                if let (Some(r), Item::Telemetry(t)) = (&self.remote, &item) {
                    r.telemetry(t);
                }
                for (topic, data) in self.messages.of(&item) {
                    // `/cmd_vel` is the robot's input on ROS 2: the base's commands are not
                    // echoed on it (they are on `/ferrobot/commands`).
                    if topic.name != topics::CMD_VEL.name {
                        self.publish.put(topic, data);
                    }
                }
            }
            for (topic, data) in self.world.poll(&self.robot) {
                self.publish.put(topic, data);
            }
            let f = &self.feeds;
            let dropped = f.telemetry.dropped()
                + f.events.dropped()
                + f.frames.as_ref().map_or(0, |f| f.dropped());
            self.publish.stats.lock().dropped = dropped;
            if stopping {
                return;
            }
            if let Some(r) = &self.remote {
                r.watchdog();
                r.alive();
            }
            // Woken by each item; the remote backend's watchdog looks at least this often.
            bell.wait(Duration::from_millis(20));
        }
    }
}

/// The remote backend's service for `robot`.
fn remote(
    robot: &Robot,
    session: &zenoh::Session,
    opts: &ServeOptions,
    camera: bool,
) -> Result<RemoteService, BridgeError> {
    let camera = match camera {
        true => {
            let i = robot.camera()?.intrinsics()?;
            Some(RemoteCamera {
                size: [i.width, i.height],
                pinhole: [i.fx, i.fy, i.cx, i.cy],
                rate: robot.config().camera.as_ref().map_or(30.0, |c| c.rate),
            })
        }
        false => None,
    };
    let info = RemoteInfo {
        robot: robot.name().to_string(),
        device: robot.device_info(),
        camera,
        domain: opts.domain,
        lockstep: opts.lockstep,
        shared: robot.shares_world(),
    };
    RemoteService::start(robot, session, &wire::prefix(&opts.namespace), info)
}

/// A thread that lets a robot's time pass, `step` at a time, until dropped: what a simulated
/// robot being served needs (the simulator's time passes only while someone waits), paced to
/// the wall clock when the simulator is (`realtime`).
pub struct Clock {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Clock {
    /// Starts letting `robot`'s time pass.
    pub fn start(robot: &Robot, step: Duration) -> Clock {
        let stop = Arc::new(AtomicBool::new(false));
        let (r, s) = (robot.clone(), stop.clone());
        let thread = std::thread::Builder::new()
            .name("ferrobot-clock".into())
            .spawn(move || {
                while !s.load(Ordering::SeqCst) {
                    if r.wait(step.as_secs_f64()).is_err() {
                        std::thread::sleep(step);
                    }
                }
            })
            .ok();
        Clock { stop, thread }
    }
}

impl Drop for Clock {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
