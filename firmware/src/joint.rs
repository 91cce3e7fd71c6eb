//! Per-joint control state: the setpoint queue with cubic Hermite interpolation, the
//! reference rate limiter, the joint PID with anti-windup, and limit enforcement.

use ferrobot_protocol::dxl::units;
use ferrobot_protocol::{JointConfig, JointMode, JointPoint, JointState};
use heapless::Deque;

use crate::time::{Duration, Instant};

/// Knots a joint can queue.
pub const QUEUE_LEN: usize = 16;

/// Velocity mode approaches a position limit on an envelope: the commanded speed is at most
/// this gain (1/s) times the distance left, so the joint stops at the limit instead of
/// reacting once it is past it; past a limit the envelope brings it back.
pub const LIMIT_APPROACH_GAIN: f32 = 2.0;
/// Position mode: a joint measured faster than its velocity limit times this factor (or, in
/// a loop slower than [`SERVO_TIME_CONSTANT`], the loop period over it), plus
/// [`BRAKE_SPEED_ABS`], or moving further out beyond a limit, is braked from where it is
/// (caught falling, pushed, torqued while moving).
pub const BRAKE_SPEED_FACTOR: f32 = 1.05;
/// How fast a servo's own position loop closes on a step of its goal, s: in a control loop
/// slower than this, the servo moves faster than the command between two setpoints.
pub const SERVO_TIME_CONSTANT: f32 = 0.01;
/// Ticks in a row a joint must be measured too fast, the same way, before it is braked.
pub const FAST_TICKS: u8 = 2;
/// See [`BRAKE_SPEED_FACTOR`], rad/s (above the noise of a servo's velocity reading).
pub const BRAKE_SPEED_ABS: f32 = 0.15;
/// The speed above the noise of a servo's velocity reading at which a joint beyond a limit
/// counts as moving further out, rad/s.
pub const LEAVING_SPEED: f32 = 0.15;
/// Position mode, braking: the goal is behind the joint by its speed times this, s ...
pub const BRAKE_TIME: f32 = 0.1;
/// ... but at least this far, rad (a joint drifting under a load needs a goal well behind it
/// to stop) ...
pub const BRAKE_MIN: f32 = 0.02;
/// ... and at most this far, rad (near full torque).
pub const BRAKE_OFFSET: f32 = 0.3;
/// Position mode: once a braked joint outside its limits has slowed down, its goal stays at
/// most this far from it, rad: enough to hold a load, little enough not to race back.
pub const BRAKE_HOLD: f32 = 0.1;
/// Velocity mode, holding (no command): speed (rad/s) per rad of error towards the hold point.
pub const VELOCITY_HOLD_GAIN: f32 = 2.0;
/// Current and PWM modes: the speed envelope near a limit, 1/s. The envelope ahead of a limit
/// is this gain times the distance left (capped at the velocity limit), so a joint slows down
/// before it reaches a limit, from its state, rather than after crossing it.
pub const GUARD_APPROACH_GAIN: f32 = 10.0;
/// Current and PWM modes: speed beyond the envelope (rad/s) at which the guard brakes with the
/// joint's full strength, at a 1 kHz loop (slower loops brake proportionally more gently, so
/// that a braking effort held for a whole period does not overshoot).
pub const GUARD_SPEED_SPAN: f32 = 0.25;
/// Velocity, current and PWM modes: a joint moving faster than its mode's speed envelope
/// allows by more than half its velocity limit plus this (rad/s), capped at
/// [`STOP_SPEED_MARGIN`] (velocity mode: [`STOP_SPEED_MARGIN_VELOCITY`]), or more than
/// [`STOP_OUTSIDE`] outside a position limit and not coming back, is stopped: switched to
/// position mode, holding where it comes to rest.
pub const STOP_SPEED_BASE: f32 = 0.05;
/// See [`STOP_SPEED_BASE`], rad/s.
pub const STOP_SPEED_MARGIN: f32 = 0.2;
/// See [`STOP_SPEED_BASE`]: the servo's own velocity loop lags the envelope it is given.
pub const STOP_SPEED_MARGIN_VELOCITY: f32 = 0.3;
/// See [`STOP_SPEED_MARGIN`], rad.
pub const STOP_OUTSIDE: f32 = 0.01;

/// The speed envelope `(lowest, highest)` (rad/s) at position `q`: within the velocity limit,
/// and `gain` × the distance to each position limit (pointing back inside beyond one).
pub fn envelope(q: f32, lim: &ferrobot_protocol::JointLimits, gain: f32) -> (f32, f32) {
    // Both ends within ±the velocity limit, so they stay ordered even far outside the limits.
    let v = lim.velocity;
    let up = (gain * (lim.max - q)).min(v).max(-v);
    let down = (gain * (lim.min - q)).max(-v).min(v);
    (down, up)
}

