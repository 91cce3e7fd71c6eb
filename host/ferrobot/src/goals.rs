//! The goal table: what each component's goals claim ([`Claim`]), what they see at a step
//! ([`Step`]), the [`Goal`] trait each component implements, and the table of goals under way
//! and results not yet collected ([`Goals`]), with the faults and link events kept for the
//! program. A new goal preempts the goals whose claims it overlaps.

use std::collections::{HashMap, HashSet, VecDeque};
use std::time::Duration;

use ferrobot_protocol::{Fault, FaultKind, Telemetry};

use crate::backend::{Link, LinkEvent};
use crate::config::RobotConfig;
use crate::error::{Error, Result};

/// How long one [`crate::Motion::poll`] lets pass.
pub const POLL: Duration = Duration::from_millis(10);
/// Joint motions are not judged stalled during their first this long (they start at rest).
pub const STALL_GRACE: Duration = Duration::from_millis(300);
/// A joint motion whose largest error has not improved for this long has stalled.
pub const STALL_TIME: Duration = Duration::from_millis(500);
/// Improvement of the largest joint error that counts as progress, rad.
pub const STALL_PROGRESS: f64 = 0.001;
/// While a joint motion follows a timed reference, a joint lagging it by no more than this is
/// tracking, not stalled, rad (the servos lag a reference at speed by a few hundredths).
pub const STALL_LAG: f64 = 0.15;
/// A joint motion has arrived once every joint is within its tolerance and at rest: measured
/// slower than this, rad/s (above the velocity reading's quantum, 0.024 rad/s, and its noise).
/// A joint within tolerance may still be moving (the servo's last creep against its gear
/// friction): returning then would leave the arm moving on.
pub const ARRIVAL_SPEED: f64 = 0.05;
/// Faults kept for [`crate::Robot::take_faults`]; older ones are dropped first.
pub const FAULT_QUEUE: usize = 1024;
/// Link events kept for [`crate::Robot::take_link_events`]; older ones are dropped first.
pub const LINK_EVENT_QUEUE: usize = 64;

/// The firmware joint mask of joints (firmware indices, each below 16).
pub(crate) fn joint_mask(joints: impl IntoIterator<Item = usize>) -> u16 {
    joints.into_iter().fold(0, |m, j| m | (1 << j))
}

/// What a goal drives: joints (firmware joint mask), the base, the gripper. Two goals whose
/// claims overlap cannot run at once: the newer preempts the older.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Claim {
    /// Firmware joint mask.
    pub joints: u16,
    /// The mobile base.
    pub base: bool,
    /// The gripper's state machine.
    pub gripper: bool,
}

impl Claim {
    /// Whether the two claim anything in common.
    pub fn overlaps(&self, other: &Claim) -> bool {
        self.joints & other.joints != 0
            || (self.base && other.base)
            || (self.gripper && other.gripper)
    }

    /// Whether `fault` ends a goal with this claim (the emergency stop and the watchdog end
    /// every goal).
    pub(crate) fn hit_by(&self, fault: &Fault) -> bool {
        match fault.kind {
            FaultKind::Bumper | FaultKind::Cliff | FaultKind::WheelDrop | FaultKind::BaseLost => {
                self.base
            }
            FaultKind::ServoLost | FaultKind::ServoHardware => fault
                .joint
                .is_some_and(|j| j < 16 && self.joints & (1 << j) != 0),
            FaultKind::Watchdog | FaultKind::EmergencyStop => true,
            _ => false,
        }
    }
}

/// What a goal sees at each step.
pub(crate) struct Step<'a> {
    /// The link, to send commands.
    pub link: &'a mut dyn Link,
    /// The robot's configuration.
    pub cfg: &'a RobotConfig,
    /// The backend's clock.
    pub now: Duration,
    /// The newest telemetry.
    pub telemetry: &'a Telemetry,
    /// Base commands sent by host-side laws: (time s, v m/s, ω rad/s).
    pub base_log: &'a mut Vec<(f64, f64, f64)>,
    /// What the camera and SLAM tell the goals.
    pub sense: &'a crate::sense::Sense,
}

