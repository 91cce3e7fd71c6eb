//! The mobile base: velocity commands, position goals, odometry. Poses are `[x, y, θ]` (m, m,
//! rad) in the odometry frame (x forward at the last odometry reset, y left, θ counter-
//! clockwise). A bumper, cliff or wheel-drop event aborts a motion with an error that names the
//! sensor.

use std::collections::VecDeque;
use std::time::Duration;

use ferrobot_protocol::{HostMsg, Telemetry};

use crate::base_control::{ilqr, wrap, Dwa, Limits, LqrTracker, NavField, Reference};
use crate::config::BaseController;
use crate::error::{check_finite, Error, Result};
use crate::validate;
use ferrobot_geometry::Pose2;

/// A relative base goal: finite, at most [`validate::MAX_BASE_GOAL_DISTANCE`] away, a turn
/// within ±[`validate::MAX_ANGLE`].
fn check_relative(delta: [f64; 3]) -> Result<()> {
    check_finite("base goal", &delta)?;
    validate::in_range(
        "base goal distance",
        delta[0].hypot(delta[1]),
        0.0,
        validate::MAX_BASE_GOAL_DISTANCE,
    )?;
    Ok(validate::angles("base goal heading", &delta[2..])?)
}
use crate::backend::Link;
use crate::config::RobotConfig;
use crate::motion::{Claim, Goal, Motion, Step};
use crate::navigate::NavGoal;
use crate::obstacles::{Circle, Obstacles, OccupancyGrid};
use crate::odometry_calibration::WheelGeometry;
use crate::robot::{Io, Robot};
use crate::slam::Source;
use ferrobot_nav::{NavSettings, Navigator};

/// Control period of the host-side base controllers.
pub const BASE_CONTROL_PERIOD: Duration = Duration::from_millis(50);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    TurnToGoal,
    Drive,
    TurnToHeading,
}

/// The proportional position controller, as PyRobot's: turn towards the goal, drive to it
/// (backwards when it lies behind), turn to the goal heading. Speeds are proportional to the
/// remaining error, bounded by the limits, ramped at bounded acceleration, and kept above the
/// base's deadband until within tolerance.
#[derive(Debug, Clone)]
pub struct BaseGoal {
    goal: [f64; 3],
    phase: Phase,
    backwards: bool,
    v: f64,
    w: f64,
    next: Duration,
    max_v: f64,
    max_w: f64,
    min_w: f64,
    tol_xy: f64,
    tol_th: f64,
}

/// Gains and limits of the proportional controller.
pub mod gains {
    /// Forward speed per metre of remaining distance, 1/s.
    pub const K_V: f64 = 1.0;
    /// Yaw rate per radian of heading error, 1/s.
    pub const K_W: f64 = 2.0;
    /// Forward acceleration bound, m/s².
    pub const ACCEL_V: f64 = 0.5;
    /// Yaw acceleration bound, rad/s².
    pub const ACCEL_W: f64 = 2.0;
    /// Smallest forward speed while not yet within tolerance, m/s.
    pub const MIN_V: f64 = 0.02;
    /// Smallest wheel speed while turning and not yet within tolerance, m/s: above the
    /// deadband of the bases' wheel controllers (Kobuki 5 mm/s, Create 2 10 mm/s).
    pub const MIN_WHEEL: f64 = 0.015;
}

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

impl BaseLaw for BaseGoal {
    fn step(&mut self, now: Duration, t: &Telemetry) -> Result<Option<(f64, f64)>> {
        Ok(self.step_inner(now, t))
    }
}

impl BaseGoal {
    /// Heading error (rad) from `th` to the direction of driving towards the goal offset
    /// `(dx, dy)`: its bearing, or the opposite when driving backwards.
    fn drive_heading_error(&self, dx: f64, dy: f64, th: f64) -> f64 {
        let back = if self.backwards {
            std::f64::consts::PI
        } else {
            0.0
        };
        wrap(dy.atan2(dx) + back - th)
    }

    /// Aims at `goal` (the odometry's frame) from `now` on, keeping the present speeds.
    pub(crate) fn retarget(&mut self, goal: [f64; 3], now: Duration) {
        self.goal = goal;
        self.phase = Phase::TurnToGoal;
        self.next = now;
    }

    pub(crate) fn step_inner(&mut self, now: Duration, t: &Telemetry) -> Option<(f64, f64)> {
        if now < self.next {
            return Some((self.v, self.w));
        }
        self.next = now + BASE_CONTROL_PERIOD;
        let dt = BASE_CONTROL_PERIOD.as_secs_f64();
        let o = t.odometry;
        let (x, y, th) = (o.x as f64, o.y as f64, o.theta as f64);
        let (dx, dy) = (self.goal[0] - x, self.goal[1] - y);
        let dist = dx.hypot(dy);
        let mut v = 0.0;
        let w;
        loop {
            match self.phase {
                Phase::TurnToGoal => {
                    if dist < self.tol_xy {
                        self.phase = Phase::TurnToHeading;
                        continue;
                    }
                    self.backwards = wrap(dy.atan2(dx) - th).abs() > std::f64::consts::FRAC_PI_2;
                    let e = self.drive_heading_error(dx, dy, th);
                    if e.abs() < self.tol_th {
                        self.phase = Phase::Drive;
                        continue;
                    }
                    let p = (gains::K_W * e).clamp(-self.max_w, self.max_w);
                    w = p.signum() * p.abs().max(self.min_w);
                }
                Phase::Drive => {
                    let e = self.drive_heading_error(dx, dy, th);
                    // Distance along the heading; past the goal it turns negative.
                    let along = dist * e.cos();
                    if dist < self.tol_xy {
                        self.phase = Phase::TurnToHeading;
                        continue;
                    }
                    if along < 0.0 {
                        // Passed wide of the tolerance (an overshoot, a slip, a push): aim at
                        // the goal again (backwards when it lies behind), never call it reached.
                        self.phase = Phase::TurnToGoal;
                        continue;
                    }
                    let speed = (gains::K_V * along).clamp(gains::MIN_V, self.max_v);
                    v = if self.backwards { -speed } else { speed };
                    w = (gains::K_W * e).clamp(-self.max_w, self.max_w);
                }
                Phase::TurnToHeading => {
                    let e = wrap(self.goal[2] - th);
                    if e.abs() < self.tol_th {
                        self.v = 0.0;
                        self.w = 0.0;
                        return None;
                    }
                    let p = (gains::K_W * e).clamp(-self.max_w, self.max_w);
                    w = p.signum() * p.abs().max(self.min_w);
                }
            }
            break;
        }
        // Ramp: bounded acceleration (braking to zero is never slower than the bound either).
        self.v += (v - self.v).clamp(-gains::ACCEL_V * dt, gains::ACCEL_V * dt);
        self.w += (w - self.w).clamp(-gains::ACCEL_W * dt, gains::ACCEL_W * dt);
        Some((self.v, self.w))
    }
}

