//! The servo loop: each tick, once the bus has read every servo, the joints are measured
//! (servo ticks to joint rad, rad/s and N·m through each row's sign and offset), the gravity
//! model gives their loads, each joint's controller runs and its output, past the safety gate,
//! becomes its servos' goals; the servos' modes follow the joints'. Bus events (lost,
//! recovered, hardware errors) hold the joint concerned and are reported.

use ferrobot_protocol::dxl::units;
use ferrobot_protocol::{
    ranges, FaultKind, GripperState, JointConfig, JointMode, JointState, MAX_JOINTS,
};
use heapless::Vec;

use crate::bus::{self, BusEvent, Goal, ServoStatus};
use crate::gripper::GripperDrive;
use crate::joint::JointOutput;
use crate::time::Instant;
use crate::Firmware;

impl Firmware {
    /// Hold the joint of every servo the bus reports lost, failed or faulty, report it, and
    /// note which servos are lost.
    pub(crate) fn drain_bus_events(&mut self, now: Instant) {
        while let Some(e) = self.bus.pop_event() {
            let (i, kind, code) = match e {
                BusEvent::Lost(i) => (i, FaultKind::ServoLost, 0),
                BusEvent::Recovered(i) => (i, FaultKind::ServoRecovered, 0),
                BusEvent::HardwareError(i, bits) => (i, FaultKind::ServoHardware, bits as u16),
                BusEvent::ConfigFailed(i) => (i, FaultKind::ServoConfig, 0),
            };
            let (joint, id) = self
                .bus
                .servos
                .get(i as usize)
                .map(|s| (Some(s.joint), Some(s.id)))
                .unwrap_or((None, None));
            if let Some(j) = joint.and_then(|j| self.joints.get_mut(j as usize)) {
                j.hold_here(now);
            }
            self.fault(now, kind, joint, id, code);
        }
        self.lost_servos = self
            .bus
            .servos
            .iter()
            .enumerate()
            .filter(|(_, s)| s.status == ServoStatus::Lost)
            .fold(0u16, |m, (i, _)| m | (1u16 << (i as u32 % 16)));
    }

    /// Measure, control, write goals.
    pub(crate) fn finish_tick(&mut self, now: Instant) {
        let dt = self.loop_period.as_secs_f32();
        self.measure(now);
        self.report_outside(now);
        self.model_gravity(now);
        let mut goals: Vec<Goal, { bus::MAX_SERVOS }> = Vec::new();
        for _ in 0..self.bus.servos.len() {
            let _ = goals.push(Goal::None);
        }
        for j in 0..self.joints.len() {
            self.control_joint(now, dt, j, &mut goals);
        }
        self.apply_modes();
        self.bus.finish_tick(now, &goals);
        let took = now - self.tick_started;
        let s = &mut self.loop_stats;
        s.ticks = s.ticks.wrapping_add(1);
        s.worst_tick_us = s
            .worst_tick_us
            .max(u32::try_from(took.as_micros()).unwrap_or(u32::MAX));
        if took > self.loop_period {
            s.overruns = s.overruns.saturating_add(1);
            self.overrun_since_telemetry = true;
        }
    }

    /// Report each joint under control found more than [`ranges::OUTSIDE_FAULT`] outside its
    /// limits, once until it is back within half that.
    fn report_outside(&mut self, now: Instant) {
        let gripper = self.gripper.as_ref().map(|(j, _)| *j);
        for j in 0..self.joints.len() {
            let (Some(jc), Some(cfg)) = (self.joints.get(j), self.profile.joints.get(j)) else {
                continue;
            };
            let q = jc.state.position;
            let l = cfg.limits;
            let beyond = (l.min - q).max(q - l.max);
            let watched = jc.measured && jc.mode != JointMode::Off && gripper != Some(j);
            let report = watched && !jc.outside_reported && beyond > ranges::OUTSIDE_FAULT;
            let clear = !watched || beyond < 0.5 * ranges::OUTSIDE_FAULT;
            if let Some(jc) = self.joints.get_mut(j) {
                if report {
                    jc.outside_reported = true;
                } else if clear {
                    jc.outside_reported = false;
                }
            }
            if report {
                let mrad = (beyond * 1000.0).min(u16::MAX as f32) as u16;
                let id = cfg.servo_id;
                self.fault(now, FaultKind::OutsideLimits, Some(j as u8), Some(id), mrad);
            }
        }
    }

