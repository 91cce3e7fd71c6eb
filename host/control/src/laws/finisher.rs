//! The finisher after closed-loop tracking (our deadband compensation): removes the last
//! millimetres and hundredths of a degree by odometry, in straight drives, turns in place and
//! creep-speed pulses the firmware times. Poses `[x, y, θ]` (m, m, rad) in the goal's frame,
//! twists and commands `(v, ω)` (m/s, rad/s).

use std::collections::VecDeque;
use std::time::Duration;

use crate::trajectory::Limits;
use crate::wrap;

/// Longest the [`Finisher`] may add to a motion's timeout.
pub const FINISH_TIME: Duration = Duration::from_secs(30);

/// Residual position error (m) along the heading that the finisher leaves.
pub const FINISH_TOL_XY: f64 = 0.0005;
/// Residual position error (m) across the heading above which the finisher backs up and
/// re-approaches.
pub const FINISH_TOL_LATERAL: f64 = 0.0005;
/// Residual heading error (rad) that the finisher aims for (0.05°), unless the odometry's
/// resolution is coarser (see [`Finisher`]).
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
/// backing up `FINISH_BACKUP` (5 cm), facing the goal and driving to it; the error along the
/// heading to [`FINISH_TOL_XY`]; then the heading to [`FINISH_TOL_TH`] or, when one encoder
/// tick turns the odometry by more than twice that, to 0.55 tick (the Create 2: 0.06°).
/// Large errors are driven at speeds proportional to them, ramped within the tracking
/// accelerations; small ones by pulses at creep speed (`[base] min_wheel_speed`, just above
/// the deadband and below one tracking period's acceleration) whose length the firmware
/// times to the millisecond, corrected for the wheels' dead time, which each pulse measures;
/// the last heading pulses pivot about one wheel so that the odometry can change by a single
/// encoder tick. It waits for the base to stand still before each pulse and after each step.
#[derive(Debug, Clone)]
pub struct Finisher {
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

impl Finisher {
    /// A finisher to `goal` with creep speeds `v_min` (m/s) and `w_min` (rad/s), for
    /// odometry whose heading changes by `tick` (rad) per encoder tick.
    pub fn new(goal: [f64; 3], v_min: f64, w_min: f64, tick: f64, limits: Limits) -> Self {
        Finisher {
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

    /// The next command `(v, ω)` (m/s, rad/s) at `now` from the odometry pose `[x, y, θ]`
    /// (m, m, rad; the goal's frame) and twist `[v, ω]` (m/s, rad/s); `None` when done.
    pub fn step(&mut self, now: Duration, pose: [f64; 3], twist: [f64; 2]) -> Option<(f64, f64)> {
        let c = self.want(now, pose, twist)?;
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
    fn want(&mut self, now: Duration, pose: [f64; 3], twist: [f64; 2]) -> Option<FinishCmd> {
        let [x, y, th] = pose;
        let still = twist[0].abs() < 1e-3 && twist[1].abs() < 1e-2;
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

impl Finisher {
    /// How long (ms) the firmware should hold the command [`Finisher::step`] returned last.
    pub fn hold_ms(&self) -> u16 {
        self.hold_ms
    }

    /// Starts from a base commanded at `(v, ω)` (m/s, rad/s), e.g. when a tracker hands over.
    pub fn take_over(&mut self, last: (f64, f64)) {
        self.last = last;
    }
}