/// A [`Dwa`] position goal: the window steers to the goal position among the obstacles, then
/// the proportional controller turns to the goal heading.
struct DwaGoal {
    dwa: Dwa,
    finish: BaseGoal,
    reached: bool,
    next: Duration,
    last: (f64, f64),
    /// Closest distance to the goal so far, m, and when it was last bettered by a centimetre.
    progress: (f64, Duration),
}

/// How long the dynamic window may go without getting 1 cm closer to the goal before the goal
/// is declared unreachable (a local minimum, or boxed in).
const DWA_NO_PROGRESS: Duration = Duration::from_secs(8);

/// Extra clearance (m) the global path keeps from obstacles beyond the footprint radius, so the
/// window can follow it at speed and still be able to brake.
const DWA_PATH_MARGIN: f64 = 0.1;

/// Within this distance of the goal (m) the dynamic window hands over to the proportional
/// controller, which drives the last stretch straight and turns to the goal heading. The
/// stretch starts inside the footprint the robot will occupy at the goal (both footprint radii
/// exceed it), which the caller's goal must leave free anyway.
const DWA_HANDOVER: f64 = 0.1;

impl BaseLaw for DwaGoal {
    fn step(&mut self, now: Duration, t: &Telemetry) -> Result<Option<(f64, f64)>> {
        if self.reached {
            return Ok(self.finish.step_inner(now, t));
        }
        if now < self.next {
            return Ok(Some(self.last));
        }
        self.next = now + Duration::from_secs_f64(self.dwa.dt);
        let o = t.odometry;
        let x = [o.x as f64, o.y as f64, o.theta as f64];
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
            self.finish.next = now;
            self.finish.v = self.last.0;
            self.finish.w = self.last.1;
            return Ok(self.finish.step_inner(now, t));
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

/// Longest the [`Finish`] stage may add to a motion's timeout.
const FINISH_TIME: Duration = Duration::from_secs(30);

/// Residual position error (m) along the heading that the finisher leaves.
pub const FINISH_TOL_XY: f64 = 0.0005;
/// Residual position error (m) across the heading above which the finisher backs up and
/// re-approaches.
pub const FINISH_TOL_LATERAL: f64 = 0.0005;
/// Residual heading error (rad) that the finisher aims for (0.05°), unless the odometry's
/// resolution is coarser (see [`Finish`]).
pub const FINISH_TOL_TH: f64 = 0.05 * std::f64::consts::PI / 180.0;
/// How far (m) the finisher backs up before re-approaching to remove a lateral error.
const FINISH_BACKUP: f64 = 0.05;
/// Lateral re-approaches the finisher tries before it settles for what it has.
const FINISH_ATTEMPTS: u32 = 3;
/// The finisher's speed caps (m/s, rad/s) and its proportional gain (1/s).
const FINISH_V_MAX: f64 = 0.05;
const FINISH_W_MAX: f64 = 0.3;
const FINISH_GAIN: f64 = 1.5;
/// Errors a creep-speed pulse of up to this long (s) would cover are removed by pulses.
const FINISH_PULSE_SPAN: f64 = 0.5;
/// First guess of the wheels' dead time (s): a pulse of length T at creep speed moves about
/// speed · (T − dead time). Learned from every pulse.
const FINISH_DEAD_TIME: f64 = 0.05;

/// One step of the finisher's plan.
#[derive(Debug, Clone, Copy, PartialEq)]
enum FinishStep {
    /// Look at the remaining error and plan the next steps.
    Decide,
    /// Drive straight along the current heading until the point's projection on it is
    /// within `tol` (m).
    Drive { to: [f64; 2], tol: f64 },
    /// Turn in place to face the goal position (or away from it, whichever is nearer).
    Face,
    /// Turn in place to the heading (rad).
    Turn { to: f64 },
}

/// A creep-speed pulse the firmware times.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pulse {
    end: Duration,
    cmd: (f64, f64),
    /// The error (m or rad) when it started.
    e0: f64,
    speed: f64,
    /// Its length, s.
    len: f64,
    /// Whether the stop after it has been commanded.
    stopped: bool,
}

/// A command of the finisher: `(v, ω)`, how long the firmware holds it (ms), and whether it
/// is ramped within the accelerations.
#[derive(Debug, Clone, Copy, PartialEq)]
struct FinishCmd {
    u: (f64, f64),
    hold_ms: u16,
    ramp: bool,
}

impl FinishCmd {
    const STOP: FinishCmd = FinishCmd {
        u: (0.0, 0.0),
        hold_ms: 250,
        ramp: false,
    };
}

/// The finisher after closed-loop tracking (our deadband compensation): the LQR's feedback
/// on millimetre errors asks for wheel speeds below the wheels' deadband, which do nothing.
/// Checked at every odometry sample (50 Hz), it removes the error by odometry in straight
/// drives and turns in place: an error across the heading above [`FINISH_TOL_LATERAL`] by
/// backing up [`FINISH_BACKUP`], facing the goal and driving to it; the error along the
/// heading to [`FINISH_TOL_XY`]; then the heading to [`FINISH_TOL_TH`] or, when one encoder
/// tick turns the odometry by more than twice that, to 0.55 tick (the Create 2: 0.06°).
/// Large errors are driven at speeds proportional to them, ramped within the tracking
/// accelerations; small ones by pulses at creep speed (`[base] min_wheel_speed`, just above
/// the deadband and below one tracking period's acceleration) whose length the firmware
/// times to the millisecond, corrected for the wheels' dead time, which each pulse measures;
/// the last heading pulses pivot about one wheel so that the odometry can change by a single
/// encoder tick. It waits for the base to stand still before each pulse and after each step.
#[derive(Debug, Clone)]
struct Finish {
    goal: [f64; 3],
    v_min: f64,
    w_min: f64,
    /// Odometry heading change of one encoder tick of one wheel, rad.
    tick: f64,
    limits: Limits,
    /// The last command, when it was sent, and its hold.
    last: (f64, f64),
    last_t: Option<Duration>,
    hold_ms: u16,
    step: FinishStep,
    /// Steps after the current one.
    plan: VecDeque<FinishStep>,
    attempts: u32,
    pulse: Option<Pulse>,
    /// Learned dead time (s) of linear and angular pulses.
    dead_time: [f64; 2],
}

impl Finish {
    /// A finisher to `goal` with creep speeds `v_min` (m/s) and `w_min` (rad/s), for
    /// odometry whose heading changes by `tick` (rad) per encoder tick.
    fn new(goal: [f64; 3], v_min: f64, w_min: f64, tick: f64, limits: Limits) -> Self {
        Finish {
            goal,
            v_min,
            w_min,
            tick,
            limits,
            last: (0.0, 0.0),
            last_t: None,
            hold_ms: 250,
            step: FinishStep::Decide,
            plan: VecDeque::new(),
            attempts: 0,
            pulse: None,
            dead_time: [FINISH_DEAD_TIME; 2],
        }
    }