    /// The joints' states from the servos read this tick (or at configuration); a joint's first
    /// measurement starts it from where it is.
    fn measure(&mut self, now: Instant) {
        let mut states: [Option<JointState>; MAX_JOINTS] = [None; MAX_JOINTS];
        let mut reread = 0u32;
        for s in self.bus.servos.iter_mut() {
            if core::mem::take(&mut s.reread) && !s.twin {
                reread |= 1 << (s.joint as u32 % 32);
            }
        }
        for s in self.bus.servos.iter() {
            if !(s.fresh || (s.position_valid && !s.twin)) {
                continue;
            }
            let Some(cfg) = self.profile.joints.get(s.joint as usize) else {
                continue;
            };
            let Some(slot) = states.get_mut(s.joint as usize) else {
                continue;
            };
            let sign = cfg.sign as f32;
            let effort = cfg.model.spec().effort_from_register(s.present.current);
            if s.twin {
                if let Some(st) = slot.as_mut() {
                    st.effort += -sign * effort;
                }
            } else {
                let angle = units::tick_to_rad(s.present.position);
                *slot = Some(JointState {
                    position: sign * (angle - cfg.offset),
                    velocity: sign * s.present.velocity as f32 * units::RAD_S_PER_VELOCITY_UNIT,
                    effort: if s.fresh { sign * effort } else { 0.0 },
                });
                if !s.fresh {
                    // Position read during configuration only.
                    if let Some(st) = slot.as_mut() {
                        st.velocity = 0.0;
                    }
                }
            }
        }
        for (j, st) in states.iter().enumerate() {
            let (Some(st), Some(jc)) = (st, self.joints.get_mut(j)) else {
                continue;
            };
            let first = !jc.measured;
            jc.state = *st;
            jc.measured = true;
            if first || reread & (1 << (j as u32 % 32)) != 0 {
                jc.measured_afresh(now, st.position);
            }
        }
    }

    /// The bus indices of joint `joint`'s servo and twin.
    pub(crate) fn servo_indices(&self, joint: usize) -> (Option<usize>, Option<usize>) {
        let mut p = None;
        let mut t = None;
        for (i, s) in self.bus.servos.iter().enumerate() {
            if s.joint as usize == joint {
                if s.twin {
                    t = Some(i);
                } else {
                    p = Some(i);
                }
            }
        }
        (p, t)
    }

    /// Run joint `j`'s controller (or the gripper state machine) and put its goals, past the
    /// safety gate, in `goals` (one per servo).
    fn control_joint(&mut self, now: Instant, dt: f32, j: usize, goals: &mut [Goal]) {
        let Some(cfg) = self.profile.joints.get(j).cloned() else {
            return;
        };
        let (p, t) = self.servo_indices(j);
        let healthy = |i: Option<usize>| {
            i.and_then(|i| self.bus.servos.get(i))
                .is_some_and(|s| s.status == ServoStatus::Ok && s.hw_error == 0)
        };
        if !healthy(p) {
            return;
        }
        let twin_ok = t.is_some() && healthy(t);
        // The gripper state machine drives its servo directly, in servo units.
        if let Some((gj, g)) = self.gripper.as_mut() {
            if *gj == j && g.state != GripperState::Unknown {
                let present = p
                    .and_then(|i| self.bus.servos.get(i))
                    .map(|s| s.present)
                    .unwrap_or_default();
                let drive = g.tick(now, &present);
                if let Some(goal) = p.and_then(|i| goals.get_mut(i)) {
                    *goal = match drive {
                        GripperDrive::Position(tick) => Goal::Position(tick),
                        GripperDrive::Pwm(pwm) => Goal::Pwm(pwm),
                        GripperDrive::Idle => Goal::None,
                    };
                }
                return;
            }
        }
        let Some(jc) = self.joints.get_mut(j) else {
            return;
        };
        // A joint that left its limits in velocity, current or PWM mode is stopped: position
        // mode (the servo's own stiff loop) holds it where it comes to rest.
        if jc.must_stop(&cfg.limits) {
            jc.set_mode(now, JointMode::Position);
            self.fault(now, FaultKind::LimitStop, Some(j as u8), None, 0);
            return;
        }
        let Some(jc) = self.joints.get_mut(j) else {
            return;
        };
        let out = jc.tick(now, dt, &cfg);
        let (out, passed) = self.gate(now, dt, j, &cfg, out);
        self.write_goals(p, t, twin_ok, out, &cfg, goals);
        if passed {
            self.report_clamp(now, j);
        }
    }

