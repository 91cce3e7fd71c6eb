//! Per-joint control state: the setpoint queue with cubic Hermite interpolation, the
//! reference rate limiter, the joint PID with anti-windup, and limit enforcement. Joint
//! space: rad, rad/s, N·m, as the robot description defines the joint.

use ferrobot_protocol::{JointLimits, JointMode, JointState};
use heapless::Deque;

use crate::time::Instant;

mod limits;
mod modes;
mod position;
mod servo_model;
mod teach;
mod trajectory;

pub use limits::*;
pub use modes::{EFFORT_RAMP_TIME, VELOCITY_HOLD_GAIN};
pub use position::{
    goal_window_extension, SAG_MAX, SAG_MODEL_MIN, SAG_MODEL_SHARE, STALL_LEAD_SHARE, STALL_SPEED,
    STALL_TIME,
};
pub use servo_model::*;
pub use teach::{TEACH_DEADBAND, TEACH_GAIN, TEACH_MODEL_SHARE};
pub use trajectory::*;

/// Knots a joint can queue.
pub const QUEUE_LEN: usize = 16;

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
    /// The trusted model's load at the measured pose (N·m), whether or not this joint has
    /// borne it out yet: teach mode tells a hand from it. `None` without a trusted model.
    pub model_load: Option<f32>,
    /// Position mode: the goal offset that carries the modelled load, rad (last tick).
    feed_forward: f32,
    /// Position mode: whether the last tick had a trusted model (its offset and the load
    /// correction hand the load over when that changes).
    modelled: bool,
    /// Teach mode: whether a hand pushed the joint at the last tick.
    teach_push: bool,
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
            model_load: None,
            feed_forward: 0.0,
            modelled: false,
            teach_push: false,
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
    fn update_anchor(&mut self, lim: &JointLimits) {
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

    /// A measurement that replaces what the joint was believed to be (its first, or its servo's
    /// first after it was lost or rebooted, its torque maybe off meanwhile): from now on it
    /// starts from where it really is. Knots already queued are kept (the trajectory to them
    /// starts here); an idle joint holds here, not where it stood before.
    pub fn measured_afresh(&mut self, now: Instant, q: f32) {
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

    /// Whether the joint is held still in position mode with nothing to do: [`at_rest`] and
    /// not held back from its command (an obstacle, a payload's stall); its measured effort is
    /// then its load.
    ///
    /// [`at_rest`]: JointControl::at_rest
    pub fn holding_still(&self, cfg: &ferrobot_protocol::JointConfig) -> bool {
        let lead = position_lead(cfg);
        self.at_rest()
            && self.held_since.is_none()
            && (self.cmd - self.state.position).abs() < STALL_LEAD_SHARE * lead
    }

    /// Whether the joint rests in position mode with nothing to do: measured, its queue empty,
    /// not braked, slower than [`STALL_SPEED`], its effort measured. Held back from its command
    /// or not: a wrong gravity model displaces a joint from its command by its own error.
    pub fn at_rest(&self) -> bool {
        let qd = self.state.velocity;
        self.mode == JointMode::Position
            && self.measured
            && self.queue.is_empty()
            && self.direct.is_none()
            && !self.braking
            && qd.is_finite()
            && qd.abs() < STALL_SPEED
            && self.state.effort.is_finite()
    }

    /// Whether a joint in velocity, current or PWM mode has left its limits and must be
    /// stopped (see [`STOP_SPEED_BASE`]).
    pub fn must_stop(&self, lim: &JointLimits) -> bool {
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

    /// The effort the joint was last measured giving, N·m, when measured and finite.
    fn measured_effort(&self) -> Option<f32> {
        let e = self.state.effort;
        (self.measured && e.is_finite()).then_some(e)
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
        // Between position and teach mode the servo's loop goes on as it was: the joint keeps
        // its load correction, its brake and what it learned of a stall, and holds where it
        // was told to be (a loaded joint whose correction was dropped would sag).
        let position_like = |m| matches!(m, JointMode::Position | JointMode::Teach);
        if position_like(mode) && position_like(self.mode) {
            self.mode = mode;
            self.teach_push = false;
            let cmd = self.cmd;
            let integral = self.integral;
            self.hold_at(
                now,
                if cmd.is_finite() {
                    cmd
                } else {
                    self.state.position
                },
            );
            self.integral = integral;
            return;
        }
        self.mode = mode;
        self.sag = 0.0;
        self.teach_push = false;
        self.held_since = None;
        // The torque modes' ramp starts from what held the joint: the modelled load (at the
        // first tick; a model is trusted only once the arm bears it out) or, without a
        // trusted model, the effort the joint was last measured giving (a moving or braked
        // joint's is not its load, so the model's is preferred). From nothing, a loaded joint
        // of an arm without a model handed from position mode to current mode dropped faster
        // than its speed limit before the guard could brake it (a LoCoBot-Lite without its
        // model, pointed stream 10008: 0.234 rad/s against 0.229).
        self.effort = match self.gravity.filter(|g| g.is_finite()) {
            Some(_) => None,
            None => self.measured_effort(),
        };
        self.braking = false;
        self.brake_way = (0, false);
        self.anchor = None;
        self.hold_measured(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::Duration;
    use ferrobot_protocol::{JointConfig, JointPoint};
    use limits::{BRAKE_RELEASE_SHARE, BRAKE_SPEED_ABS, BRAKE_SPEED_FACTOR};

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

    /// Without a model, a loaded joint handed from position mode to current mode starts from
    /// the effort it was measured holding, not from nothing; one that held nothing (or more
    /// than its limit) starts from that (or its limit).
    #[test]
    fn torque_modes_ramp_from_the_measured_holding_effort_without_a_model() {
        let cfg = crate::config::locobot().joints[1].clone();
        for (held, starts_at) in [(-1.2f32, -1.2f32), (0.0, 0.0), (-50.0, -cfg.limits.effort)] {
            let mut j = JointControl::new();
            j.set_mode(Instant::ZERO, JointMode::Position);
            j.state = JointState {
                position: 0.5,
                velocity: 0.0,
                effort: held,
            };
            j.measured = true;
            j.gravity = None;
            j.set_mode(Instant::ZERO, JointMode::Current);
            j.set_direct(0.0);
            let JointOutput::Effort(t, _) = j.tick(Instant::from_millis(1), 1e-3, &cfg) else {
                panic!("current mode commands an effort");
            };
            // One tick's ramp away from where it started, towards the asked 0 N·m.
            let servos = if cfg.twin_id.is_some() { 2.0 } else { 1.0 };
            let ramp = servos * cfg.model.spec().stall_torque / EFFORT_RAMP_TIME * 1e-3;
            assert!(
                (t - starts_at).abs() <= ramp + 1e-6 && t.abs() <= starts_at.abs(),
                "held {held} N·m: first effort {t} N·m, expected within {ramp} of {starts_at}"
            );
        }
    }

    /// A position-mode joint at `q` (rad) moving at `qd` (rad/s) under a trusted model of
    /// `gravity` (N·m), its velocity limit `v` (rad/s), with limits well below it.
    fn moving_joint(q: f32, qd: f32, gravity: f32, v: f32) -> (JointControl, JointConfig) {
        let mut cfg = crate::config::locobot().joints[1].clone();
        cfg.limits.min = -0.2;
        cfg.limits.max = 0.2;
        cfg.limits.velocity = v;
        let mut j = JointControl::new();
        j.state = JointState {
            position: q,
            velocity: qd,
            effort: 0.4,
        };
        j.measured = true;
        j.set_mode(Instant::ZERO, JointMode::Position);
        j.gravity = Some(gravity);
        j.model_load = Some(gravity);
        (j, cfg)
    }

    /// A joint rising out of its limits that its model says is loaded far more than it is:
    /// the brake's goal lies at or behind the joint, the model's offset does not carry it
    /// ahead again (pointed seed 707: 0.3 rad/s away from its limits, on and on).
    #[test]
    fn a_brake_goal_is_never_ahead_of_the_joint_whatever_the_model_says() {
        let (mut j, cfg) = moving_joint(0.7, 0.0, -3.0, 0.1);
        // At rest first: the model takes the load over from the load correction.
        j.tick(Instant::from_millis(1), 1e-3, &cfg);
        j.state.velocity = 0.3;
        for k in 2..=4u64 {
            let out = j.tick(Instant::from_millis(k), 1e-3, &cfg);
            assert!(j.command().1, "tick {k}: not braking");
            let JointOutput::Position(goal) = out else {
                panic!("position mode commands a position");
            };
            assert!(
                goal <= 0.7,
                "tick {k}: goal {goal} rad ahead of the joint at 0.7 rad (offset {}, command {:?})",
                j.feed_forward(),
                j.command()
            );
        }
        // The model's offset is real: ahead of the command while not braking.
        assert!(j.feed_forward() > 0.01, "offset {} rad", j.feed_forward());
    }

    /// A braked joint is let go only once well below the speed that braked it (a joint dragged
    /// on would otherwise speed up again at once: pointed seed 709).
    #[test]
    fn a_brake_lets_go_below_the_speed_that_engaged_it() {
        let v = 0.055;
        let engage = v * BRAKE_SPEED_FACTOR + BRAKE_SPEED_ABS;
        let release = v * BRAKE_SPEED_FACTOR + BRAKE_RELEASE_SHARE * BRAKE_SPEED_ABS;
        let (mut j, cfg) = moving_joint(0.0, -(engage + 0.02), 0.0, v);
        for (k, qd, braking) in [
            (1u64, -(engage + 0.02), false),
            (2, -(engage + 0.02), true),
            (3, -(engage - 0.01), true),
            (4, -(release + 0.01), true),
            (5, -(release - 0.01), false),
        ] {
            j.state.velocity = qd;
            j.tick(Instant::from_millis(k), 1e-3, &cfg);
            assert_eq!(j.command().1, braking, "tick {k} at {qd} rad/s");
        }
    }

    /// A joint outside its limits, held back against a load bringing it back, may have its
    /// goal beyond it by that load's offset, the way its servos push, and no further; inside
    /// its limits, only the model's offset, within the load borne, carries the goal beyond.
    #[test]
    fn a_goal_may_hold_a_load_beyond_the_window_only_as_far_as_the_load_needs() {
        let cfg = crate::config::locobot().joints[2].clone();
        let need = |e: f32| goal_offset_for_effort(&cfg, crate::dynamics::supported(e));
        // Outside, pushing up against 1 N·m: above by that load's offset only.
        let (below, above) = goal_window_extension(&cfg, true, 1.0, 0.0);
        assert_eq!(below, 0.0);
        assert!(
            above > 0.0 && (above - need(1.0)).abs() < 1e-6,
            "{above} rad"
        );
        // Pushing down: below.
        let (below, above) = goal_window_extension(&cfg, true, -1.0, 0.0);
        assert!(
            (below + need(1.0)).abs() < 1e-6 && above == 0.0,
            "{below} rad"
        );
        // Inside: nothing for the load; the model's offset, within the load borne.
        assert_eq!(goal_window_extension(&cfg, false, 1.0, 0.0), (0.0, 0.0));
        let (_, above) = goal_window_extension(&cfg, false, 0.1, 1.0);
        assert!(
            (above - need(0.1)).abs() < 1e-6,
            "{above} rad for an offset of 1 rad"
        );
        // Nothing finite, nothing beyond.
        let (below, above) = goal_window_extension(&cfg, true, 0.0, f32::NAN);
        assert!(below <= 0.0 && above >= 0.0 && (above - below) <= need(0.0) + 1e-6);
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