    /// The heading tolerance (rad): [`FINISH_TOL_TH`], or 0.55 tick where one encoder tick
    /// turns the odometry by more than twice that.
    fn tol_th(&self) -> f64 {
        FINISH_TOL_TH.max(0.55 * self.tick)
    }

    /// The next command, `None` when done.
    fn step(&mut self, now: Duration, t: &Telemetry) -> Option<(f64, f64)> {
        let c = self.want(now, t)?;
        let (v, w) = if c.ramp {
            // Ramp within the accelerations, over the time since the last command (at most
            // one tracking period).
            let dt = self
                .last_t
                .map_or(0.1, |l| now.saturating_sub(l).as_secs_f64().min(0.1));
            let l = &self.limits;
            (
                self.last.0 + (c.u.0 - self.last.0).clamp(-l.accel_v * dt, l.accel_v * dt),
                self.last.1 + (c.u.1 - self.last.1).clamp(-l.accel_w * dt, l.accel_w * dt),
            )
        } else {
            c.u
        };
        self.last = (v, w);
        self.last_t = Some(now);
        self.hold_ms = c.hold_ms;
        Some((v, w))
    }

    /// Creep towards a signed error `e` (m along the heading, or rad) within `tol`; `None`
    /// once within it and standing still. Angular pulses within 1.5 ticks of the goal pivot
    /// about one wheel, so that one encoder tick at a time can change (turning in place moves both, a two-tick step
    /// that can jump over the tolerance); `pivot_forward` picks the wheel: the base's centre
    /// then moves forward (true) or back by half the track times the turn.
    fn creep(
        &mut self,
        now: Duration,
        e: f64,
        tol: f64,
        angular: Option<bool>,
        still: bool,
    ) -> Option<FinishCmd> {
        let k = angular.is_some() as usize;
        let (speed, cap) = if angular.is_some() {
            (self.w_min, FINISH_W_MAX)
        } else {
            (self.v_min, FINISH_V_MAX)
        };
        let axis = |s: f64| match angular {
            Some(_) => (0.0, s),
            None => (s, 0.0),
        };
        if let Some(p) = self.pulse {
            if now < p.end {
                let left = (p.end - now).as_millis().clamp(1, 1000) as u16;
                return Some(FinishCmd {
                    u: p.cmd,
                    hold_ms: left,
                    ramp: false,
                });
            }
            // The firmware has stopped the base at the pulse's end; say so on the command
            // stream too, and wait for it to stand still.
            if !still || !p.stopped {
                self.pulse = Some(Pulse { stopped: true, ..p });
                return Some(FinishCmd::STOP);
            }
            // moved = speed · (len − dead time).
            let moved = (p.e0 - e) * p.e0.signum();
            let dead = (p.len - moved / p.speed).clamp(0.0, 0.2);
            self.dead_time[k] = 0.5 * (self.dead_time[k] + dead);
            self.pulse = None;
        }
        if e.abs() <= tol {
            return (!still).then_some(FinishCmd::STOP);
        }
        if e.abs() > speed * FINISH_PULSE_SPAN {
            let s = (FINISH_GAIN * e.abs()).clamp(speed, cap);
            return Some(FinishCmd {
                u: axis(e.signum() * s),
                hold_ms: 250,
                ramp: true,
            });
        }
        if !still {
            return Some(FinishCmd::STOP);
        }
        let (speed, cmd) = match angular {
            // Within 1.5 ticks: one wheel at creep speed, the other still (ω = ±w_min / 2,
            // v = ±v_min / 2); the centre moves by at most 0.75 tick of wheel travel.
            Some(forward) if e.abs() <= 1.5 * self.tick => {
                let w = 0.5 * self.w_min;
                let v = if forward { 0.5 } else { -0.5 } * self.v_min;
                (w, (v, e.signum() * w))
            }
            _ => (speed, axis(e.signum() * speed)),
        };
        let len = (e.abs() / speed + self.dead_time[k]).clamp(0.001, 1.0);
        self.pulse = Some(Pulse {
            end: now + Duration::from_secs_f64(len),
            cmd,
            e0: e,
            speed,
            len,
            stopped: false,
        });
        Some(FinishCmd {
            u: cmd,
            hold_ms: (len * 1000.0).round().max(1.0) as u16,
            ramp: false,
        })
    }

