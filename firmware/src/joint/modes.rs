//! One control tick of a joint, by mode: position mode (see `position`), the torque modes
//! (current and PWM: the joint PID or a direct effort, ramped and guarded within the joint's
//! speed envelope) and velocity mode (a direct speed, or a hold, within that envelope).
//! Joint space: rad, rad/s, N·m; `dt` in s.

use ferrobot_protocol::{JointConfig, JointMode};

use super::limits::{envelope, guard_effort, LIMIT_APPROACH_GAIN};
use super::{JointControl, JointOutput};
use crate::time::Instant;

/// Velocity mode, holding (no command): speed (rad/s) per rad of error towards the hold point.
pub const VELOCITY_HOLD_GAIN: f32 = 2.0;
/// Current and PWM modes: the effort ramps from what the joint held at the mode change to its
/// full strength in at least this long, s (a step of torque would outrun the guard's braking).
pub const EFFORT_RAMP_TIME: f32 = 0.1;

impl JointControl {
    /// Run one control tick of length `dt` (s) for joint `cfg`; returns what to command.
    pub fn tick(&mut self, now: Instant, dt: f32, cfg: &JointConfig) -> JointOutput {
        self.update_anchor(&cfg.limits);
        let mut clamped = false;
        let last_ff = core::mem::take(&mut self.feed_forward);
        let out = match self.mode {
            JointMode::Off => JointOutput::None,
            JointMode::Position => self.tick_position(now, dt, cfg, last_ff, &mut clamped),
            JointMode::Teach => {
                self.teach(now, dt, cfg);
                self.tick_position(now, dt, cfg, last_ff, &mut clamped)
            }
            JointMode::Current | JointMode::Pwm if !self.measured => JointOutput::None,
            JointMode::Current | JointMode::Pwm => self.tick_effort(now, dt, cfg, &mut clamped),
            JointMode::Velocity => self.tick_velocity(cfg, &mut clamped),
            // A mode added to the protocol later: leave the servo alone until this core knows it.
            _ => JointOutput::None,
        };
        self.clamped = clamped;
        out
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

    /// One tick of the torque modes: the effort (N·m) asked (directly, or by the joint PID),
    /// ramped and guarded; `clamped` is set when that changed it.
    fn tick_effort(
        &mut self,
        now: Instant,
        dt: f32,
        cfg: &JointConfig,
        clamped: &mut bool,
    ) -> JointOutput {
        let lim = &cfg.limits;
        let q = self.state.position;
        let qd = self.state.velocity;
        let spec = cfg.model.spec();
        let asked = match (self.mode, self.direct) {
            (JointMode::Pwm, Some(p)) => spec.effort_for_pwm_fraction(p, qd),
            (_, Some(t)) => t,
            // No direct command: the joint PID tracks the reference (or holds), with the
            // trusted model's load added.
            (_, None) => {
                let load = self.gravity.filter(|g| g.is_finite()).unwrap_or(0.0);
                self.pid(now, dt, cfg) - load
            }
        };
        let tau = asked.clamp(-lim.effort, lim.effort);
        let servos = if cfg.twin_id.is_some() { 2.0 } else { 1.0 };
        let strength = servos * spec.stall_torque;
        // The effort ramps from what held the joint before (its modelled load, or the
        // effort it was measured giving; within the effort limit) rather than stepping.
        let from = self
            .effort
            .filter(|e| e.is_finite())
            .unwrap_or_else(|| self.gravity.filter(|g| g.is_finite()).map_or(0.0, |g| -g))
            .clamp(-lim.effort, lim.effort);
        let ramp = strength / EFFORT_RAMP_TIME * dt;
        let tau = tau.clamp(from - ramp, from + ramp);
        let t = guard_effort(tau, (q, qd), lim, strength, dt, self.stopped);
        self.effort = Some(t);
        *clamped |= t != asked;
        if self.mode == JointMode::Pwm {
            JointOutput::PwmEffort(t, qd)
        } else {
            JointOutput::Effort(t, qd)
        }
    }

    /// One tick of velocity mode: the speed (rad/s) asked, or a hold, within the envelope;
    /// `clamped` is set when that changed it.
    fn tick_velocity(&mut self, cfg: &JointConfig, clamped: &mut bool) -> JointOutput {
        let lim = &cfg.limits;
        let q = self.state.position;
        let v0 = self.direct.unwrap_or(VELOCITY_HOLD_GAIN * (self.cmd - q));
        let (down, up) = if self.stopped {
            (-lim.velocity, lim.velocity)
        } else {
            envelope(q, lim, LIMIT_APPROACH_GAIN)
        };
        let v = v0.clamp(down, up);
        *clamped |= self.direct.is_some_and(|d| d != v);
        JointOutput::Velocity(v)
    }
}