/// Where a position goal may lie: within the limits, or, for a joint outside them, between
/// them and its `anchor` (rad): the outermost point it has been allowed, which only ever moves
/// back towards the limits (see [`JointControl::anchor`]); while it is `braking`, up to
/// [`BRAKE_OFFSET`] beyond.
pub fn position_goal_range(
    lim: &ferrobot_protocol::JointLimits,
    anchor: Option<f32>,
    braking: bool,
) -> (f32, f32) {
    // A joint coming back too fast (gravity helping it) is braked with a goal behind it, which
    // may lie up to BRAKE_OFFSET beyond its anchor.
    let slack = if braking { BRAKE_OFFSET } else { 0.0 };
    match anchor {
        Some(a) if a.is_finite() => (lim.min.min(a - slack), lim.max.max(a + slack)),
        _ => (lim.min, lim.max),
    }
}

/// The guard of the torque modes: the effort `tau` (N·m, already within the joint's effort
/// limit) limited so that a joint at `q` (rad) moving at `qd` (rad/s) is braked back into its
/// speed envelope (under an emergency stop, `stopped`, only its speed limit: it is not moved
/// back inside), at up to `strength` (N·m, what the joint's servos can give) at
/// [`GUARD_SPEED_SPAN`] beyond it. Position and speed limits take precedence over the effort
/// limit: braking, and holding at a position limit, may use the servos' full torque.
pub fn guard_effort(
    tau: f32,
    (q, qd): (f32, f32),
    lim: &ferrobot_protocol::JointLimits,
    strength: f32,
    dt: f32,
    stopped: bool,
) -> f32 {
    // Emergency stop: no motion, not even back inside the limits.
    let (down, up) = if stopped {
        (-lim.velocity, lim.velocity)
    } else {
        envelope(q, lim, GUARD_APPROACH_GAIN)
    };
    let b = strength / GUARD_SPEED_SPAN * (1e-3 / dt).min(1.0);
    tau.min(b * (up - qd))
        .max(b * (down - qd))
        .clamp(-strength, strength)
}

/// The servo's position loop, as the servo runs it (the e-manual's gain scaling, no profile):
/// PWM = P/128 · error (ticks) − D/16 · speed (ticks/ms). Returns (P term per rad, D term per
/// rad/s), PWM units.
fn position_loop_gains(cfg: &JointConfig) -> (f32, f32) {
    let tpr = units::TICKS_PER_REV / core::f32::consts::TAU;
    (
        cfg.servo.pos_p as f32 / 128.0 * tpr,
        cfg.servo.pos_d as f32 / 16.0 * tpr * 1e-3,
    )
}

/// How far (rad) a position command may lead the joint: twice the servo's tracking lag at the
/// joint's velocity limit (the goal error at which its position loop, unloaded, drives it at
/// that speed), plus [`LEAD_MIN`].
pub fn position_lead(cfg: &JointConfig) -> f32 {
    let v = cfg.limits.velocity;
    let f = cfg.model.spec().pwm_fraction_for_effort(0.0, v);
    let (kp, kd) = position_loop_gains(cfg);
    if kp <= 0.0 {
        return 0.0;
    }
    let e = (f * units::PWM_MAX + kd * v) / kp;
    if e.is_finite() {
        (LEAD_FACTOR * e.abs() + LEAD_MIN).min(1.0)
    } else {
        0.0
    }
}
/// See [`position_lead`].
pub const LEAD_FACTOR: f32 = 2.0;
/// See [`position_lead`], rad.
pub const LEAD_MIN: f32 = 0.004;

/// How far (rad) from a joint moving at `qd` (rad/s) a position goal drives its servo at full
/// PWM: goals further away ask for nothing more.
pub fn position_reach(cfg: &JointConfig, qd: f32) -> f32 {
    let (kp, kd) = position_loop_gains(cfg);
    if kp <= 0.0 || !qd.is_finite() {
        return 0.0;
    }
    ((units::PWM_MAX + kd * qd.abs()) / kp).min(1.0)
}

/// Where a position goal may lie for a joint at `q` moving at `qd`: within
/// [`position_goal_range`], or, while it is braked, behind the moving joint (the other way from its motion) within
/// [`position_reach`] of it: such a goal slows it.
pub fn position_goal_window(
    lim: &ferrobot_protocol::JointLimits,
    anchor: Option<f32>,
    braking: bool,
    (q, qd): (f32, f32),
    reach: f32,
) -> (f32, f32) {
    let (mut lo, mut hi) = position_goal_range(lim, anchor, braking);
    if braking && q.is_finite() && qd.is_finite() && reach > 0.0 {
        if qd < 0.0 {
            hi = hi.max(q + reach);
        } else if qd > 0.0 {
            lo = lo.min(q - reach);
        }
    }
    (lo, hi)
}