    /// The command the current step wants; `None` when done.
    fn want(&mut self, now: Duration, t: &Telemetry) -> Option<FinishCmd> {
        let o = t.odometry;
        let (x, y, th) = (o.x as f64, o.y as f64, o.theta as f64);
        let still = (o.v as f64).abs() < 1e-3 && (o.w as f64).abs() < 1e-2;
        let (c, s) = (th.cos(), th.sin());
        // A bounded number of plan changes per sample; each returns or advances.
        for _ in 0..8 {
            match self.step {
                FinishStep::Decide => {
                    let (dx, dy) = (self.goal[0] - x, self.goal[1] - y);
                    let along = dx * c + dy * s;
                    let lateral = -dx * s + dy * c;
                    self.plan.clear();
                    if lateral.abs() > FINISH_TOL_LATERAL && self.attempts < FINISH_ATTEMPTS {
                        // Back up to a point behind the goal on the current heading line,
                        // face the goal, drive to it, look again.
                        self.attempts += 1;
                        let back = along - FINISH_BACKUP;
                        self.step = FinishStep::Drive {
                            to: [x + back * c, y + back * s],
                            tol: 0.002,
                        };
                        self.plan.extend([
                            FinishStep::Face,
                            FinishStep::Drive {
                                to: [self.goal[0], self.goal[1]],
                                tol: FINISH_TOL_XY,
                            },
                            FinishStep::Decide,
                        ]);
                    } else if along.abs() > FINISH_TOL_XY {
                        self.step = FinishStep::Drive {
                            to: [self.goal[0], self.goal[1]],
                            tol: FINISH_TOL_XY,
                        };
                        self.plan.push_back(FinishStep::Decide);
                    } else {
                        self.step = FinishStep::Turn { to: self.goal[2] };
                    }
                }
                FinishStep::Drive { to, tol } => {
                    let along = (to[0] - x) * c + (to[1] - y) * s;
                    match self.creep(now, along, tol, None, still) {
                        Some(cmd) => return Some(cmd),
                        None => self.advance(),
                    }
                }
                FinishStep::Face => {
                    let (dx, dy) = (self.goal[0] - x, self.goal[1] - y);
                    let d = dx.hypot(dy);
                    let mut to = dy.atan2(dx);
                    if wrap(to - th).abs() > std::f64::consts::FRAC_PI_2 {
                        to = wrap(to + std::f64::consts::PI);
                    }
                    // Close enough when driving there leaves less than half the lateral
                    // tolerance.
                    let tol = (0.5 * FINISH_TOL_LATERAL / d.max(1e-9))
                        .min(1.0)
                        .asin()
                        .max(self.tol_th());
                    let forward = dx * c + dy * s >= 0.0;
                    match self.creep(now, wrap(to - th), tol, Some(forward), still) {
                        Some(cmd) => return Some(cmd),
                        None => self.advance(),
                    }
                }
                FinishStep::Turn { to } => {
                    let tol = self.tol_th();
                    let forward = (self.goal[0] - x) * c + (self.goal[1] - y) * s >= 0.0;
                    match self.creep(now, wrap(to - th), tol, Some(forward), still) {
                        Some(cmd) => return Some(cmd),
                        None if self.plan.is_empty() => return None,
                        None => self.advance(),
                    }
                }
            }
        }
        Some(FinishCmd::STOP)
    }

    fn advance(&mut self) {
        self.pulse = None;
        self.step = self.plan.pop_front().unwrap_or(FinishStep::Decide);
    }
}

/// Closed-loop tracking, then the [`Finish`]er.
struct TrackThenFinish {
    track: Tracking,
    tracking: bool,
    last: (f64, f64),
    finish: Finish,
}

impl BaseLaw for TrackThenFinish {
    fn step(&mut self, now: Duration, t: &Telemetry) -> Result<Option<(f64, f64)>> {
        if self.tracking {
            match self.track.step(now, t) {
                Some(Some(u)) => {
                    self.last = u;
                    return Ok(Some(u));
                }
                Some(None) => return Ok(Some(self.last)),
                None => {
                    self.tracking = false;
                    self.finish.last = self.last;
                }
            }
        }
        Ok(self.finish.step(now, t))
    }

    fn hold_ms(&self) -> u16 {
        if self.tracking {
            250
        } else {
            self.finish.hold_ms
        }
    }
}

/// How a position goal is reached.
#[derive(Debug, Clone, PartialEq)]
pub struct GoalOptions {
    /// The controller; the configuration's default when `None`.
    pub controller: Option<BaseController>,
    /// LQR: a smooth (Bézier) reference instead of rotate-drive-rotate.
    pub smooth: bool,
    /// LQR: correct from odometry (true) or play the reference open loop.
    pub close_loop: bool,
    /// Circular obstacles `[x, y, r]` (m) in the odometry frame. With obstacles or a map and no
    /// explicit controller, the dynamic window approach is used.
    pub obstacles: Vec<Circle>,
    /// An occupancy-grid map (in the frame `frame` names). With a map the base is driven by
    /// the navigator ([`ferrobot_nav::Navigator`]: global plan, path following, re-planning,
    /// recovery), the round obstacles stamped into it. The navigator's robot radius is the
    /// base's footprint radius, or the arm's reach ([`crate::Arm::reach`]) when the arm sticks
    /// out further: [`crate::Arm::stow`] folds it in before a long drive.
    pub map: Option<OccupancyGrid>,
    /// The frame of the goal, the map and the obstacles: the odometry's, or SLAM's map (the
    /// base then steers by SLAM's pose; SLAM must be running, see
    /// [`crate::Robot::start_slam`]).
    pub frame: Source,
    /// Plan on SLAM's occupancy grid, refreshed as it grows (PyRobot's `use_map`): the frame
    /// is then SLAM's map, whatever `frame` says, and `map`, when given, is used instead.
    pub use_map: bool,
    /// With a map: avoid what the depth camera sees too (when the robot has a camera).
    pub live_obstacles: bool,
}

impl Default for GoalOptions {
    fn default() -> Self {
        GoalOptions {
            controller: None,
            smooth: false,
            close_loop: true,
            obstacles: Vec::new(),
            map: None,
            frame: Source::Odometry,
            use_map: false,
            live_obstacles: true,
        }
    }
}

/// A reference being tracked: the LQR gains, the clock, and the rate limiter of the commands.
#[derive(Debug, Clone)]
pub struct Tracking {
    tracker: LqrTracker,
    closed_loop: bool,
    start: Option<Duration>,
    next: Duration,
    last: (f64, f64),
    limits: Limits,
}

impl Tracking {
    /// `None` when finished; `Some(None)` to keep waiting; `Some(Some((v, w)))` to send.
    pub(crate) fn step(&mut self, now: Duration, t: &Telemetry) -> Option<Option<(f64, f64)>> {
        let start = *self.start.get_or_insert(now);
        if now < self.next {
            return Some(None);
        }
        let dt = self.tracker.reference.dt;
        // `dt` is validated in `validate::REFERENCE_DT`.
        self.next = now + Duration::from_secs_f64(dt);
        let k = ((now - start).as_secs_f64() / dt).floor() as usize;
        if k >= self.tracker.reference.controls.len() {
            return None;
        }
        let o = t.odometry;
        let [v, w] = self.tracker.control(
            k,
            [o.x as f64, o.y as f64, o.theta as f64],
            self.closed_loop,
        );
        // Limits hold on what is commanded: bound, then rate-limit.
        let l = &self.limits;
        let v = v.clamp(-l.v, l.v);
        let w = w.clamp(-l.w, l.w);
        let v = self.last.0 + (v - self.last.0).clamp(-l.accel_v * dt, l.accel_v * dt);
        let w = self.last.1 + (w - self.last.1).clamp(-l.accel_w * dt, l.accel_w * dt);
        self.last = (v, w);
        Some(Some((v, w)))
    }
}

/// What the base remembers between calls.
#[derive(Debug, Default)]
pub(crate) struct BaseState {
    /// Base commands sent by host-side laws: (time s, v m/s, ω rad/s).
    pub(crate) log: Vec<(f64, f64, f64)>,
    /// While recording: the wheel angles `[left, right]` (rad) of each telemetry frame the
    /// motions have seen, with the frame's firmware time (µs).
    wheel_log: Option<Vec<(u64, [f64; 2])>>,
    /// The geometry the firmware's odometry uses, when set (calibrated).
    odometry: Option<WheelGeometry>,
}

impl BaseState {
    /// The base state of a robot of `cfg`, before its odometry geometry is pushed.
    pub(crate) fn new(_cfg: &RobotConfig) -> Self {
        BaseState::default()
    }

