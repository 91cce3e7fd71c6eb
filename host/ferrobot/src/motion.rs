//! [`Motion`]: a motion under way, to wait on, poll or cancel. Every blocking call of the API
//! is its non-blocking form followed by [`Motion::wait`].

use std::time::Duration;

use ferrobot_protocol::{FaultKind, GripperState, HostMsg};

use crate::base::BaseLaw;
use crate::error::{Error, Result};
use crate::robot::Robot;

/// How long one [`Motion::poll`] lets pass.
pub const POLL: Duration = Duration::from_millis(10);
/// Joint motions are not judged stalled during their first this long (they start at rest).
pub const STALL_GRACE: Duration = Duration::from_millis(300);
/// A joint motion whose largest error has not improved for this long has stalled.
pub const STALL_TIME: Duration = Duration::from_millis(500);
/// Improvement of the largest joint error that counts as progress, rad.
pub const STALL_PROGRESS: f64 = 0.001;
/// A joint motion has arrived once every joint is within its tolerance and at rest: measured
/// slower than this, rad/s (above the velocity reading's quantum, 0.024 rad/s, and its noise).
/// A joint within tolerance may still be moving (the servo's last creep against its gear
/// friction): returning then would leave the arm moving on.
pub const ARRIVAL_SPEED: f64 = 0.05;

pub(crate) enum Goal {
    /// Joints (firmware indices) to reach targets within a tolerance.
    Joints {
        idx: Vec<usize>,
        target: Vec<f64>,
        tolerance: f64,
        /// Best (smallest) worst-joint error so far, and when it was reached.
        stall_since: Option<(f64, Duration)>,
    },
    /// The gripper reaching one of these states.
    Gripper(&'static [GripperState]),
    /// A base velocity held until a time.
    BaseVelocity {
        v: f64,
        w: f64,
        until: Duration,
        next_send: Duration,
    },
    /// A base position goal run by a host-side controller.
    Base(Box<dyn BaseLaw>),
    /// A base reference tracked by LQR (closed loop) or played open loop.
    Track(Box<crate::base::Tracking>),
}

/// A motion under way.
#[must_use = "a motion does nothing unless waited on or polled"]
pub struct Motion<'r> {
    pub(crate) robot: &'r mut Robot,
    pub(crate) goal: Goal,
    pub(crate) what: String,
    pub(crate) deadline: Duration,
    pub(crate) started: Duration,
    pub(crate) timeout: Duration,
    pub(crate) result: Option<Result<()>>,
}

impl<'r> Motion<'r> {
    pub(crate) fn new(
        robot: &'r mut Robot,
        goal: Goal,
        what: impl Into<String>,
        timeout: Duration,
    ) -> Self {
        let started = robot.link.now();
        // Timeouts are validated at the API (`validate::timeout`); saturate all the same.
        let deadline = started.saturating_add(timeout);
        Motion {
            started,
            robot,
            goal,
            what: what.into(),
            deadline,
            timeout,
            result: None,
        }
    }

    /// Whether it has finished (successfully or not).
    pub fn is_finished(&self) -> bool {
        self.result.is_some()
    }

    /// Let [`POLL`] pass and check; `Some(result)` once finished.
    pub fn poll(&mut self) -> Option<&Result<()>> {
        if self.result.is_none() {
            self.robot.link.wait(POLL);
            let r = self.check();
            if let Some(r) = r {
                if r.is_err() {
                    self.halt();
                }
                self.result = Some(r);
            }
        }
        self.result.as_ref()
    }

    /// Block until finished.
    pub fn wait(mut self) -> Result<()> {
        // Check first: a motion may be finished before any time passes.
        if self.result.is_none() {
            if let Some(r) = self.check() {
                self.result = Some(r);
            }
        }
        loop {
            if let Some(r) = self.result.take() {
                return r;
            }
            self.poll();
        }
    }

    /// Stop the motion where it is: joints hold, the base stops.
    pub fn cancel(mut self) -> Result<()> {
        self.halt();
        Ok(())
    }

    fn halt(&mut self) {
        let msg = match &self.goal {
            Goal::Joints { idx, .. } => HostMsg::ClearQueue {
                joints: idx.iter().fold(0, |m, &j| m | (1 << j)),
            },
            Goal::BaseVelocity { .. } | Goal::Base(_) | Goal::Track(_) => HostMsg::BaseVelocity {
                v: 0.0,
                w: 0.0,
                duration_ms: 0,
            },
            _ => return,
        };
        let _ = self.robot.link.command(&msg, "stop");
    }

    fn fault_error(&mut self) -> Option<Error> {
        let joints: Vec<usize> = match &self.goal {
            Goal::Joints { idx, .. } => idx.clone(),
            _ => Vec::new(),
        };
        let base = matches!(
            self.goal,
            Goal::BaseVelocity { .. } | Goal::Base(_) | Goal::Track(_)
        );
        for f in self.robot.link.take_faults() {
            let hit = match f.kind {
                FaultKind::Bumper
                | FaultKind::Cliff
                | FaultKind::WheelDrop
                | FaultKind::BaseLost => base,
                FaultKind::ServoLost | FaultKind::ServoHardware => {
                    f.joint.is_some_and(|j| joints.contains(&(j as usize)))
                }
                FaultKind::Watchdog => true,
                FaultKind::EmergencyStop => return Some(Error::EmergencyStop),
                _ => false,
            };
            if hit {
                let detail = match f.kind {
                    FaultKind::Bumper | FaultKind::Cliff | FaultKind::WheelDrop => {
                        Some(sensor_names(f.code))
                    }
                    _ => f
                        .joint
                        .and_then(|j| self.robot.cfg.joints.get(j as usize))
                        .map(|j| {
                            format!(
                                "joint {} (servo {}), code {:#04x}",
                                j.name.as_str(),
                                j.servo_id,
                                f.code
                            )
                        }),
                };
                return Some(Error::Fault {
                    kind: f.kind,
                    detail,
                });
            }
        }
        None
    }