/// Position mode with a gravity model: the load correction may add at most this share of the
/// model's goal offset to it ...
pub const SAG_MODEL_SHARE: f32 = 0.3;
/// ... plus this, rad: it mends the model's error (masses, friction), not the load.
pub const SAG_MODEL_MIN: f32 = 0.005;
/// Without a model (or for a stalled joint, see [`STALL_TIME`]), the load correction's
/// bound, rad.
pub const SAG_MAX: f32 = 0.2;
/// Position mode: a joint held back by the command's lead (it cannot follow its command) and
/// slower than [`STALL_SPEED`] for this long is stalled against something the gravity
/// model does not know (an obstacle, a payload): its load correction may then use
/// [`SAG_MAX`], as without a model, and the servo pushes as hard as its own protection allows.
pub const STALL_TIME: Duration = Duration::from_millis(300);
/// See [`STALL_TIME`], rad/s.
pub const STALL_SPEED: f32 = 0.05;
/// See [`STALL_TIME`]: held back means the command leads the joint by at least this share
/// of its lead ([`position_lead`]).
pub const STALL_LEAD_SHARE: f32 = 0.75;
/// Current and PWM modes: the effort ramps from what the joint held at the mode change to its
/// full strength in at least this long, s (a step of torque would outrun the guard's braking).
pub const EFFORT_RAMP_TIME: f32 = 0.1;

/// The goal offset (rad) that makes a joint's servo(s), in position mode at rest, give the
/// effort `tau` (N·m): their proportional loop's stiffness at zero speed; within the goal
/// distance of full PWM. Zero when the gains give no stiffness or `tau` is not finite.
pub fn goal_offset_for_effort(cfg: &JointConfig, tau: f32) -> f32 {
    let (kp, _) = position_loop_gains(cfg);
    let spec = cfg.model.spec();
    let servos = if cfg.twin_id.is_some() { 2.0 } else { 1.0 };
    if kp <= 0.0 || !tau.is_finite() {
        return 0.0;
    }
    let f = spec.pwm_fraction_for_effort(tau / servos, 0.0);
    let reach = position_reach(cfg, 0.0);
    (f * units::PWM_MAX / kp).clamp(-reach, reach)
}

/// One queued trajectory knot at an absolute firmware time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Knot {
    /// Firmware time.
    pub t: Instant,
    /// Position, rad.
    pub q: f32,
    /// Velocity, rad/s.
    pub qd: f32,
    /// Effort feed-forward, N·m.
    pub eff: f32,
}

/// Reference a joint tracks at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Reference {
    /// Position, rad.
    pub q: f32,
    /// Velocity, rad/s.
    pub qd: f32,
    /// Effort feed-forward, N·m.
    pub eff: f32,
}

/// Cubic Hermite interpolation between knots `a` and `b` at time `t` (a.t ≤ t ≤ b.t).
pub fn hermite(a: &Knot, b: &Knot, t: Instant) -> Reference {
    let span = b.t - a.t;
    if span.is_zero() {
        return Reference {
            q: b.q,
            qd: b.qd,
            eff: b.eff,
        };
    }
    let h = span.as_secs_f32();
    let s = ((t - a.t).as_micros() as f32 / span.as_micros() as f32).clamp(0.0, 1.0);
    let s2 = s * s;
    let s3 = s2 * s;
    let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
    let h10 = s3 - 2.0 * s2 + s;
    let h01 = -2.0 * s3 + 3.0 * s2;
    let h11 = s3 - s2;
    let q = h00 * a.q + h10 * h * a.qd + h01 * b.q + h11 * h * b.qd;
    let d00 = 6.0 * s2 - 6.0 * s;
    let d10 = 3.0 * s2 - 4.0 * s + 1.0;
    let d01 = -6.0 * s2 + 6.0 * s;
    let d11 = 3.0 * s2 - 2.0 * s;
    let qd = (d00 * a.q + d01 * b.q) / h + d10 * a.qd + d11 * b.qd;
    let eff = a.eff + (b.eff - a.eff) * s;
    Reference { q, qd, eff }
}

/// What one control tick asks of a joint's servo(s), in joint space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointOutput {
    /// Leave the servo alone (off, or no valid measurement in a torque mode).
    None,
    /// Goal position, rad.
    Position(f32),
    /// Goal velocity, rad/s.
    Velocity(f32),
    /// Goal effort, N·m, with the measured joint speed for voltage-mode servos: as goal
    /// current where the servo has current control, else as PWM.
    Effort(f32, f32),
    /// Goal effort, N·m, at the measured joint speed, always realised as PWM (PWM mode).
    PwmEffort(f32, f32),
}

/// Control state of one joint.
#[derive(Debug, Clone)]
pub struct JointControl {
    /// Current mode.
    pub mode: JointMode,
    queue: Deque<Knot, QUEUE_LEN>,
    seg_start: Knot,
    /// Rate-limited position command of the last tick, rad.
    cmd: f32,
    /// Direct command (velocity, effort or PWM) from `JointCommand`.
    direct: Option<f32>,
    integral: f32,
    sag: f32,
    /// Position mode: braking a joint that moves faster than its limit.
    braking: bool,
    /// Position mode: consecutive ticks the joint has been measured too fast the same way
    /// (signed): one reading alone may be a motor rattling inside the backlash.
    fast_ticks: i8,
    /// Position mode: the way (sign of the speed) the last brake stopped the joint, and
    /// whether the brake before it stopped it the same way (a load, not momentum).
    brake_way: (i8, bool),