/// A goal of one component, stepped by whoever lets time pass.
pub(crate) trait Goal: Send {
    /// What it drives.
    fn claim(&self) -> Claim;
    /// One step at `s.now`: `Some(result)` once finished. Timeouts are judged by the table.
    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>>;
    /// Stop where it is (best effort): joints hold, the base stops.
    fn halt(&mut self, link: &mut dyn Link);
    /// Whether it wants the camera's obstacle scans ([`crate::sense::Sense::scan`]).
    fn wants_scans(&self) -> bool {
        false
    }
    /// Whether it wants SLAM's occupancy grid ([`crate::sense::Sense::grid`]).
    fn wants_grid(&self) -> bool {
        false
    }
}

/// A goal under way in the table.
pub(crate) struct Running {
    pub(crate) id: u64,
    pub(crate) goal: Box<dyn Goal>,
    pub(crate) what: String,
    pub(crate) timeout: Duration,
    pub(crate) deadline: Duration,
    /// When it was last stepped: a goal is stepped once per instant.
    pub(crate) stepped: Option<Duration>,
}

/// The goals under way and the results not yet collected.
#[derive(Default)]
pub(crate) struct Goals {
    pub(crate) next: u64,
    pub(crate) running: Vec<Running>,
    pub(crate) finished: HashMap<u64, Result<()>>,
    /// Goals whose handle was dropped: their results are not kept.
    detached: HashSet<u64>,
    /// Faults for [`crate::Robot::take_faults`].
    pub(crate) faults: VecDeque<Fault>,
    /// Link events for [`crate::Robot::take_link_events`].
    pub(crate) link_events: VecDeque<LinkEvent>,
}

impl Goals {
    /// Whether any goal under way wants what `f` asks of it.
    pub(crate) fn any(&self, f: impl Fn(&dyn Goal) -> bool) -> bool {
        self.running.iter().any(|g| f(g.goal.as_ref()))
    }

    pub(crate) fn finish(&mut self, id: u64, r: Result<()>) {
        if !self.detached.remove(&id) {
            self.finished.insert(id, r);
        }
    }

    /// Whether goal `id` is still under way.
    pub fn is_running(&self, id: u64) -> bool {
        self.running.iter().any(|g| g.id == id)
    }

    /// The result of goal `id`, once, when it has finished.
    pub fn take(&mut self, id: u64) -> Option<Result<()>> {
        self.finished.remove(&id)
    }

    /// Forget goal `id`'s result; a goal still under way runs on.
    pub fn detach(&mut self, id: u64) {
        if self.finished.remove(&id).is_none() && self.is_running(id) {
            self.detached.insert(id);
        }
    }

    /// End every goal under way with the error `e` makes (without halting them: the caller
    /// has stopped everything).
    pub fn end_all(&mut self, e: impl Fn() -> Error) {
        for g in std::mem::take(&mut self.running) {
            self.finish(g.id, Err(e()));
        }
    }

    /// The faults collected since the last call.
    pub fn take_faults(&mut self) -> Vec<Fault> {
        self.faults.drain(..).collect()
    }

    /// The link events collected since the last call.
    pub fn take_link_events(&mut self) -> Vec<LinkEvent> {
        self.link_events.drain(..).collect()
    }
}

/// The error a fault makes of a goal it ends.
pub(crate) fn fault_error(cfg: &RobotConfig, f: &Fault) -> Error {
    if f.kind == FaultKind::EmergencyStop {
        return Error::EmergencyStop;
    }
    let detail = match f.kind {
        FaultKind::Bumper | FaultKind::Cliff | FaultKind::WheelDrop => Some(sensor_names(f.code)),
        _ => f.joint.and_then(|j| cfg.joints.get(j as usize)).map(|j| {
            format!(
                "joint {} (servo {}), code {:#04x}",
                j.name.as_str(),
                j.servo_id,
                f.code
            )
        }),
    };
    Error::Fault {
        kind: f.kind,
        detail,
    }
}

fn sensor_names(bits: u16) -> String {
    use ferrobot_protocol::base_flags::*;
    let names = [
        (BUMPER_LEFT, "left bumper"),
        (BUMPER_CENTER, "centre bumper"),
        (BUMPER_RIGHT, "right bumper"),
        (CLIFF_LEFT, "left cliff sensor"),
        (CLIFF_CENTER, "centre cliff sensor"),
        (CLIFF_RIGHT, "right cliff sensor"),
        (WHEEL_DROP_LEFT, "left wheel drop"),
        (WHEEL_DROP_RIGHT, "right wheel drop"),
    ];
    names
        .iter()
        .filter(|(b, _)| bits & b != 0)
        .map(|(_, n)| *n)
        .collect::<Vec<_>>()
        .join(", ")
}