    /// One check of the goal; `Some` once finished.
    pub(crate) fn check(&mut self) -> Option<Result<()>> {
        if let Some(e) = self.fault_error() {
            return Some(Err(e));
        }
        let now = self.robot.link.now();
        let t = match self.robot.link.telemetry() {
            Ok(t) => t,
            Err(e) => return Some(Err(e)),
        };
        self.robot.log_wheels(&t);
        let timed_out = now >= self.deadline;
        match &mut self.goal {
            Goal::Joints {
                idx,
                target,
                tolerance,
                stall_since,
            } => {
                let mut worst = (0usize, 0.0f64);
                let mut at_rest = true;
                for (&j, &q) in idx.iter().zip(target.iter()) {
                    let s = t.joints.get(j).copied().unwrap_or_default();
                    let e = (s.position as f64 - q).abs();
                    if e > worst.1 {
                        worst = (j, e);
                    }
                    at_rest &= (s.velocity as f64).abs() < ARRIVAL_SPEED;
                }
                if worst.1 <= *tolerance && at_rest && t.queued == 0 {
                    return Some(Ok(()));
                }
                // Stalled: past the start of the motion, the largest joint error has not
                // improved by STALL_PROGRESS for STALL_TIME (a blocked joint, or a trajectory
                // that ended short of its target). Progress, not speed readings, so that noise
                // on a joint pressed against an obstacle does not hide the stall.
                let (best, at) = *stall_since.get_or_insert((worst.1, now));
                if worst.1 < best - STALL_PROGRESS {
                    *stall_since = Some((worst.1, now));
                } else if now > self.started + STALL_GRACE && now - at > STALL_TIME {
                    let cfg = &self.robot.cfg.joints;
                    let joint = cfg
                        .get(worst.0)
                        .map(|j| j.name.to_string())
                        .unwrap_or_default();
                    let position = t
                        .joints
                        .get(worst.0)
                        .map(|s| s.position as f64)
                        .unwrap_or(0.0);
                    return Some(Err(Error::Stalled {
                        joint,
                        position,
                        error: worst.1,
                    }));
                }
                timed_out.then(|| Err(self.timeout_error()))
            }
            Goal::Gripper(want) => {
                if want.contains(&t.gripper) {
                    Some(Ok(()))
                } else {
                    timed_out.then(|| Err(self.timeout_error()))
                }
            }
            Goal::BaseVelocity {
                v,
                w,
                until,
                next_send,
            } => {
                if now >= *until {
                    self.stop_base();
                    return Some(Ok(()));
                }
                if now >= *next_send {
                    *next_send = now + Duration::from_millis(100);
                    let left = (*until - now).as_millis().min(250) as u16;
                    let (v, w) = (*v, *w);
                    return self.send_base_velocity(v, w, left);
                }
                None
            }
            Goal::Track(tr) => {
                if timed_out {
                    return Some(Err(self.timeout_error()));
                }
                match tr.step(now, &t) {
                    None => {
                        self.stop_base();
                        Some(Ok(()))
                    }
                    Some(None) => None,
                    Some(Some((v, w))) => {
                        self.robot.base_log.push((now.as_secs_f64(), v, w));
                        self.send_base_velocity(v, w, 200)
                    }
                }
            }
            Goal::Base(g) => {
                if timed_out {
                    return Some(Err(self.timeout_error()));
                }
                match g.step(now, &t) {
                    // Stop explicitly either way: otherwise the firmware would hold the last
                    // command (up to 250 ms) after the law has declared the goal reached.
                    Err(e) => {
                        self.stop_base();
                        Some(Err(e))
                    }
                    Ok(None) => {
                        self.stop_base();
                        Some(Ok(()))
                    }
                    Ok(Some((v, w))) => {
                        if self.robot.base_log.last().map(|l| (l.1, l.2)) != Some((v, w)) {
                            self.robot.base_log.push((now.as_secs_f64(), v, w));
                        }
                        let hold = g.hold_ms();
                        self.send_base_velocity(v, w, hold)
                    }
                }
            }
        }
    }

    /// Stop the base now (best effort: the motion is over either way).
    fn stop_base(&mut self) {
        let _ = self.robot.link.command(
            &HostMsg::BaseVelocity {
                v: 0.0,
                w: 0.0,
                duration_ms: 0,
            },
            "stop",
        );
    }

    /// Send a base velocity `(v, ω)` (m/s, rad/s) held for `duration_ms`; `Some(Err)` when the
    /// link refuses it, which ends the motion.
    fn send_base_velocity(&mut self, v: f64, w: f64, duration_ms: u16) -> Option<Result<()>> {
        self.robot
            .link
            .command(
                &HostMsg::BaseVelocity {
                    v: v as f32,
                    w: w as f32,
                    duration_ms,
                },
                "base velocity",
            )
            .err()
            .map(Err)
    }

    /// The motion ran out of time.
    fn timeout_error(&self) -> Error {
        Error::Timeout {
            what: self.what.clone(),
            after: self.timeout,
        }
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
