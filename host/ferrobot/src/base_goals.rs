//! The base's goals as the hub steps them: the host-side laws ([`BaseLaw`]: the proportional
//! law, the dynamic window, tracking then finishing) fed with the odometry of each telemetry
//! frame, a velocity held for a time, and a reference tracked; with the commands they send.

use std::time::Duration;

use ferrobot_control::laws::{Finisher, Proportional, Tracking};
use ferrobot_protocol::{HostMsg, Telemetry};

use crate::backend::Link;
use crate::base_control::Dwa;
use crate::error::{Error, Result};
use crate::goals::{Claim, Goal, Step};

/// A host-side position controller run by a [`Motion`] every time the motions are stepped.
pub(crate) trait BaseLaw: Send {
    /// The next command `(v, ω)` (m/s, rad/s) from odometry at `now`, `Ok(None)` when the goal
    /// is reached, or an error when it cannot be.
    fn step(&mut self, now: Duration, t: &Telemetry) -> Result<Option<(f64, f64)>>;

    /// How long (ms) the firmware holds the command `step` just returned before it stops the
    /// base by itself.
    fn hold_ms(&self) -> u16 {
        250
    }
}

/// A law's view of the odometry in telemetry `t`: the pose `[x, y, θ]` (m, m, rad).
pub(crate) fn odometry_pose(t: &Telemetry) -> [f64; 3] {
    let o = t.odometry;
    [o.x as f64, o.y as f64, o.theta as f64]
}

/// A law's view of the odometry's twist in telemetry `t`: `[v, ω]` (m/s, rad/s).
pub(crate) fn odometry_twist(t: &Telemetry) -> [f64; 2] {
    let o = t.odometry;
    [o.v as f64, o.w as f64]
}

impl BaseLaw for Proportional {
    fn step(&mut self, now: Duration, t: &Telemetry) -> Result<Option<(f64, f64)>> {
        Ok(Proportional::step(self, now, odometry_pose(t)))
    }
}

/// A dynamic-window position goal: the window steers to the goal position among the
/// obstacles, then the proportional controller turns to the goal heading.
pub(crate) struct DwaGoal {
    pub(crate) dwa: Dwa,
    pub(crate) finish: Proportional,
    pub(crate) reached: bool,
    pub(crate) next: Duration,
    pub(crate) last: (f64, f64),
    /// Closest distance to the goal so far, m, and when it was last bettered by a centimetre.
    pub(crate) progress: (f64, Duration),
}

/// How long the dynamic window may go without getting 1 cm closer to the goal before the goal
/// is declared unreachable (a local minimum, or boxed in).
pub(crate) const DWA_NO_PROGRESS: Duration = Duration::from_secs(8);

/// Extra clearance (m) the global path keeps from obstacles beyond the footprint radius, so the
/// window can follow it at speed and still be able to brake.
pub(crate) const DWA_PATH_MARGIN: f64 = 0.1;

/// Within this distance of the goal (m) the dynamic window hands over to the proportional
/// controller, which drives the last stretch straight and turns to the goal heading. The
/// stretch starts inside the footprint the robot will occupy at the goal (both footprint radii
/// exceed it), which the caller's goal must leave free anyway.
pub(crate) const DWA_HANDOVER: f64 = 0.1;

impl BaseLaw for DwaGoal {
    fn step(&mut self, now: Duration, t: &Telemetry) -> Result<Option<(f64, f64)>> {
        if self.reached {
            return Ok(self.finish.step(now, odometry_pose(t)));
        }
        if now < self.next {
            return Ok(Some(self.last));
        }
        self.next = now + Duration::from_secs_f64(self.dwa.dt);
        let x = odometry_pose(t);
        let dist = (self.dwa.goal[0] - x[0]).hypot(self.dwa.goal[1] - x[1]);
        if dist < self.progress.0 - 0.01 {
            self.progress = (dist, now);
        } else if now.saturating_sub(self.progress.1) > DWA_NO_PROGRESS {
            return Err(Error::Unreachable {
                why: format!(
                    "the dynamic window made no progress for {DWA_NO_PROGRESS:?}, {dist:.3} m from the goal"
                ),
            });
        }
        if dist < DWA_HANDOVER {
            self.reached = true;
            self.finish.take_over(now, self.last);
            return Ok(self.finish.step(now, x));
        }
        // The window is built around what was commanded (odometry velocity lags it).
        let (v0, w0) = self.last;
        match self.dwa.command(x, v0, w0) {
            Some(u) => {
                self.last = u;
                Ok(Some(u))
            }
            None => Err(Error::Unreachable {
                why: format!(
                    "the dynamic window found no collision-free velocity at [{:.3}, {:.3}, {:.3}]",
                    x[0], x[1], x[2]
                ),
            }),
        }
    }
}