    /// The gravity load the arm's model gives this joint at its measured pose (N·m, what
    /// gravity exerts), set by the core before every tick; `None` without a trusted model.
    pub gravity: Option<f32>,
    /// Position mode: the goal offset that carries the modelled load, rad (last tick).
    feed_forward: f32,
    /// Position mode: since when the joint has been held back and standing still.
    held_since: Option<Instant>,
    /// Position mode: where the joint was last held back, rad.
    stall_q: f32,
    /// Current and PWM modes: the effort of the last tick (the ramp starts from it), N·m;
    /// `None` right after a mode change.
    effort: Option<f32>,

    /// Emergency stop: hold exactly where the joint stopped, even outside its limits (no
    /// motion at all, not even back inside), until released.
    pub stopped: bool,
    /// For a joint found outside its limits: the outermost point its goals may name (where it
    /// was found), moving only back towards the limits as the joint comes back, so that a
    /// load pushing it further out never drags its goals along.
    anchor: Option<f32>,

    /// Last measured state.
    pub state: JointState,
    /// Whether `state` has ever been measured.
    pub measured: bool,
    /// Whether a limit clamped the last command (reported once per episode).
    pub clamped: bool,
    /// Whether the joint's being outside its limits has been reported
    /// ([`ferrobot_protocol::FaultKind::OutsideLimits`], once per episode).
    pub outside_reported: bool,
}

impl Default for JointControl {
    fn default() -> Self {
        Self::new()
    }
}

impl JointControl {
    /// A joint that is off.
    pub fn new() -> Self {
        Self {
            mode: JointMode::Off,
            queue: Deque::new(),
            seg_start: Knot::default(),
            cmd: 0.0,
            direct: None,
            integral: 0.0,
            sag: 0.0,
            braking: false,
            brake_way: (0, false),
            fast_ticks: 0,
            gravity: None,
            feed_forward: 0.0,
            held_since: None,
            stall_q: 0.0,
            effort: None,
            stopped: false,
            anchor: None,
            state: JointState::default(),
            measured: false,
            clamped: false,
            outside_reported: false,
        }
    }

    /// Track where a joint outside its limits may have its goals: found outside, the anchor is
    /// where it is; as it comes back, the anchor follows it in (not while it is braked: a goal
    /// behind a joint coming back too fast is what slows it); inside, there is none.
    fn update_anchor(&mut self, lim: &ferrobot_protocol::JointLimits) {
        let q = self.state.position;
        if !self.measured || !q.is_finite() || (lim.min..=lim.max).contains(&q) {
            self.anchor = None;
            return;
        }
        let inward = |a: f32| if q > lim.max { a.min(q) } else { a.max(q) };
        self.anchor = Some(match self.anchor {
            // Braked: it stays where it was, so goals may stay behind the joint. Under an
            // emergency stop too: the joint is held where it stopped, not let back in by a
            // load.
            Some(a) if self.braking || self.stopped => a,
            // Same side: only ever back in.
            Some(a) if (a > lim.max) == (q > lim.max) => inward(a),
            _ => q,
        });
    }

    /// Forget the anchor: the joint's situation changed (new limits, new mode), and it is
    /// found again where it is at the next tick.
    pub fn reset_anchor(&mut self) {
        self.anchor = None;
    }

    /// Position mode: the goal offset that carried the modelled gravity load at the last tick,
    /// rad (within [`position_reach`] at rest).
    pub fn feed_forward(&self) -> f32 {
        self.feed_forward
    }

    /// The position command of the last tick (rad), and whether the joint is being braked.
    pub fn command(&self) -> (f32, bool) {
        (self.cmd, self.braking)
    }

    /// Knots still queued.
    pub fn queued(&self) -> usize {
        self.queue.len()
    }

    /// Forget the queue and the direct command; hold at `q` (rad).
    pub fn hold_at(&mut self, now: Instant, q: f32) {
        self.queue.clear();
        self.direct = None;
        self.integral = 0.0;
        self.cmd = q;
        self.seg_start = Knot {
            t: now,
            q,
            qd: 0.0,
            eff: 0.0,
        };
    }

    /// The joint's first measurement: from now on it starts from where it really is. Knots
    /// already queued are kept (the trajectory to them starts here); an idle joint holds here.
    pub fn first_measurement(&mut self, now: Instant, q: f32) {
        if self.queue.is_empty() && self.direct.is_none() {
            self.hold_at(now, q);
        } else {
            self.cmd = q;
            self.seg_start = Knot {
                t: now,
                q,
                qd: 0.0,
                eff: self.seg_start.eff,
            };
        }
    }

