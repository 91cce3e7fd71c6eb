//! The setpoint queue of a joint: knots at absolute firmware times, interpolated by cubic
//! Hermite splines into the reference it tracks; the direct command that replaces them.
//! Positions in rad, velocities in rad/s, efforts in N·m.

use ferrobot_protocol::JointPoint;

use super::JointControl;
use crate::time::{Duration, Instant};

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

impl JointControl {
    /// Knots still queued.
    pub fn queued(&self) -> usize {
        self.queue.len()
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
}
