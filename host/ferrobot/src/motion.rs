//! Motions: goals under way on the robot's components, and [`Motion`], the owned handle to
//! one of them (poll, wait, cancel). Every blocking call of the API is its non-blocking form
//! followed by [`Motion::wait`].
//!
//! A motion does not borrow the robot: it holds a clone of the [`Robot`] handle and the number
//! of its goal. The goals of all components live in one table beside the link ([`Goals`]);
//! whoever lets time pass (any motion's `poll` or `wait`, [`Robot::wait`]) steps every goal
//! under way, so the arm, the gripper, the head and the base move at the same time, whichever
//! of them a program waits on. Each component defines its own goal type ([`Goal`]) in its own
//! module and claims what it drives ([`Claim`]); a new goal preempts (stops and ends with
//! [`Error::Preempted`]) the goals whose claims it overlaps.

use std::collections::{HashMap, HashSet, VecDeque};
use std::time::Duration;

use ferrobot_protocol::{Fault, FaultKind, Telemetry};

use crate::backend::{Link, LinkEvent};
use crate::config::RobotConfig;
use crate::error::{Error, Result};
use crate::robot::{Io, Robot};

/// How long one [`Motion::poll`] lets pass.
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
/// Faults kept for [`Robot::take_faults`]; older ones are dropped first.
pub const FAULT_QUEUE: usize = 1024;
/// Link events kept for [`Robot::take_link_events`]; older ones are dropped first.
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
    fn hit_by(&self, fault: &Fault) -> bool {
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

struct Running {
    id: u64,
    goal: Box<dyn Goal>,
    what: String,
    timeout: Duration,
    deadline: Duration,
    /// When it was last stepped: a goal is stepped once per instant.
    stepped: Option<Duration>,
}

/// The goals under way and the results not yet collected.
#[derive(Default)]
pub(crate) struct Goals {
    next: u64,
    running: Vec<Running>,
    finished: HashMap<u64, Result<()>>,
    /// Goals whose handle was dropped: their results are not kept.
    detached: HashSet<u64>,
    /// Faults for [`Robot::take_faults`].
    faults: VecDeque<Fault>,
    /// Link events for [`Robot::take_link_events`].
    link_events: VecDeque<LinkEvent>,
}

impl Goals {
    /// Whether any goal under way wants what `f` asks of it.
    pub(crate) fn any(&self, f: impl Fn(&dyn Goal) -> bool) -> bool {
        self.running.iter().any(|g| f(g.goal.as_ref()))
    }

    fn finish(&mut self, id: u64, r: Result<()>) {
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

impl Io {
    /// Collect the link's events and faults. A link lost ends every goal under way with
    /// [`Error::Link`] (a reconnection is a new session: nothing from before it goes on); each
    /// goal a fault hits ends with its error. Both are kept for [`Robot::take_link_events`]
    /// and [`Robot::take_faults`].
    pub(crate) fn collect_faults(&mut self, cfg: &RobotConfig) {
        for e in self.link.take_events() {
            if let LinkEvent::Lost { why } = &e {
                let why = format!("{why} (reconnecting)");
                self.end_where(|_| true, |_| Error::Link(why.clone()));
            }
            if self.goals.link_events.len() >= LINK_EVENT_QUEUE {
                self.goals.link_events.pop_front();
            }
            self.goals.link_events.push_back(e);
        }
        let faults = self.link.take_faults();
        if faults.is_empty() {
            return;
        }
        for f in faults {
            self.end_where(|c| c.hit_by(&f), |_| fault_error(cfg, &f));
            if self.goals.faults.len() >= FAULT_QUEUE {
                self.goals.faults.pop_front();
            }
            self.goals.faults.push_back(f);
        }
    }

    /// Halt every goal under way whose claim `hit` picks, and end it with the error `error`
    /// makes of its description.
    fn end_where(&mut self, hit: impl Fn(&Claim) -> bool, error: impl Fn(String) -> Error) {
        let (ended, running): (Vec<_>, Vec<_>) = std::mem::take(&mut self.goals.running)
            .into_iter()
            .partition(|g| hit(&g.goal.claim()));
        self.goals.running = running;
        for mut g in ended {
            g.goal.halt(self.link.as_mut());
            self.goals.finish(g.id, Err(error(g.what)));
        }
    }

    /// Before a new goal with `claim` sends its first command: collect the faults so far (so
    /// that the new goal sees only later ones) and preempt the goals it overlaps (each is
    /// halted and ends with [`Error::Preempted`]).
    pub(crate) fn prepare(&mut self, cfg: &RobotConfig, claim: Claim) {
        self.collect_faults(cfg);
        self.end_where(|c| c.overlaps(&claim), |what| Error::Preempted { what });
    }

    /// Put a goal under way (after [`Io::prepare`] and its first commands); it may take
    /// `timeout` of the backend's time. Returns its number.
    pub(crate) fn start(&mut self, goal: Box<dyn Goal>, what: &str, timeout: Duration) -> u64 {
        let id = self.goals.next;
        self.goals.next += 1;
        let now = self.link.now();
        // Timeouts are validated at the API (`validate::timeout`); saturate all the same.
        self.goals.running.push(Running {
            id,
            goal,
            what: what.to_string(),
            timeout,
            deadline: now.saturating_add(timeout),
            stepped: None,
        });
        id
    }

    /// Step every goal under way at the present instant (each once per instant).
    pub(crate) fn step(&mut self, cfg: &RobotConfig) {
        self.collect_faults(cfg);
        if self.goals.running.is_empty() {
            return;
        }
        let now = self.link.now();
        let t = match self.link.telemetry() {
            Ok(t) => t,
            Err(e) => {
                // The link failed: every goal ends with its error.
                let msg = e.to_string();
                let mut first = Some(e);
                for g in std::mem::take(&mut self.goals.running) {
                    let e = first.take().unwrap_or_else(|| Error::Link(msg.clone()));
                    self.goals.finish(g.id, Err(e));
                }
                return;
            }
        };
        self.base.log_wheels(&t);
        let mut i = 0;
        while i < self.goals.running.len() {
            let g = &mut self.goals.running[i];
            if g.stepped == Some(now) {
                i += 1;
                continue;
            }
            g.stepped = Some(now);
            let mut s = Step {
                link: self.link.as_mut(),
                cfg,
                now,
                telemetry: &t,
                base_log: &mut self.base.log,
                sense: &self.sense,
            };
            let r = g.goal.step(&mut s).or_else(|| {
                (now >= g.deadline).then(|| {
                    Err(Error::Timeout {
                        what: g.what.clone(),
                        after: g.timeout,
                    })
                })
            });
            match r {
                None => i += 1,
                Some(r) => {
                    let mut g = self.goals.running.remove(i);
                    if r.is_err() {
                        g.goal.halt(self.link.as_mut());
                    }
                    self.goals.finish(g.id, r);
                }
            }
        }
    }

    /// Let `dt` pass (the backend's time) and step every goal under way.
    pub(crate) fn pump(&mut self, cfg: &RobotConfig, dt: Duration) {
        self.link.wait(dt);
        self.step(cfg);
        self.feed_camera();
    }

    /// Stop goal `id` where it is, when it is under way; its result is dropped.
    pub(crate) fn cancel(&mut self, id: u64) {
        self.goals.finished.remove(&id);
        if let Some(i) = self.goals.running.iter().position(|g| g.id == id) {
            let mut g = self.goals.running.remove(i);
            g.goal.halt(self.link.as_mut());
        }
    }
}

/// The error a fault makes of a goal it ends.
fn fault_error(cfg: &RobotConfig, f: &Fault) -> Error {
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

/// A motion under way: an owned handle to poll, wait on or cancel. It does not borrow the
/// robot; other motions (of other components) and other threads go on meanwhile. Dropping it
/// lets the motion run on, unobserved.
#[must_use = "a dropped motion runs on unobserved: wait on it, poll it or cancel it"]
pub struct Motion {
    robot: Robot,
    id: u64,
    result: Option<Result<()>>,
    /// The result has been handed out or the goal cancelled: nothing to detach on drop.
    done: bool,
}

impl std::fmt::Debug for Motion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Motion")
            .field("id", &self.id)
            .field("result", &self.result)
            .finish()
    }
}

impl Motion {
    pub(crate) fn new(robot: Robot, id: u64) -> Self {
        Motion {
            robot,
            id,
            result: None,
            done: false,
        }
    }

    /// Whether it has finished (successfully or not), as of the last time anyone let time
    /// pass.
    pub fn is_finished(&self) -> bool {
        self.result.is_some() || !self.robot.lock_io().goals.is_running(self.id)
    }

    /// Let [`POLL`] pass (stepping every motion under way) and check; `Some(result)` once
    /// finished. A motion that has already finished returns at once.
    pub fn poll(&mut self) -> Option<&Result<()>> {
        if self.result.is_none() && !self.done {
            let cfg = self.robot.cfg();
            let mut io = self.robot.lock_io();
            self.result = io.goals.take(self.id);
            if self.result.is_none() {
                io.pump(cfg, POLL);
                self.result = io.goals.take(self.id);
            }
            // Hand the link to a thread that is waiting for it.
            parking_lot::MutexGuard::unlock_fair(io);
        }
        self.result.as_ref()
    }

    /// Block until finished; the result says why it ended.
    pub fn wait(mut self) -> Result<()> {
        // Check first: a motion may be finished before any time passes.
        if self.result.is_none() {
            let cfg = self.robot.cfg();
            let mut io = self.robot.lock_io();
            io.step(cfg);
            self.result = io.goals.take(self.id);
        }
        loop {
            if let Some(r) = self.result.take() {
                self.done = true;
                return r;
            }
            self.poll();
        }
    }

    /// Stop the motion where it is: joints hold, the base stops. The other motions under way
    /// run on.
    pub fn cancel(mut self) -> Result<()> {
        self.robot.lock_io().cancel(self.id);
        self.done = true;
        Ok(())
    }
}

impl Drop for Motion {
    fn drop(&mut self) {
        if !self.done && self.result.is_none() {
            self.robot.lock_io().goals.detach(self.id);
        }
    }
}

/// The goal of joints (firmware indices) reaching targets within a tolerance: arm moves,
/// Cartesian paths and the pan-tilt head.
pub(crate) struct JointsGoal {
    /// Firmware joint indices.
    idx: Vec<usize>,
    /// Targets, rad.
    target: Vec<f64>,
    /// Arrival tolerance, rad.
    tolerance: f64,
    /// When the last knot sent for these joints is due (the backend's clock): the goal is not
    /// reached before, even if the joints pass their targets on the way.
    due: Duration,
    /// When the motion started.
    started: Duration,
    /// The timed path the joints follow (s from `started`, positions in `idx` order), when it
    /// is known: while it runs, a stall is judged by the lag behind it, not by the distance
    /// to the target (a planned path may lead away from the target first).
    reference: Vec<(f64, Vec<f64>)>,
    /// Best (smallest) worst-joint error so far, when it was reached, and whether it was a lag
    /// behind the reference.
    stall_since: Option<(f64, Duration, bool)>,
}

impl JointsGoal {
    /// Joints `idx` to reach `target` (rad) within `tolerance`, started at `started`, not
    /// before `due`.
    pub(crate) fn new(
        idx: Vec<usize>,
        target: Vec<f64>,
        tolerance: f64,
        started: Duration,
        due: Duration,
    ) -> Self {
        JointsGoal {
            idx,
            target,
            tolerance,
            due,
            started,
            reference: Vec::new(),
            stall_since: None,
        }
    }

    /// The goal following the timed path `reference` (s from the start, positions in the
    /// joints' order, times increasing).
    pub(crate) fn following(mut self, reference: Vec<(f64, Vec<f64>)>) -> Self {
        self.reference = reference;
        self
    }

    fn mask(&self) -> u16 {
        joint_mask(self.idx.iter().copied())
    }

    /// Where the reference has the joints `t` s after the start (linear between its points);
    /// `None` before its first or after its last point.
    fn reference_at(&self, t: f64) -> Option<Vec<f64>> {
        let k = self.reference.iter().position(|(tk, _)| *tk >= t)?;
        let (t1, q1) = &self.reference[k];
        if k == 0 {
            return (t >= *t1 - 1e-9).then(|| q1.clone());
        }
        let (t0, q0) = &self.reference[k - 1];
        let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 1.0 };
        Some(q0.iter().zip(q1).map(|(a, b)| a + f * (b - a)).collect())
    }
}

impl Goal for JointsGoal {
    fn claim(&self) -> Claim {
        Claim {
            joints: self.mask(),
            ..Claim::default()
        }
    }

    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>> {
        let now = s.now;
        let position = |j: usize| {
            s.telemetry
                .joints
                .get(j)
                .copied()
                .unwrap_or_default()
                .position as f64
        };
        let mut worst = (0usize, 0.0f64);
        let mut at_rest = true;
        for (&j, &q) in self.idx.iter().zip(self.target.iter()) {
            let st = s.telemetry.joints.get(j).copied().unwrap_or_default();
            let e = (st.position as f64 - q).abs();
            if e > worst.1 {
                worst = (j, e);
            }
            at_rest &= (st.velocity as f64).abs() < ARRIVAL_SPEED;
        }
        if worst.1 <= self.tolerance && at_rest && now >= self.due {
            return Some(Ok(()));
        }
        // Stalled: past the start of the motion, the largest joint error has not improved by
        // STALL_PROGRESS for STALL_TIME (a blocked joint, or a trajectory that ended short of
        // its target). Progress, not speed readings, so that noise on a joint pressed against
        // an obstacle does not hide the stall. Joints within tolerance of their targets,
        // waiting for the last knot to be due, are not stalled. While a known reference runs,
        // the error is the lag behind it, and a lag within STALL_LAG is no stall.
        let t = now.saturating_sub(self.started).as_secs_f64();
        let lagging = self.reference_at(t).map(|r| {
            self.idx
                .iter()
                .zip(&r)
                .map(|(&j, &q)| (j, (position(j) - q).abs()))
                .fold((0usize, 0.0f64), |w, e| if e.1 > w.1 { e } else { w })
        });
        let (error, tracking) = match lagging {
            Some(lag) if lag.1 <= STALL_LAG => {
                self.stall_since = None;
                return None;
            }
            Some(lag) => (lag, true),
            None => (worst, false),
        };
        let (best, at, _) = match self.stall_since {
            Some(since) if since.2 == tracking => since,
            _ => *self.stall_since.insert((error.1, now, tracking)),
        };
        if error.1 < best - STALL_PROGRESS {
            self.stall_since = Some((error.1, now, tracking));
        } else if error.1 > self.tolerance
            && now > self.started + STALL_GRACE
            && now - at > STALL_TIME
        {
            let joint = s
                .cfg
                .joints
                .get(error.0)
                .map(|j| j.name.to_string())
                .unwrap_or_default();
            return Some(Err(Error::Stalled {
                joint,
                position: position(error.0),
                error: error.1,
            }));
        }
        None
    }

    fn halt(&mut self, link: &mut dyn Link) {
        let _ = link.command(
            &ferrobot_protocol::HostMsg::ClearQueue {
                joints: self.mask(),
            },
            "stop",
        );
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