    /// Stop the motion where the joint is measured to be (or was commanded, if never
    /// measured, or where it is being braked towards: a joint running on under a load is not
    /// let go).
    pub fn hold_here(&mut self, now: Instant) {
        if self.braking {
            let q = self.cmd;
            self.hold_at(now, q);
        } else {
            self.hold_measured(now);
        }
    }

    /// Hold where the joint is measured to be (or was commanded, if never measured).
    fn hold_measured(&mut self, now: Instant) {
        let q = if self.measured {
            self.state.position
        } else {
            self.cmd
        };
        self.hold_at(now, q);
    }

    /// The anchor of a joint outside its limits (see [`JointControl::anchor`] on the field).
    pub fn anchor(&self) -> Option<f32> {
        self.anchor
    }

    /// Whether a joint in velocity, current or PWM mode has left its limits and must be
    /// stopped (see [`STOP_SPEED_BASE`]).
    pub fn must_stop(&self, lim: &ferrobot_protocol::JointLimits) -> bool {
        let (gain, cap) = match self.mode {
            JointMode::Velocity => (LIMIT_APPROACH_GAIN, STOP_SPEED_MARGIN_VELOCITY),
            JointMode::Current | JointMode::Pwm => (GUARD_APPROACH_GAIN, STOP_SPEED_MARGIN),
            _ => return false,
        };
        let margin = (0.5 * lim.velocity + STOP_SPEED_BASE).min(cap);
        if !self.measured {
            return false;
        }
        let (q, qd) = (self.state.position, self.state.velocity);
        let (down, up) = envelope(q, lim, gain);
        let too_fast = qd > up + margin || qd < down - margin;
        let out_high = q > lim.max + STOP_OUTSIDE && qd >= 0.0;
        let out_low = q < lim.min - STOP_OUTSIDE && qd <= 0.0;
        too_fast || out_high || out_low
    }

    /// Switch mode; the joint holds where it is.
    pub fn set_mode(&mut self, now: Instant, mode: JointMode) {
        // The mode it is in already: it holds where it is told to be now (the command in
        // position mode, the reference of the joint PID in the others; where it is, when a
        // direct command drove it), and keeps what it learned of its load
        // (the load correction, the PID's integral, the effort ramp's start, the anchor of a
        // joint outside its limits). Held where it was measured instead, with all that
        // forgotten, a loaded joint sagged a little further at every repeated SetMode, out past
        // its limits (issue 48's pointed streams: 0.96 rad).
        if mode == self.mode {
            let told = match mode {
                _ if self.direct.is_some() || !self.measured => None,
                JointMode::Position => Some(self.cmd),
                _ => Some(self.reference(now).q),
            };
            let integral = self.integral;
            match told.filter(|q| q.is_finite()) {
                Some(q) => self.hold_at(now, q),
                None => self.hold_measured(now),
            }
            self.integral = integral;
            return;
        }
        self.mode = mode;
        self.sag = 0.0;
        self.held_since = None;
        self.effort = None;
        self.braking = false;
        self.brake_way = (0, false);
        self.anchor = None;
        self.hold_measured(now);
    }

    /// Queue a knot `duration` after the last one (or after `now` when idle).
    /// Returns false when the queue is full.
    pub fn push(&mut self, now: Instant, duration: Duration, p: &JointPoint) -> bool {
        if self.queue.is_full() {
            return false;
        }
        let start = match self.queue.back() {
            Some(k) => k.t,
            None => {
                // After a direct command (an effort, a PWM duty or a speed) the joint went
                // where that took it: the trajectory starts from where it is measured, not
                // from the hold point before (which would yank it back there).
                if self.direct.is_some() && self.measured && self.state.position.is_finite() {
                    self.cmd = self.state.position;
                    self.integral = 0.0;
                }
                let r = self.reference(now);
                self.seg_start = Knot {
                    t: now,
                    q: self.cmd,
                    qd: 0.0,
                    eff: r.eff,
                };
                now
            }
        };
        self.direct = None;
        self.queue
            .push_back(Knot {
                t: start + duration,
                q: p.position,
                qd: p.velocity,
                eff: p.effort,
            })
            .is_ok()
    }

    /// Set the direct command (velocity, effort or PWM, by mode).
    pub fn set_direct(&mut self, value: f32) {
        self.queue.clear();
        self.direct = Some(value);
    }

    /// The interpolated reference at `now`, popping knots already passed.
    pub fn reference(&mut self, now: Instant) -> Reference {
        while let Some(k) = self.queue.front() {
            if k.t <= now {
                self.seg_start = *k;
                self.queue.pop_front();
            } else {
                break;
            }
        }
        match self.queue.front() {
            Some(next) => hermite(&self.seg_start, next, now),
            None => Reference {
                q: self.seg_start.q,
                qd: 0.0,
                eff: self.seg_start.eff,
            },
        }
    }