    /// While a wheel log is kept, add the wheel angles of telemetry frame `t` unless it is the
    /// frame logged last.
    pub(crate) fn log_wheels(&mut self, t: &Telemetry) {
        if let Some(log) = &mut self.wheel_log {
            if log.last().map(|l| l.0) != Some(t.time_us) {
                log.push((t.time_us, [t.wheels.left as f64, t.wheels.right as f64]));
            }
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
struct VelocityGoal {
    v: f64,
    w: f64,
    until: Duration,
    next_send: Duration,
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
            let left = (self.until - now).as_millis().min(250) as u16;
            return send_base_velocity(s.link, self.v, self.w, left);
        }
        None
    }

    fn halt(&mut self, link: &mut dyn Link) {
        stop_base(link);
    }
}

/// A base position goal run by a host-side law.
struct LawGoal(Box<dyn BaseLaw>);

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
struct TrackGoal(Box<Tracking>);

impl Goal for TrackGoal {
    fn claim(&self) -> Claim {
        BASE
    }

    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>> {
        match self.0.step(s.now, s.telemetry) {
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

/// The base of a [`Robot`]: a handle (clone of the robot's), so base motions run while other
/// components move.
#[derive(Clone, Debug)]
pub struct Base {
    pub(crate) robot: Robot,
}

impl Base {
    pub(crate) fn new(robot: Robot) -> Self {
        Base { robot }
    }

    /// Put a base goal under way (preempting a base motion under way).
    fn start(&self, goal: Box<dyn Goal>, what: &str, timeout: Duration) -> Result<Motion> {
        self.robot
            .start_motion(BASE, what, |_io: &mut Io| Ok((goal, timeout)))
    }

    /// The backend's clock.
    fn now(&self) -> Duration {
        self.robot.lock_io().link.now()
    }

    /// The tracking limits, capped by the configuration's speeds.
    fn tracking_limits(&self) -> Limits {
        let s = self.section();
        Limits {
            v: Limits::TRACKING.v.min(s.max_linear),
            w: Limits::TRACKING.w.min(s.max_angular),
            ..Limits::TRACKING
        }
    }

    /// A proportional controller for `goal`, starting now.
    pub(crate) fn proportional(&self, goal: [f64; 3]) -> BaseGoal {
        let s = self.section();
        BaseGoal {
            goal,
            phase: Phase::TurnToGoal,
            backwards: false,
            v: 0.0,
            w: 0.0,
            next: Duration::ZERO,
            max_v: s.max_linear,
            max_w: s.max_angular,
            min_w: gains::MIN_WHEEL / (0.5 * s.track),
            tol_xy: s.translation_tolerance,
            tol_th: s.rotation_tolerance,
        }
    }

    fn section(&self) -> &crate::config::BaseSection {
        // Present: `Robot::base` checks it.
        self.robot.cfg().base.as_ref().expect("base config")
    }

    /// Odometry pose `[x, y, θ]`.
    pub fn get_state(&self) -> Result<[f64; 3]> {
        let o = self.robot.telemetry()?.odometry;
        Ok([o.x as f64, o.y as f64, o.theta as f64])
    }

    /// The geometry the odometry uses: the configuration's calibrated `[base] odometry`, or
    /// the last [`Base::set_odometry_geometry`], else the nominal wheel radius and track.
    pub fn odometry_geometry(&self) -> WheelGeometry {
        let s = self.section();
        self.robot
            .lock_io()
            .base
            .odometry
            .or(ferrobot_profile::odometry_geometry(s))
            .unwrap_or_else(|| ferrobot_profile::nominal_geometry(s))
    }

    /// Make the firmware's odometry use a calibrated geometry (from
    /// [`crate::odometry_calibration::estimate`]); each value must be within 10 % of the
    /// nominal one. Takes effect from the next wheel sample; the pose is not reset.
    pub fn set_odometry_geometry(&self, g: WheelGeometry) -> Result<()> {
        if !g.near(&ferrobot_profile::nominal_geometry(self.section()), 0.1) {
            return Err(Error::Calibration {
                why: format!(
                    "{g:?} is not within 10 % of the nominal {:?}",
                    ferrobot_profile::nominal_geometry(self.section())
                ),
            });
        }
        let mut io = self.robot.lock_io();
        io.link.command(
            &HostMsg::SetBaseGeometry {
                left_radius: g.left_radius as f32,
                right_radius: g.right_radius as f32,
                track: g.track as f32,
            },
            "odometry geometry",
        )?;
        io.base.odometry = Some(g);
        Ok(())
    }

    /// The accumulated wheel angles `[left, right]` (rad) since the firmware started.
    pub fn wheel_angles(&self) -> Result<[f64; 2]> {
        let w = self.robot.telemetry()?.wheels;
        Ok([w.left as f64, w.right as f64])
    }

    /// Start logging the wheel angles of every telemetry frame that motions see (for odometry
    /// calibration), beginning with the current ones; replaces an earlier log.
    pub fn start_wheel_log(&self) -> Result<()> {
        let mut io = self.robot.lock_io();
        let t = io.link.telemetry()?;
        io.base.wheel_log = Some(Vec::new());
        io.base.log_wheels(&t);
        Ok(())
    }

    /// Stop logging and return the wheel angles `[left, right]` (rad) logged since
    /// [`Base::start_wheel_log`], ending with the current ones.
    pub fn take_wheel_log(&self) -> Result<Vec<[f64; 2]>> {
        let mut io = self.robot.lock_io();
        let t = io.link.telemetry()?;
        io.base.log_wheels(&t);
        let log = io.base.wheel_log.take().unwrap_or_default();
        Ok(log.into_iter().map(|l| l.1).collect())
    }

    /// Zero the odometry pose.
    pub fn reset_odometry(&self) -> Result<()> {
        self.robot
            .lock_io()
            .link
            .command(&HostMsg::ResetOdometry, "odometry reset")?;
        // Let the reset show in telemetry.
        self.robot.wait_for(Duration::from_millis(30));
        Ok(())
    }

    /// Stop now; a base motion under way ends ([`Error::Preempted`]).
    pub fn stop(&self) -> Result<()> {
        let mut io = self.robot.lock_io();
        io.prepare(self.robot.cfg(), BASE);
        io.link.command(
            &HostMsg::BaseVelocity {
                v: 0.0,
                w: 0.0,
                duration_ms: 0,
            },
            "base stop",
        )
    }

    /// Start driving at `v` (m/s) and `w` (rad/s) for `duration` s (at most
    /// [`validate::MAX_DURATION_S`]).
    pub fn set_vel_async(&self, v: f64, w: f64, duration: f64) -> Result<Motion> {
        check_finite("base velocity", &[v, w])?;
        let duration = validate::seconds("base velocity duration", duration)?;
        let s = self.section();
        let speeds = [
            ("base forward speed", v, s.max_linear),
            ("base yaw rate", w, s.max_angular),
        ];
        for (what, value, max) in speeds {
            if value.abs() > max + 1e-9 {
                return Err(Error::OutOfLimits {
                    joint: what.into(),
                    value,
                    min: -max,
                    max,
                });
            }
        }
        let now = self.now();
        let until = now.saturating_add(duration);
        self.start(
            Box::new(VelocityGoal {
                v,
                w,
                until,
                next_send: now,
            }),
            "base velocity",
            duration + Duration::from_secs(1),
        )
    }

    /// Drive at `v` (m/s) and `w` (rad/s) for `duration` s, then stop.
    pub fn set_vel(&self, v: f64, w: f64, duration: f64) -> Result<()> {
        self.set_vel_async(v, w, duration)?.wait()
    }

    /// Start tracking `reference` (states and controls every `reference.dt`) with LQR from
    /// odometry, or open loop.
    pub fn track_trajectory_async(&self, reference: Reference, close_loop: bool) -> Result<Motion> {
        self.track(reference, close_loop, None)
    }

    /// Track `reference`; with `finish`, then correct the residual to that pose with
    /// [`Finish`].
    fn track(
        &self,
        reference: Reference,
        close_loop: bool,
        finish: Option<[f64; 3]>,
    ) -> Result<Motion> {
        reference.check()?;
        let limits = self.tracking_limits();
        let duration = reference.dt * reference.controls.len() as f64;
        let now = self.now();
        let tr = Tracking {
            tracker: LqrTracker::new(reference, [3.0, 3.0, 4.0], 0.2),
            closed_loop: close_loop,
            start: None,
            next: now,
            last: (0.0, 0.0),
            limits,
        };
        let timeout = Duration::from_secs_f64(duration + 5.0);
        if let Some(goal) = finish {
            // One encoder tick of one wheel turns the odometry by this much (rad).
            let fw = ferrobot_profile::firmware_profile(self.robot.cfg()).base;
            let tick = fw.rad_per_tick() as f64 * fw.wheel_radius as f64 / fw.track as f64;
            let s = self.section();
            let law = TrackThenFinish {
                track: tr,
                tracking: true,
                last: (0.0, 0.0),
                finish: Finish::new(
                    goal,
                    s.min_wheel_speed,
                    s.min_wheel_speed / (0.5 * s.track),
                    tick,
                    limits,
                ),
            };
            return self.start(
                Box::new(LawGoal(Box::new(law))),
                "base position goal",
                timeout + FINISH_TIME,
            );
        }
        self.start(
            Box::new(TrackGoal(Box::new(tr))),
            "trajectory tracking",
            timeout,
        )
    }

    /// Track `reference` and wait (PyRobot's `track_trajectory`).
    pub fn track_trajectory(&self, reference: Reference, close_loop: bool) -> Result<()> {
        self.track_trajectory_async(reference, close_loop)?.wait()
    }

    /// Start moving to `[x, y, θ]` in the odometry frame with the chosen controller. The goal
    /// must be at most [`validate::MAX_BASE_GOAL_DISTANCE`] from the current pose; every
    /// controller has a budget (its timeout, in the backend's time) and fails with
    /// [`Error::Timeout`] when it runs out.
    pub fn go_to_absolute_with(&self, goal: [f64; 3], opts: GoalOptions) -> Result<Motion> {
        check_finite("base goal", &goal)?;
        if opts.use_map || opts.map.is_some() {
            return self.navigate(goal, &opts);
        }
        let here = self.get_state()?;
        validate::base_goal(goal, here)?;
        let obstacles = Obstacles::new(opts.obstacles.clone(), None)?;
        let controller = opts.controller.unwrap_or(if obstacles.is_empty() {
            self.section().controller
        } else {
            BaseController::Dwa
        });
        let lim = self.tracking_limits();
        match controller {
            BaseController::Proportional => self.proportional_async(goal, here),
            BaseController::Lqr | BaseController::Ilqr => {
                let mut r = if opts.smooth {
                    Reference::smooth(here, goal, &lim, 0.1, 0.8)?
                } else {
                    Reference::sharp(here, goal, &lim, 0.1)?
                };
                if controller == BaseController::Ilqr {
                    r = ilqr(here, &r, [3.0, 3.0, 4.0], 0.2, &lim)?.reference;
                }
                // Hold the goal a little: the tracker settles while the reference rests; closed
                // loop, the finisher then removes what the wheels' deadband left.
                let finish = opts.close_loop.then_some(goal);
                self.track(r.hold(10)?, opts.close_loop, finish)
            }
            BaseController::Dwa => {
                let radius = self.section().footprint_radius;
                let clear = obstacles.clearance([goal[0], goal[1]]);
                if clear < radius {
                    return Err(Error::Unreachable {
                        why: format!(
                            "the base ({radius} m footprint radius) at the goal would overlap an obstacle ({clear:.3} m from the goal)"
                        ),
                    });
                }
                let nav = NavField::new(
                    [here[0], here[1]],
                    [goal[0], goal[1]],
                    &obstacles,
                    radius + DWA_PATH_MARGIN,
                )?;
                let dwa = Dwa {
                    path: nav.path([here[0], here[1]]),
                    nav,
                    goal: [goal[0], goal[1]],
                    obstacles,
                    radius,
                    limits: lim,
                    dt: 0.1,
                    horizon: 2.0,
                };
                let dist = (goal[0] - here[0]).hypot(goal[1] - here[1]);
                // Room for a detour of half the distance again, at half speed.
                let timeout = Duration::from_secs_f64(15.0 + 3.0 * dist / lim.v);
                // The last stretch stays within the window's (tracking) limits too.
                let mut finish = self.proportional(goal);
                finish.max_v = lim.v;
                finish.max_w = lim.w;
                let now = self.now();
                let g = DwaGoal {
                    dwa,
                    finish,
                    reached: false,
                    next: now,
                    last: (0.0, 0.0),
                    progress: (f64::INFINITY, now),
                };
                self.start(
                    Box::new(LawGoal(Box::new(g))),
                    "base position goal (DWA)",
                    timeout,
                )
            }
        }
    }

    /// The odometry-frame goal `delta` (`[x, y, θ]` in the current pose's frame) names.
    fn relative_goal(&self, delta: [f64; 3]) -> Result<[f64; 3]> {
        check_relative(delta)?;
        let here = Pose2::from(self.get_state()?);
        Ok(here.compose(&Pose2::from(delta)).to_array())
    }

    /// Start moving by `[x, y, θ]` relative to the current pose with the chosen controller.
    pub fn go_to_relative_with(&self, delta: [f64; 3], opts: GoalOptions) -> Result<Motion> {
        check_relative(delta)?;
        let goal = self.relative_goal(delta)?;
        self.go_to_absolute_with(goal, opts)
    }

    /// Start moving to `[x, y, θ]` in the odometry frame with the configuration's controller.
    pub fn go_to_absolute_async(&self, goal: [f64; 3]) -> Result<Motion> {
        self.go_to_absolute_with(goal, GoalOptions::default())
    }

    /// Start the proportional controller from `here` towards `[x, y, θ]` (a goal
    /// [`Base::go_to_absolute_with`] has validated) in the odometry frame.
    fn proportional_async(&self, goal: [f64; 3], here: [f64; 3]) -> Result<Motion> {
        let s = self.section().clone();
        let now = self.now();
        let dist = (goal[0] - here[0]).hypot(goal[1] - here[1]);
        let turn = std::f64::consts::TAU;
        let timeout =
            Duration::from_secs_f64(10.0 + 3.0 * (dist / s.max_linear + turn / s.max_angular));
        let mut g = self.proportional(goal);
        g.next = now;
        self.start(
            Box::new(LawGoal(Box::new(g))),
            "base position goal",
            timeout,
        )
    }

    /// Move to `[x, y, θ]` in the odometry frame with the configuration's controller and wait.
    pub fn go_to_absolute(&self, goal: [f64; 3]) -> Result<()> {
        self.go_to_absolute_async(goal)?.wait()
    }

    /// Start moving by `[x, y, θ]` relative to the current pose (x forward, y left).
    pub fn go_to_relative_async(&self, delta: [f64; 3]) -> Result<Motion> {
        check_relative(delta)?;
        let goal = self.relative_goal(delta)?;
        self.go_to_absolute_async(goal)
    }

    /// Move by `[x, y, θ]` relative to the current pose and wait.
    pub fn go_to_relative(&self, delta: [f64; 3]) -> Result<()> {
        self.go_to_relative_async(delta)?.wait()
    }
}

impl Base {
    /// The robot's radius for the navigator, m: the base's footprint radius, or how far the arm
    /// reaches across the floor now ([`crate::Arm::reach`]) where it sticks out further.
    fn nav_radius(&self) -> Result<f64> {
        Ok(self.section().footprint_radius.max(self.robot.arm_reach()?))
    }

    /// A goal on a map, driven by the navigator (see [`GoalOptions::map`]).
    fn navigate(&self, goal: [f64; 3], opts: &GoalOptions) -> Result<Motion> {
        let slam = opts.use_map || opts.frame == Source::Slam;
        let here = self.get_state_from(if slam { Source::Slam } else { Source::Odometry })?;
        validate::base_goal(goal, here)?;
        let radius = self.nav_radius()?;
        let lim = self.tracking_limits();
        let grid = match (&opts.map, opts.use_map) {
            (Some(m), _) => m.clone(),
            (None, _) => match self.robot.slam_occupancy_map()? {
                Some(image) => image.to_grid(false)?,
                // Nothing mapped yet: all unknown, hence free.
                None => OccupancyGrid::new([here[0], here[1]], 0.02, 1, 1)?,
            },
        };
        // The map and the circles are checked before the circles are stamped into it.
        grid.check()?;
        Obstacles::new(opts.obstacles.clone(), None)?;
        let map = NavGoal::stamped(&grid, &opts.obstacles)?;
        let mut nav = Navigator::new(&map, [goal[0], goal[1]], NavSettings::new(radius, lim))?;
        let scans = opts.live_obstacles && self.robot.config().camera.is_some();
        if scans {
            // What the last goal's camera saw counts from the start.
            if let Some(live) = self.robot.lock_io().sense.live_for(slam) {
                nav.set_live(&live)?;
            }
        }
        // A goal no path reaches (another room behind closed doors, an island) is a typed
        // error now, not a failure later: the navigator's first plan, made here. Beyond the
        // map's edge is unknown, so free (as move_base's allow_unknown). When what blocks the
        // way is only what the camera saw before, the navigator looks again first.
        let now = self.now().as_secs_f64();
        match nav.plan(now, [here[0], here[1]]) {
            Err(ferrobot_nav::Error::NoPath { .. }) if nav.live_cells() > 0 => {
                // Blocked by the map itself: refused now.
                let mut bare = nav.clone();
                bare.set_live(&ferrobot_nav::LiveObstacles::new(map.resolution)?)?;
                bare.plan(now, [here[0], here[1]])?;
            }
            r => r?,
        }
        if scans {
            let eyes = self.robot.eyes()?;
            self.robot.lock_io().sense.camera = Some(eyes);
        }
        // The heading stage's controller within the window's (tracking) limits.
        let mut finish = self.proportional(goal);
        finish.max_v = lim.v;
        finish.max_w = lim.w;
        let g = NavGoal {
            nav,
            goal,
            slam,
            slam_grid: opts.use_map && opts.map.is_none(),
            circles: opts.obstacles.clone(),
            scans,
            seen: (0, 0),
            finish,
            finishing: false,
            lost_since: None,
            hold_ms: 250,
        };
        let dist = (goal[0] - here[0]).hypot(goal[1] - here[1]);
        // Room for detours and every recovery.
        let timeout = Duration::from_secs_f64(120.0 + 6.0 * dist / lim.v);
        self.start(Box::new(g), "base position goal (navigator)", timeout)
    }
}

/// Longest an exploration may take, s of the robot's clock.
pub const EXPLORE_TIMEOUT: Duration = Duration::from_secs(1800);

impl Base {
    /// Explores with SLAM until no reachable frontier is left (see [`crate::navigate`]): the
    /// base looks all round, then drives to the nearest frontier of SLAM's occupancy grid and
    /// faces it, again and again, avoiding what the depth camera sees. Needs SLAM running
    /// ([`Robot::start_slam`]); the map is then [`Robot::slam_occupancy_map`]. Fails after
    /// [`EXPLORE_TIMEOUT`], or when SLAM has no pose for [`crate::navigate::SLAM_PATIENCE`].
    pub fn explore_async(&self) -> Result<Motion> {
        // SLAM must run (its pose may come with the first frames).
        self.robot.slam_report()?;
        if self.robot.config().camera.is_none() {
            return Err(self.robot.missing("camera"));
        }
        let eyes = self.robot.eyes()?;
        self.robot.lock_io().sense.camera = Some(eyes);
        let radius = self.nav_radius()?;
        let live = self.robot.lock_io().sense.live_for(true);
        let g = crate::navigate::ExploreGoal::new(
            NavSettings::new(radius, self.tracking_limits()),
            ferrobot_nav::FrontierSettings::new(radius),
            ferrobot_slam::GridSettings::default().resolution,
            live,
        )?;
        self.start(Box::new(g), "exploration", EXPLORE_TIMEOUT)
    }

    /// As [`Base::explore_async`], waiting until it is done.
    pub fn explore(&self) -> Result<()> {
        self.explore_async()?.wait()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Telemetry whose odometry is at `[x, y, θ]`.
    fn at(pose: [f64; 3]) -> Telemetry {
        Telemetry {
            time_us: 0,
            joints: heapless::Vec::new(),
            queued: 0,
            gripper: ferrobot_protocol::GripperState::Absent,
            odometry: ferrobot_protocol::Odometry {
                x: pose[0] as f32,
                y: pose[1] as f32,
                theta: pose[2] as f32,
                ..Default::default()
            },
            wheels: Default::default(),
            base_flags: 0,
            faults: 0,
            loop_stats: Default::default(),
        }
    }

    /// A goal at (1, 0) heading 0, being driven to at 0.2 m/s (the Kobuki's limits and
    /// tolerances).
    fn driving() -> BaseGoal {
        BaseGoal {
            goal: [1.0, 0.0, 0.0],
            phase: Phase::Drive,
            backwards: false,
            v: 0.2,
            w: 0.0,
            next: Duration::ZERO,
            max_v: 0.5,
            max_w: 1.0,
            min_w: gains::MIN_WHEEL / (0.5 * 0.23),
            tol_xy: 0.02,
            tol_th: 0.05,
        }
    }

    /// Past the goal and 0.3 m to its side, with the goal's heading: the goal is driven to
    /// again, not reached (it was reported reached 0.32 m away), and a unicycle following the
    /// commands ends within the tolerances.
    #[test]
    fn a_goal_passed_wide_of_its_tolerance_is_driven_to_again() {
        let mut g = driving();
        let mut pose = [1.1, 0.3, 0.0];
        let dt = BASE_CONTROL_PERIOD.as_secs_f64();
        let mut now = Duration::ZERO;
        let mut steps = 0;
        while let Some((v, w)) = g.step_inner(now, &at(pose)) {
            pose[0] += v * pose[2].cos() * dt;
            pose[1] += v * pose[2].sin() * dt;
            pose[2] = wrap(pose[2] + w * dt);
            now += BASE_CONTROL_PERIOD;
            steps += 1;
            assert!(steps < 1200, "not reached in 60 s: at {pose:?}");
        }
        assert!(steps > 0, "reported reached at {pose:?}");
        let dist = (pose[0] - 1.0).hypot(pose[1]);
        assert!(dist < 0.02 && pose[2].abs() < 0.05, "ended at {pose:?}");
        // Within the tolerances it is reached at once.
        assert_eq!(
            driving().step_inner(Duration::ZERO, &at([1.01, 0.0, 0.0])),
            None
        );
    }
}
