//! The hub: the link to the firmware, the goal table and the sensing that time feeds, under the
//! robot's one lock. Whoever lets time pass pumps it ([`Hub::pump`]): the link advances, every
//! goal under way takes its step, and the telemetry and the camera's due frame reach their
//! subscribers (SLAM, the obstacle layer, [`crate::subscription`]s).

use std::time::Duration;

use ferrobot_protocol::{HostMsg, JointMode, JointPoint};

use crate::backend::device::CameraDevice;
use crate::backend::{Link, LinkEvent};
use crate::base_state::BaseState;
use crate::config::RobotConfig;
use crate::error::{Error, Result};
use crate::goals::{fault_error, Claim, Goal, Goals, Running, Step, FAULT_QUEUE, LINK_EVENT_QUEUE};

/// The link and what changes with it: the goals under way and each component's state.
pub(crate) struct Hub {
    /// The link to the firmware.
    pub(crate) link: Box<dyn Link>,
    /// The goals under way, their results, the faults.
    pub(crate) goals: Goals,
    /// The base's state.
    pub(crate) base: BaseState,
    /// The RGB-D camera, when the robot has and uses one.
    pub(crate) camera: Option<Box<dyn CameraDevice>>,
    /// SLAM beside the robot, once started.
    pub(crate) slam: Option<crate::slam_runner::SlamRunner>,
    /// What the camera and SLAM tell the base's goals.
    pub(crate) sense: crate::sense::Sense,
    /// The streams users subscribe to.
    pub(crate) streams: crate::sensing::Streams,
}

impl Hub {
    /// Switch joints to a mode.
    pub(crate) fn set_mode(&mut self, joints: &[usize], mode: JointMode) -> Result<()> {
        let mask = crate::goals::joint_mask(joints.iter().copied());
        self.link
            .command(&HostMsg::SetMode { joints: mask, mode }, "mode change")
    }

    /// Queue one trajectory knot at rest (zero velocity and effort) for the joints in `mask`,
    /// at `positions` (rad, lowest joint first), `seconds` after the previous knot.
    pub(crate) fn send_rest_waypoint(
        &mut self,
        mask: u16,
        positions: impl IntoIterator<Item = f64>,
        seconds: f64,
        what: &str,
    ) -> Result<()> {
        let points = positions
            .into_iter()
            .map(|p| JointPoint::at_rest(p as f32))
            .collect();
        self.link.command(
            &HostMsg::Waypoint {
                joints: mask,
                duration_us: (seconds * 1e6) as u32,
                points,
            },
            what,
        )
    }
}

impl Hub {
    /// Collect the link's events and faults. A link lost ends every goal under way with
    /// [`Error::Link`] (a reconnection is a new session: nothing from before it goes on); each
    /// goal a fault hits ends with its error. Both are kept for [`Robot::take_link_events`]
    /// and [`Robot::take_faults`].
    pub(crate) fn collect_faults(&mut self, cfg: &RobotConfig) {
        let events = self.link.take_events();
        let faults = self.link.take_faults();
        self.publish_events(&events, &faults);
        for e in events {
            if let LinkEvent::Lost { why } = &e {
                let why = format!("{why} (reconnecting)");
                self.end_where(|_| true, |_| Error::Link(why.clone()));
            }
            if self.goals.link_events.len() >= LINK_EVENT_QUEUE {
                self.goals.link_events.pop_front();
            }
            self.goals.link_events.push_back(e);
        }
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

    /// Publishes link events and faults on the events' stream, stamped now.
    fn publish_events(&mut self, events: &[LinkEvent], faults: &[ferrobot_protocol::Fault]) {
        if events.is_empty() && faults.is_empty() {
            return;
        }
        let mut stream = self.streams.events.lock();
        if !stream.wanted() {
            return;
        }
        let time = self.link.now();
        for e in events {
            stream.publish(crate::events::Event::Link {
                time,
                event: e.clone(),
            });
        }
        for &fault in faults {
            stream.publish(crate::events::Event::Fault { time, fault });
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

    /// Put a goal under way (after [`Hub::prepare`] and its first commands); it may take
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
            let id = g.id;
            match r {
                None => i += 1,
                // A command the firmware refused because of a fault it reported first (a base
                // lost, then its drive refused as unsafe): the goal ends with the fault, its
                // cause, as it would had the fault been read a step earlier. The fault is on
                // the wire before the refusal, so it is with the link already.
                Some(Err(e @ Error::Rejected { .. })) => {
                    self.collect_faults(cfg);
                    if let Some(k) = self.goals.running.iter().position(|g| g.id == id) {
                        let mut g = self.goals.running.remove(k);
                        g.goal.halt(self.link.as_mut());
                        self.goals.finish(g.id, Err(e));
                    }
                    // The faults may have ended goals before this one: look again (those
                    // stepped at this instant are passed over).
                    i = 0;
                }
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
        self.publish_telemetry();
        self.feed_camera();
    }

    /// Stop every goal under way where it is; each ends with [`Error::Cancelled`].
    pub(crate) fn cancel_all(&mut self) {
        for mut g in std::mem::take(&mut self.goals.running) {
            g.goal.halt(self.link.as_mut());
            self.goals.finish(g.id, Err(Error::Cancelled));
        }
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