    /// The joint PID on the interpolated reference (clamped into the limits), with its
    /// feed-forward and anti-windup integral, N·m.
    fn pid(&mut self, now: Instant, dt: f32, cfg: &JointConfig) -> f32 {
        let lim = &cfg.limits;
        let (q, qd) = (self.state.position, self.state.velocity);
        let r = self.reference(now);
        let e = r.q.clamp(lim.min, lim.max) - q;
        let p = cfg.pid.kp * e + cfg.pid.kd * (r.qd - qd) + r.eff;
        let i_next = (self.integral + cfg.pid.ki * e * dt).clamp(-cfg.pid.i_limit, cfg.pid.i_limit);
        // Anti-windup: integrate only while the output is not saturated, or when integrating
        // drives it back out of saturation.
        let unsat = (p + i_next).abs() <= lim.effort;
        if unsat || (i_next.abs() < self.integral.abs()) {
            self.integral = i_next;
        }
        p + self.integral
    }

    /// Run one control tick of length `dt` (s) for joint `cfg`; returns what to command.
    pub fn tick(&mut self, now: Instant, dt: f32, cfg: &JointConfig) -> JointOutput {
        let lim = &cfg.limits;
        let q = self.state.position;
        let qd = self.state.velocity;
        self.update_anchor(lim);
        let mut clamped = false;
        self.feed_forward = 0.0;
        let out = match self.mode {
            JointMode::Off => JointOutput::None,
            JointMode::Position => {
                let r = self.reference(now);
                // The modelled gravity load rides in the goal: the servo's proportional loop
                // gives the holding effort at the commanded position.
                let model = self.gravity.filter(|t| t.is_finite());
                let ff = model.map_or(0.0, |t| goal_offset_for_effort(cfg, -t));
                self.feed_forward = ff;
                let target = if self.stopped {
                    self.cmd
                } else {
                    r.q.clamp(lim.min, lim.max)
                };
                clamped |= target != r.q;
                // Between two setpoints of a slow loop the servo catches up with a step of the
                // command faster than the command moves: that is not running away.
                let factor = BRAKE_SPEED_FACTOR.max(dt / SERVO_TIME_CONSTANT);
                let fast = lim.velocity * factor + BRAKE_SPEED_ABS;
                let leaving =
                    (q > lim.max && qd > LEAVING_SPEED) || (q < lim.min && qd < -LEAVING_SPEED);
                self.fast_ticks = match (qd.abs() > fast, qd > 0.0) {
                    (true, true) => self.fast_ticks.max(0).saturating_add(1),
                    (true, false) => self.fast_ticks.min(0).saturating_sub(1),
                    (false, _) => 0,
                };
                let runaway = self.fast_ticks.unsigned_abs() >= FAST_TICKS;
                let mut held = false;
                if self.measured && (runaway || leaving) {
                    // Brake: the goal stays behind the joint (at least its speed times
                    // BRAKE_TIME, and as far as the joint has since run on), so the servo
                    // pushes back harder the further it goes; once it has slowed down, the
                    // command is brought near where it is, so it never races back to a
                    // command it left far behind.
                    // The goal never moves the way the joint runs.
                    // The load correction becomes part of the goal, so the goal the servo
                    // holds against its load does not jump when braking starts.
                    self.cmd += core::mem::take(&mut self.sag);
                    let behind =
                        q - qd.signum() * (qd.abs() * BRAKE_TIME).clamp(BRAKE_MIN, BRAKE_OFFSET);
                    self.cmd = if qd > 0.0 {
                        self.cmd.min(behind)
                    } else {
                        self.cmd.max(behind)
                    };
                    if !self.braking {
                        let way = if qd > 0.0 { 1 } else { -1 };
                        self.brake_way = (way, way == self.brake_way.0);
                    }
                    self.braking = true;
                    clamped = true;
                } else {
                    if core::mem::take(&mut self.braking) {
                        // Where the joint came to rest; outside its limits keeping up to
                        // BRAKE_HOLD of the goal offset that stopped it (the load that pushed
                        // it out may need it to hold there).
                        // Under an emergency stop too: the arm must stay where it stopped,
                        // and a goal where it is would let its load carry it on, brake after
                        // brake.
                        let outside = q < lim.min || q > lim.max;
                        let kept = self.cmd.clamp(q - BRAKE_HOLD, q + BRAKE_HOLD);
                        self.cmd = if model.is_some() {
                            // The model carries the load: the brake lets go where the joint
                            // rests, with no offset of its own left to pull it on.
                            self.sag = 0.0;
                            q
                        } else if self.stopped {
                            // Stopped: the joint is held where it came to rest, and the goal
                            // offset that stopped it becomes its load correction (the goal
                            // does not jump; the correction then holds it here, it does not
                            // pull it on to where the brake put its goal).
                            self.sag = kept - q;
                            q
                        } else if outside {
                            kept
                        } else {
                            // Without a model, a joint braked the same way twice in a row is
                            // carried by a load, and the offset that stopped it may be all
                            // that holds it: it becomes the load correction, which the
                            // integrator then refines (a goal where the joint rests let a
                            // loaded joint run on, brake after brake, at the brake's
                            // threshold: twice the strict checker's bound at 0.05 rad/s).
                            // Once only, or each way in turn, it was momentum: taking the
                            // offset over would throw it back the other way, brake after
                            // brake (1.28 rad/s against 0.77, broad seed 20064).
                            if self.brake_way.1 {
                                self.sag = kept - q;
                            }
                            q
                        };
                    }
                    let step = lim.velocity * dt;
                    let delta = target - self.cmd;
                    if delta.abs() > step {
                        clamped |= !self.queue.is_empty() || delta.abs() > step * 1.5;
                    }
                    // A joint measured faster than its velocity limit towards its command
                    // (a motor racing across the gear backlash towards a goal a brake left
                    // behind) has that command brought within its lead at once.
                    let lead = position_lead(cfg);
                    if self.measured && q.is_finite() && qd.abs() > lim.velocity && lead > 0.0 {
                        if qd > 0.0 && self.cmd > q + lead {
                            self.cmd = q + lead;
                        } else if qd < 0.0 && self.cmd < q - lead {
                            self.cmd = q - lead;
                        }
                    }
                    let delta = target - self.cmd;
                    let next = self.cmd + delta.clamp(-step, step);
                    // The command never leads the joint by more than the servo's tracking lag
                    // at the velocity limit: a joint held back (gear backlash, stiction, a
                    // load) is not left with a goal far ahead that it then races to. It is
                    // only held back, never pulled back (the load correction holds the rest).
                    let free = next;
                    self.cmd = if !self.measured || !q.is_finite() || lead <= 0.0 {
                        next
                    } else if next > self.cmd {
                        next.min((q + lead).max(self.cmd))
                    } else {
                        next.max((q - lead).min(self.cmd))
                    };
                    held = self.cmd != free;
                }
                // Settled: the command has reached a target that stays put (no knot left, or
                // the reference held at a limit).
                // Or held back by the joint: a load (or an obstacle) it must push against.
                let settled = ((self.queue.is_empty() || target != r.q)
                    && (target - self.cmd).abs() < 1e-6)
                    || held;
                // Outside its limits a loaded joint must not sag further out: the correction
                // runs there too, on the way back.
                let outside = q < lim.min || q > lim.max;
                // Held back and standing still for a while: stalled against a load the model
                // does not know.
                // Held back: its command near the lead's end, ahead of it (one encoder tick
                // of give lets the command step on once, that is not catching up). Once
                // stalled it stays so while it is held back (pushing harder against an
                // obstacle's give moves it a little) and, once the command stops pushing (the
                // host gave up on the motion and holds it where it is: the obstacle is still
                // there), until it has moved that share of its lead from where it was last
                // held back (the obstacle gave way); speed readings alone would let the noise
                // of a joint pressed against an obstacle free it.
                let lead = position_lead(cfg);
                let held_back = lead > 0.0 && (self.cmd - q).abs() >= STALL_LEAD_SHARE * lead;
                let still = qd.is_finite() && qd.abs() < STALL_SPEED;
                let stalled_before = self.held_since.is_some_and(|t| now - t >= STALL_TIME);
                let moved = !q.is_finite() || (q - self.stall_q).abs() > STALL_LEAD_SHARE * lead;
                if held_back {
                    self.stall_q = q;
                }
                self.held_since = if held_back && (still || stalled_before) {
                    Some(self.held_since.unwrap_or(now))
                } else if stalled_before && !moved {
                    self.held_since
                } else {
                    None
                };
                let stalled = self.held_since.is_some_and(|t| now - t >= STALL_TIME);
                // With a model the correction only mends its error; without one (or stalled),
                // it carries the whole load.
                let bound = match model {
                    Some(_) if !stalled => SAG_MODEL_SHARE * ff.abs() + SAG_MODEL_MIN,
                    _ => SAG_MAX,
                };
                if (settled || (outside && !self.stopped)) && self.measured && cfg.position_ki > 0.0
                {
                    self.sag += cfg.position_ki * (self.cmd - q) * dt;
                }
                self.sag = self.sag.clamp(-bound, bound);
                // The goal stays within the limits, or between them and a joint outside them:
                // never further out than the joint is.
                // The model's offset may carry the goal beyond that by itself: the goal
                // that holds the joint at a limit against its load lies beyond the limit.
                let (lo, hi) = position_goal_window(
                    lim,
                    self.anchor,
                    self.braking,
                    (q, qd),
                    position_reach(cfg, qd),
                );
                let (lo, hi) = (lo + ff.min(0.0), hi + ff.max(0.0));
                JointOutput::Position((self.cmd + ff + self.sag).clamp(lo, hi))
            }
            JointMode::Current | JointMode::Pwm if !self.measured => JointOutput::None,
            JointMode::Current | JointMode::Pwm => {
                let spec = cfg.model.spec();
                let asked = match (self.mode, self.direct) {
                    (JointMode::Pwm, Some(p)) => spec.effort_for_pwm_fraction(p, qd),
                    (_, Some(t)) => t,
                    // No direct command: the joint PID tracks the reference (or holds).
                    (_, None) => self.pid(now, dt, cfg),
                };
                let tau = asked.clamp(-lim.effort, lim.effort);
                let servos = if cfg.twin_id.is_some() { 2.0 } else { 1.0 };
                let strength = servos * spec.stall_torque;
                // The effort ramps from what held the joint before (its modelled load, in
                // position mode) rather than stepping.
                let from = self
                    .effort
                    .filter(|e| e.is_finite())
                    .unwrap_or_else(|| self.gravity.filter(|g| g.is_finite()).map_or(0.0, |g| -g));
                let ramp = strength / EFFORT_RAMP_TIME * dt;
                let tau = tau.clamp(from - ramp, from + ramp);
                let t = guard_effort(tau, (q, qd), lim, strength, dt, self.stopped);
                self.effort = Some(t);
                clamped |= t != asked;
                if self.mode == JointMode::Pwm {
                    JointOutput::PwmEffort(t, qd)
                } else {
                    JointOutput::Effort(t, qd)
                }
            }
            JointMode::Velocity => {
                let v0 = self.direct.unwrap_or(VELOCITY_HOLD_GAIN * (self.cmd - q));
                let (down, up) = if self.stopped {
                    (-lim.velocity, lim.velocity)
                } else {
                    envelope(q, lim, LIMIT_APPROACH_GAIN)
                };
                let v = v0.clamp(down, up);
                clamped |= self.direct.is_some_and(|d| d != v);
                JointOutput::Velocity(v)
            }
            // A mode added to the protocol later: leave the servo alone until this core knows it.
            _ => JointOutput::None,
        };
        self.clamped = clamped;
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hermite_meets_knots_and_slopes() {
        let a = Knot {
            t: Instant::ZERO,
            q: 0.0,
            qd: 0.0,
            eff: 0.0,
        };
        let b = Knot {
            t: Instant::from_secs(1),
            q: 1.0,
            qd: 0.0,
            eff: 2.0,
        };
        assert_eq!(hermite(&a, &b, Instant::ZERO).q, 0.0);
        assert!((hermite(&a, &b, Instant::from_secs(1)).q - 1.0).abs() < 1e-6);
        let mid = hermite(&a, &b, Instant::from_millis(500));
        assert!((mid.q - 0.5).abs() < 1e-6);
        assert!((mid.qd - 1.5).abs() < 1e-4, "{}", mid.qd); // peak speed of a cubic: 1.5·Δq/T
        assert!((mid.eff - 1.0).abs() < 1e-6);
    }

    /// A trajectory sent after a direct effort moved the joint starts where the joint is
    /// (it started from the hold point before the effort: 0.6 rad away).
    #[test]
    fn a_trajectory_after_a_direct_command_starts_where_the_joint_is() {
        let mut j = JointControl::new();
        j.state.position = 0.0;
        j.measured = true;
        j.set_mode(Instant::ZERO, JointMode::Current);
        j.set_direct(0.3);
        // The effort took the joint here.
        j.state.position = 0.6;
        let now = Instant::from_millis(100);
        assert!(j.push(now, Duration::from_secs(1), &JointPoint::at_rest(0.8)));
        let r = j.reference(now);
        assert!((r.q - 0.6).abs() < 1e-6, "starts at {}", r.q);
    }

    #[test]
    fn position_reference_is_rate_limited_and_clamped() {
        let cfg = crate::config::locobot().joints[0].clone();
        let mut j = JointControl::new();
        j.set_mode(Instant::ZERO, JointMode::Position);
        assert!(j.push(Instant::ZERO, Duration::ZERO, &JointPoint::at_rest(5.0)));
        let mut last = 0.0;
        for k in 1..=3000u64 {
            if let JointOutput::Position(p) = j.tick(Instant::from_millis(k), 1e-3, &cfg) {
                assert!(p - last <= cfg.limits.velocity * 1e-3 + 1e-6);
                last = p;
            }
        }
        assert!((last - cfg.limits.max).abs() < 1e-5, "{last}");
    }

    #[test]
    fn queue_is_bounded() {
        let mut j = JointControl::new();
        j.set_mode(Instant::ZERO, JointMode::Position);
        let p = JointPoint::at_rest(0.1);
        for _ in 0..QUEUE_LEN {
            assert!(j.push(Instant::ZERO, Duration::from_millis(1), &p));
        }
        assert!(!j.push(Instant::ZERO, Duration::from_millis(1), &p));
    }
}