    /// Report a limit clamping joint `j`'s command, once per episode.
    fn report_clamp(&mut self, now: Instant, j: usize) {
        let clamped = self.joints.get(j).is_some_and(|jc| jc.clamped);
        let bit = 1u16 << (j as u32 % 16);
        if clamped && self.clamp_reported & bit == 0 {
            self.clamp_reported |= bit;
            self.fault(now, FaultKind::LimitClamped, Some(j as u8), None, 0);
        } else if !clamped {
            self.clamp_reported &= !bit;
        }
    }

    /// Turn a joint's output into the goals of its servo and twin.
    fn write_goals(
        &self,
        p: Option<usize>,
        t: Option<usize>,
        twin_ok: bool,
        out: JointOutput,
        cfg: &JointConfig,
        goals: &mut [Goal],
    ) {
        let sign = cfg.sign as f32;
        let spec = cfg.model.spec();
        let n = if twin_ok { 2.0 } else { 1.0 };
        let (gp, gt) = match out {
            JointOutput::None => (Goal::None, Goal::None),
            JointOutput::Position(q) => {
                let a = sign * q + cfg.offset;
                (
                    Goal::Position(units::rad_to_tick(a)),
                    Goal::Position(units::rad_to_tick(-a)),
                )
            }
            JointOutput::Velocity(v) => {
                let raw = sign * v / units::RAD_S_PER_VELOCITY_UNIT;
                let raw = if raw >= 0.0 { raw + 0.5 } else { raw - 0.5 } as i32;
                (Goal::Velocity(raw), Goal::Velocity(raw.saturating_neg()))
            }
            JointOutput::Effort(tau, qd) | JointOutput::PwmEffort(tau, qd) => {
                // Twins share the effort.
                let ts = sign * tau / n;
                let ws = sign * qd;
                if spec.current_control && matches!(out, JointOutput::Effort(..)) {
                    (
                        Goal::Current(spec.register_from_effort(ts)),
                        Goal::Current(spec.register_from_effort(-ts)),
                    )
                } else {
                    (
                        Goal::Pwm(spec.pwm_for_effort(ts, ws)),
                        Goal::Pwm(spec.pwm_for_effort(-ts, -ws)),
                    )
                }
            }
        };
        if let Some(g) = p.and_then(|i| goals.get_mut(i)) {
            *g = gp;
        }
        if twin_ok {
            if let Some(g) = t.and_then(|i| goals.get_mut(i)) {
                *g = gt;
            }
        }
    }

    /// Push each servo's desired operating mode and torque to the bus.
    pub(crate) fn apply_modes(&mut self) {
        for i in 0..self.bus.servos.len() {
            let Some(s) = self.bus.servos.get(i) else {
                continue;
            };
            let j = s.joint as usize;
            let model = s.model;
            let Some(jc) = self.joints.get(j) else {
                continue;
            };
            // A servo whose range exceeds one turn around its centre needs extended position mode.
            let multi_turn = self.profile.joints.get(j).is_some_and(|c| {
                let s = c.sign as f32;
                let (a, b) = (s * c.limits.min + c.offset, s * c.limits.max + c.offset);
                a.min(b) < -core::f32::consts::PI || a.max(b) > core::f32::consts::PI
            });
            let mut m = bus::mode_byte(jc.mode, model, multi_turn);
            let mut torque = jc.mode != JointMode::Off;
            if let Some((gj, g)) = self.gripper.as_ref() {
                if *gj == j {
                    match g.state {
                        GripperState::Closing | GripperState::Holding | GripperState::Closed => {
                            m = ferrobot_protocol::dxl::mode::PWM;
                            torque = true;
                        }
                        GripperState::Open | GripperState::Opening => {
                            m = ferrobot_protocol::dxl::mode::POSITION;
                            torque = true;
                        }
                        _ => {}
                    }
                }
            }
            self.bus.set_mode(i, m, torque);
        }
    }
}