/// Closed-loop tracking, then the [`Finisher`].
pub(crate) struct TrackThenFinish {
    pub(crate) track: Tracking,
    pub(crate) tracking: bool,
    pub(crate) last: (f64, f64),
    pub(crate) finish: Finisher,
}

impl BaseLaw for TrackThenFinish {
    fn step(&mut self, now: Duration, t: &Telemetry) -> Result<Option<(f64, f64)>> {
        if self.tracking {
            match self.track.step(now, odometry_pose(t)) {
                Some(Some(u)) => {
                    self.last = u;
                    return Ok(Some(u));
                }
                Some(None) => return Ok(Some(self.last)),
                None => {
                    self.tracking = false;
                    self.finish.take_over(self.last);
                }
            }
        }
        Ok(self.finish.step(now, odometry_pose(t), odometry_twist(t)))
    }

    fn hold_ms(&self) -> u16 {
        if self.tracking {
            250
        } else {
            self.finish.hold_ms()
        }
    }
}

/// Stop the base now (best effort: the motion is over either way).
pub(crate) fn stop_base(link: &mut dyn Link) {
    let _ = link.command(
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
pub(crate) fn send_base_velocity(
    link: &mut dyn Link,
    v: f64,
    w: f64,
    duration_ms: u16,
) -> Option<Result<()>> {
    link.command(
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

/// Send a base velocity `(v, ω)` held for `duration_ms` from a goal's step, noting it in the
/// base's command log when it differs from the last one noted.
pub(crate) fn send_logged(
    s: &mut Step<'_>,
    v: f64,
    w: f64,
    duration_ms: u16,
) -> Option<Result<()>> {
    if s.base_log.last().map(|l| (l.1, l.2)) != Some((v, w)) {
        s.base_log.push((s.now.as_secs_f64(), v, w));
    }
    send_base_velocity(s.link, v, w, duration_ms)
}

/// What every base goal claims.
pub(crate) const BASE: Claim = Claim {
    joints: 0,
    base: true,
    gripper: false,
};

/// A base velocity held until a time.
pub(crate) struct VelocityGoal {
    pub(crate) v: f64,
    pub(crate) w: f64,
    pub(crate) until: Duration,
    pub(crate) next_send: Duration,
}

impl Goal for VelocityGoal {
    fn claim(&self) -> Claim {
        BASE
    }

    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>> {
        let now = s.now;
        if now >= self.until {
            stop_base(s.link);
            return Some(Ok(()));
        }
        if now >= self.next_send {
            self.next_send = now + Duration::from_millis(100);
            let horizon = s.link.command_horizon().as_millis();
            let left = (self.until - now)
                .as_millis()
                .min(horizon)
                .min(u16::MAX.into()) as u16;
            return send_base_velocity(s.link, self.v, self.w, left);
        }
        None
    }

    fn halt(&mut self, link: &mut dyn Link) {
        stop_base(link);
    }
}

/// A base position goal run by a host-side law.
pub(crate) struct LawGoal(pub(crate) Box<dyn BaseLaw>);

impl Goal for LawGoal {
    fn claim(&self) -> Claim {
        BASE
    }

    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>> {
        match self.0.step(s.now, s.telemetry) {
            // Stop explicitly either way: otherwise the firmware would hold the last command
            // (up to 250 ms) after the law has declared the goal reached.
            Err(e) => {
                stop_base(s.link);
                Some(Err(e))
            }
            Ok(None) => {
                stop_base(s.link);
                Some(Ok(()))
            }
            Ok(Some((v, w))) => send_logged(s, v, w, self.0.hold_ms()),
        }
    }

    fn halt(&mut self, link: &mut dyn Link) {
        stop_base(link);
    }
}

/// A base reference tracked by LQR (closed loop) or played open loop.
pub(crate) struct TrackGoal(pub(crate) Box<Tracking>);

impl Goal for TrackGoal {
    fn claim(&self) -> Claim {
        BASE
    }

    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>> {
        match self.0.step(s.now, odometry_pose(s.telemetry)) {
            None => {
                stop_base(s.link);
                Some(Ok(()))
            }
            Some(None) => None,
            Some(Some((v, w))) => {
                s.base_log.push((s.now.as_secs_f64(), v, w));
                send_base_velocity(s.link, v, w, 200)
            }
        }
    }

    fn halt(&mut self, link: &mut dyn Link) {
        stop_base(link);
    }
}
