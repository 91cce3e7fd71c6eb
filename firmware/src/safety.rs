//! The safety layer, at both ends of the core. Inbound: the emergency stop and the host
//! watchdog, which act in every session state (a refused or lost session is itself a safe
//! state). Outbound: the last gate between every joint controller and the servo bus, which
//! lets a joint's output through only when it is finite and within the joint's position
//! limits (or its way back to them), speed limit and strength, and otherwise holds the joint
//! and reports it. Joint space: rad, rad/s, N·m.

use ferrobot_protocol::{FaultKind, JointConfig, JointLimits, JointMode};

use crate::joint::{self, JointControl, JointOutput};
use crate::time::Instant;
use crate::Firmware;

/// Whether a joint output may reach the servos: finite, within the joint's speed limit, an
/// effort the servos can give (`strength`, N·m), and its position limits (or between them and
/// the `anchor` of a joint outside them, and up to the braking offset beyond it while it is
/// `braking`), extended by `ext` ([`joint::goal_window_extension`]).
fn goal_is_safe(
    out: &JointOutput,
    lim: &JointLimits,
    (anchor, braking): (Option<f32>, bool),
    strength: f32,
    (state, reach): ((f32, f32), f32),
    (below, above): (f32, f32),
) -> bool {
    match *out {
        JointOutput::None => true,
        JointOutput::Position(g) => {
            let (lo, hi) = joint::position_goal_window(lim, anchor, braking, state, reach);
            // The load the joint bears (and the model's offset within it) may carry the goal
            // beyond that.
            let (lo, hi) = (lo + below.min(0.0), hi + above.max(0.0));
            g.is_finite() && (lo..=hi).contains(&g)
        }
        JointOutput::Velocity(v) => v.is_finite() && v.abs() <= lim.velocity,
        // Within what the servos can give (the guard may exceed the effort limit to keep the
        // joint within its position and speed limits).
        JointOutput::Effort(tau, qd) | JointOutput::PwmEffort(tau, qd) => {
            tau.is_finite() && qd.is_finite() && tau.abs() <= strength
        }
    }
}

/// What a joint's output is checked against, taken from the joint after its controller ran.
struct GoalWindow {
    /// The anchor of a joint outside its limits (rad), and whether the joint is being braked.
    anchor: (Option<f32>, bool),
    /// The measured position and speed (NaN before the first measurement), and how far from
    /// there a position goal drives the servo at full PWM, rad.
    window: ((f32, f32), f32),
    /// How far beyond the window a goal may lie for the load the joint bears, rad
    /// ([`joint::goal_window_extension`]).
    ext: (f32, f32),
    /// What the joint's servos can give, N·m.
    strength: f32,
}

impl GoalWindow {
    fn of(jc: &JointControl, cfg: &JointConfig) -> Self {
        let anchor = (jc.anchor(), jc.command().1);
        let state = if jc.measured {
            (jc.state.position, jc.state.velocity)
        } else {
            (f32::NAN, f32::NAN)
        };
        let window = (state, joint::position_reach(cfg, state.1));
        // The model's offset is trusted only within the servos' full-PWM reach at rest.
        let ff = Some(jc.feed_forward())
            .filter(|f| f.is_finite() && f.abs() <= joint::position_reach(cfg, 0.0))
            .unwrap_or(0.0);
        let ext = joint::goal_window_extension(cfg, jc.anchor().is_some(), jc.state.effort, ff);
        let strength =
            cfg.model.spec().stall_torque * if cfg.twin_id.is_some() { 2.0 } else { 1.0 };
        Self {
            anchor,
            window,
            ext,
            strength,
        }
    }

    fn admits(&self, out: &JointOutput, lim: &JointLimits) -> bool {
        goal_is_safe(out, lim, self.anchor, self.strength, self.window, self.ext)
    }
}

impl Firmware {
    /// The watchdog, once armed by an accepted Hello, runs in every session state: a refused
    /// or silent host is a reason to stop, never a way around it.
    pub(crate) fn watchdog_deadline(&self) -> Option<Instant> {
        (!self.watchdog_period.is_zero() && !self.watchdog_tripped)
            .then(|| self.last_host_rx + self.watchdog_period)
    }

    /// Engage the emergency stop: the base stops at once, every joint holds where it is, and
    /// motion is refused until `Resume`.
    pub(crate) fn emergency_stop(&mut self, now: Instant) {
        self.estop = true;
        self.base.stop(now);
        self.base.poll(now);
        self.hold_all(now);
        let gripper = self.gripper.as_ref().map(|(j, _)| *j);
        for (k, j) in self.joints.iter_mut().enumerate() {
            // A joint in a torque mode is held by its servo's own stiff position loop: a
            // torque that only limits its speed would let a load (gravity) carry it on. So is
            // one in velocity mode: the servo's velocity loop brakes softly, and its hold
            // point would let the joint run on past where the stop found it.
            // One in teach mode holds in position mode: a hand no longer moves it.
            if matches!(
                j.mode,
                JointMode::Current | JointMode::Pwm | JointMode::Velocity | JointMode::Teach
            ) && gripper != Some(k)
            {
                j.set_mode(now, JointMode::Position);
            }
            j.stopped = true;
        }
        self.apply_modes();
        self.fault(now, FaultKind::EmergencyStop, None, None, 0);
    }

    /// Leave the emergency stop: motion commands are accepted again.
    pub(crate) fn resume(&mut self) {
        self.estop = false;
        for j in self.joints.iter_mut() {
            j.stopped = false;
        }
    }

    pub(crate) fn trip_watchdog(&mut self, now: Instant) {
        self.watchdog_tripped = true;
        // A host that is gone cannot record what a hand teaches, nor end it.
        self.leave_teach(now);
        self.base.stop(now);
        self.base.poll(now);
        self.hold_all(now);
        self.fault(now, FaultKind::Watchdog, None, None, 0);
    }

    pub(crate) fn hold_all(&mut self, now: Instant) {
        for j in self.joints.iter_mut() {
            j.hold_here(now);
        }
        if let Some((_, g)) = self.gripper.as_mut() {
            g.halt();
        }
    }

    /// The last gate before the bus: an output of joint `j`'s controller that is not finite
    /// or outside the joint's limits never reaches a servo; the joint holds where it is
    /// (what its hold asks, if that passes; else nothing) and the fault is reported, once
    /// until an output passes again. Returns what may go to the servos, and whether the
    /// controller's own output passed.
    pub(crate) fn gate(
        &mut self,
        now: Instant,
        dt: f32,
        j: usize,
        cfg: &JointConfig,
        out: JointOutput,
    ) -> (JointOutput, bool) {
        let bit = 1u16 << (j as u32 % 16);
        let Some(jc) = self.joints.get_mut(j) else {
            return (JointOutput::None, false);
        };
        let window = GoalWindow::of(jc, cfg);
        if window.admits(&out, &cfg.limits) {
            self.unsafe_reported &= !bit;
            return (out, true);
        }
        jc.hold_here(now);
        let held = jc.tick(now, dt, cfg);
        let out = if window.admits(&held, &cfg.limits) {
            held
        } else {
            JointOutput::None
        };
        if self.unsafe_reported & bit == 0 {
            self.unsafe_reported |= bit;
            self.fault(now, FaultKind::UnsafeGoal, Some(j as u8), None, 0);
        }
        (out, false)
    }
}
