//! The robot's events as a stream ([`crate::Robot::subscribe_events`]): every command the host
//! sends the firmware, every fault, what happens to the link, SLAM's pose at each tracked
//! frame, and the arm's planned motions, each stamped with the robot's clock. Recorders subscribe to it; reading it takes
//! nothing from [`crate::Robot::take_faults`] or [`crate::Robot::take_link_events`].
//!
//! The commands are tapped where they leave the API: a tap wraps the backend's link and
//! publishes each command that the firmware acknowledged, so no goal, component or backend
//! needs to know about recording.

use std::sync::Arc;
use std::time::Duration;

use ferrobot_protocol::{DeviceInfo, Diagnostics, Fault, JointConfig, Telemetry};
/// The commands' types as the wire protocol carries them ([`Event::Command`]).
pub use ferrobot_protocol::{GripperCommand, HostMsg, JointMode, JointPoint};
use ferrobot_slam::TrackReport;
use parking_lot::Mutex;

use crate::backend::{Link, LinkEvent, StopLine};
use crate::error::Result;
use crate::subscription::Publisher;

/// One event of the robot, at `time` on the robot's clock (the backend's, since the firmware
/// started).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Event {
    /// A command the firmware acknowledged (a rejected one is not an event: it changed
    /// nothing).
    Command {
        /// When it was sent.
        time: Duration,
        /// The message, as the wire protocol carries it (SI units, joint-table order).
        msg: HostMsg,
    },
    /// A fault the firmware reported.
    Fault {
        /// When the host received it (the fault's own time is `fault.time_us`, the firmware's
        /// clock).
        time: Duration,
        /// The fault.
        fault: Fault,
    },
    /// The link was lost or came back.
    Link {
        /// When the host saw it.
        time: Duration,
        /// What happened.
        event: LinkEvent,
    },
    /// SLAM tracked a frame (or lost it).
    Slam {
        /// The frame's capture time.
        time: Duration,
        /// SLAM's report: the body's pose in the map (m, `[x, y, z, w]` quaternion inside), the
        /// tracking state, the keyframe and loop-closure flags.
        report: TrackReport,
    },
    /// The arm planned a motion ([`crate::arm::Arm::plan_to`], and every move that plans).
    ArmPlan {
        /// When it was planned.
        time: Duration,
        /// The plan: its waypoints, and where the end effector goes along it.
        plan: Arc<PlannedArmPath>,
    },
}

/// An arm's planned motion, as a viewer draws it.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedArmPath {
    /// The arm's base frame (a URDF link): the frame of [`PlannedArmPath::ee_path`].
    pub frame: String,
    /// The end effector's frame (a URDF link).
    pub ee_frame: String,
    /// The arm's joints, in the order of every waypoint.
    pub joints: Vec<String>,
    /// The planner's waypoints, rad, joined by collision-free straight edges.
    pub waypoints: Vec<Vec<f64>>,
    /// The end effector's pose in `frame` along the timed trajectory: at its start, every
    /// [`PlannedArmPath::EE_STEP`] s, and at its end; each with its time from the start, s.
    pub ee_path: Vec<(f64, nalgebra::Isometry3<f64>)>,
    /// The trajectory's duration, s.
    pub duration: f64,
}

impl PlannedArmPath {
    /// The end effector path's step, s.
    pub const EE_STEP: f64 = 0.05;
}

impl Event {
    /// The event's time on the robot's clock.
    pub fn time(&self) -> Duration {
        match self {
            Event::Command { time, .. }
            | Event::Fault { time, .. }
            | Event::Link { time, .. }
            | Event::Slam { time, .. }
            | Event::ArmPlan { time, .. } => *time,
        }
    }
}

/// The events' publisher, shared by the hub and the tapped link.
pub(crate) type Events = Arc<Mutex<Publisher<Event>>>;

/// A link whose acknowledged commands are published as [`Event::Command`]s; everything else
/// passes through to the backend's link, [`Link::as_any_mut`] included (the simulator's world
/// is reached through it).
pub(crate) struct Tapped {
    inner: Box<dyn Link>,
    events: Events,
}

impl Tapped {
    /// `inner`, tapped into `events`.
    pub(crate) fn new(inner: Box<dyn Link>, events: Events) -> Tapped {
        Tapped { inner, events }
    }
}

impl Link for Tapped {
    fn info(&self) -> &DeviceInfo {
        self.inner.info()
    }
    fn command(&mut self, msg: &HostMsg, what: &str) -> Result<()> {
        let time = self.inner.now();
        self.inner.command(msg, what)?;
        let mut events = self.events.lock();
        if events.wanted() {
            events.publish(Event::Command {
                time,
                msg: msg.clone(),
            });
        }
        Ok(())
    }
    fn joint_config(&mut self, index: u8) -> Result<JointConfig> {
        self.inner.joint_config(index)
    }
    fn diagnostics(&mut self) -> Result<Diagnostics> {
        self.inner.diagnostics()
    }
    fn telemetry(&mut self) -> Result<Telemetry> {
        self.inner.telemetry()
    }
    fn take_telemetry(&mut self) -> Vec<Telemetry> {
        self.inner.take_telemetry()
    }
    fn wait(&mut self, dt: Duration) {
        self.inner.wait(dt)
    }
    fn now(&self) -> Duration {
        self.inner.now()
    }
    fn pace(&mut self) -> Duration {
        self.inner.pace()
    }
    fn command_horizon(&self) -> Duration {
        self.inner.command_horizon()
    }
    fn take_faults(&mut self) -> Vec<Fault> {
        self.inner.take_faults()
    }
    fn take_events(&mut self) -> Vec<LinkEvent> {
        self.inner.take_events()
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self.inner.as_any_mut()
    }
    fn stop_line(&self) -> Option<Arc<dyn StopLine>> {
        self.inner.stop_line()
    }
}
