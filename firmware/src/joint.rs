//! Per-joint control state: the setpoint queue with cubic Hermite interpolation, the
//! reference rate limiter, the joint PID with anti-windup, and limit enforcement.

use ferrobot_protocol::{JointConfig, JointMode, JointPoint, JointState};
use heapless::Deque;

/// Knots a joint can queue.
pub const QUEUE_LEN: usize = 16;

/// Velocity and PWM modes brake towards a position limit: the commanded speed is at most
/// this gain (1/s) times the distance left, so the joint stops at the limit instead of
/// reacting once it is past it.
pub const LIMIT_APPROACH_GAIN: f32 = 2.0;
/// PWM mode: the largest PWM fraction per rad of distance left to a limit.
pub const LIMIT_APPROACH_PWM: f32 = 1.5;

/// One queued trajectory knot at an absolute firmware time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Knot {
    /// Firmware time, µs.
    pub t: u64,
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
pub fn hermite(a: &Knot, b: &Knot, t: u64) -> Reference {
    let h_us = b.t.saturating_sub(a.t);
    if h_us == 0 {
        return Reference {
            q: b.q,
            qd: b.qd,
            eff: b.eff,
        };
    }
    let h = h_us as f32 * 1e-6;
    let s = (t.saturating_sub(a.t) as f32 / h_us as f32).clamp(0.0, 1.0);
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
    /// Goal effort, N·m, with the measured joint speed for voltage-mode servos.
    Effort(f32, f32),
    /// Goal PWM fraction in [−1, 1].
    Pwm(f32),
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
    /// Last measured state.
    pub state: JointState,
    /// Whether `state` has ever been measured.
    pub measured: bool,
    /// Whether a limit clamped the last command (reported once per episode).
    pub clamped: bool,
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
            state: JointState::default(),
            measured: false,
            clamped: false,
        }
    }

    /// Knots still queued.
    pub fn queued(&self) -> usize {
        self.queue.len()
    }

    /// Forget the queue and the direct command; hold at `q` (rad).
    pub fn hold_at(&mut self, now: u64, q: f32) {
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
    pub fn first_measurement(&mut self, now: u64, q: f32) {
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

    /// Hold where the joint is measured to be (or where it was commanded, if never measured).
    pub fn hold_here(&mut self, now: u64) {
        let q = if self.measured {
            self.state.position
        } else {
            self.cmd
        };
        self.hold_at(now, q);
    }

    /// Switch mode; the joint holds where it is.
    pub fn set_mode(&mut self, now: u64, mode: JointMode) {
        self.mode = mode;
        self.sag = 0.0;
        self.hold_here(now);
    }

    /// Queue a knot `duration_us` after the last one (or after `now` when idle).
    /// Returns false when the queue is full.
    pub fn push(&mut self, now: u64, duration_us: u32, p: &JointPoint) -> bool {
        if self.queue.is_full() {
            return false;
        }
        let start = match self.queue.back() {
            Some(k) => k.t,
            None => {
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
                t: start.saturating_add(duration_us as u64),
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
    pub fn reference(&mut self, now: u64) -> Reference {
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

    /// Run one control tick of length `dt` (s) for joint `cfg`; returns what to command.
    pub fn tick(&mut self, now: u64, dt: f32, cfg: &JointConfig) -> JointOutput {
        let lim = &cfg.limits;
        let q = self.state.position;
        let qd = self.state.velocity;
        let mut clamped = false;
        let out = match self.mode {
            JointMode::Off => JointOutput::None,
            JointMode::Position => {
                let r = self.reference(now);
                let target = r.q.clamp(lim.min, lim.max);
                clamped |= target != r.q;
                let step = lim.velocity * dt;
                let delta = target - self.cmd;
                if delta.abs() > step {
                    clamped |= !self.queue.is_empty() || delta.abs() > step * 1.5;
                }
                self.cmd += delta.clamp(-step, step);
                let settled = self.queue.is_empty() && (target - self.cmd).abs() < 1e-6;
                if settled && self.measured && cfg.position_ki > 0.0 {
                    self.sag = (self.sag + cfg.position_ki * (self.cmd - q) * dt).clamp(-0.2, 0.2);
                }
                JointOutput::Position(self.cmd + self.sag)
            }
            JointMode::Current => {
                if !self.measured {
                    JointOutput::None
                } else {
                    let tau = match self.direct {
                        Some(t) => t,
                        None => {
                            let r = self.reference(now);
                            let rq = r.q.clamp(lim.min, lim.max);
                            let e = rq - q;
                            let p = cfg.pid.kp * e + cfg.pid.kd * (r.qd - qd) + r.eff;
                            let i_next = (self.integral + cfg.pid.ki * e * dt)
                                .clamp(-cfg.pid.i_limit, cfg.pid.i_limit);
                            // Anti-windup: integrate only while the output is not saturated, or
                            // when integrating drives it back out of saturation.
                            let unsat = (p + i_next).abs() <= lim.effort;
                            if unsat || (i_next.abs() < self.integral.abs()) {
                                self.integral = i_next;
                            }
                            p + self.integral
                        }
                    };
                    let mut tau = tau;
                    // Position limits: push back out, never further in.
                    if q > lim.max {
                        tau = tau.min(cfg.pid.kp * (lim.max - q) - cfg.pid.kd * qd);
                    } else if q < lim.min {
                        tau = tau.max(cfg.pid.kp * (lim.min - q) - cfg.pid.kd * qd);
                    }
                    // Velocity limit: no effort that accelerates past it.
                    if qd > lim.velocity && tau > 0.0 || qd < -lim.velocity && tau < 0.0 {
                        tau = -cfg.pid.kd * (qd - qd.clamp(-lim.velocity, lim.velocity));
                    }
                    let t = tau.clamp(-lim.effort, lim.effort);
                    clamped |= t != tau;
                    JointOutput::Effort(t, qd)
                }
            }
            JointMode::Velocity => {
                let v0 = self.direct.unwrap_or(0.0);
                let up = (LIMIT_APPROACH_GAIN * (lim.max - q)).max(0.0);
                let down = (LIMIT_APPROACH_GAIN * (lim.min - q)).min(0.0);
                let v = v0.clamp(-lim.velocity, lim.velocity).clamp(down, up);
                clamped |= v != v0;
                JointOutput::Velocity(v)
            }
            JointMode::Pwm => {
                let p0 = self.direct.unwrap_or(0.0);
                let up = (LIMIT_APPROACH_PWM * (lim.max - q)).max(0.0);
                let down = (LIMIT_APPROACH_PWM * (lim.min - q)).min(0.0);
                let p = p0.clamp(-1.0, 1.0).clamp(down, up);
                clamped |= p != p0;
                JointOutput::Pwm(p)
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
            t: 0,
            q: 0.0,
            qd: 0.0,
            eff: 0.0,
        };
        let b = Knot {
            t: 1_000_000,
            q: 1.0,
            qd: 0.0,
            eff: 2.0,
        };
        assert_eq!(hermite(&a, &b, 0).q, 0.0);
        assert!((hermite(&a, &b, 1_000_000).q - 1.0).abs() < 1e-6);
        let mid = hermite(&a, &b, 500_000);
        assert!((mid.q - 0.5).abs() < 1e-6);
        assert!((mid.qd - 1.5).abs() < 1e-4, "{}", mid.qd); // peak speed of a cubic: 1.5·Δq/T
        assert!((mid.eff - 1.0).abs() < 1e-6);
    }

    #[test]
    fn position_reference_is_rate_limited_and_clamped() {
        let cfg = crate::config::locobot().joints[0].clone();
        let mut j = JointControl::new();
        j.set_mode(0, JointMode::Position);
        assert!(j.push(0, 0, &JointPoint::at_rest(5.0)));
        let mut last = 0.0;
        for k in 1..=3000u64 {
            if let JointOutput::Position(p) = j.tick(k * 1000, 1e-3, &cfg) {
                assert!(p - last <= cfg.limits.velocity * 1e-3 + 1e-6);
                last = p;
            }
        }
        assert!((last - cfg.limits.max).abs() < 1e-5, "{last}");
    }

    #[test]
    fn queue_is_bounded() {
        let mut j = JointControl::new();
        j.set_mode(0, JointMode::Position);
        let p = JointPoint::at_rest(0.1);
        for _ in 0..QUEUE_LEN {
            assert!(j.push(0, 1000, &p));
        }
        assert!(!j.push(0, 1000, &p));
    }
}
