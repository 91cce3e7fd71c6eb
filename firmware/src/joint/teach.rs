//! Teach mode: an admittance on the servo's own position loop. The joint runs as in position
//! mode (its goal rate-limited within its limits, braked when it runs away, its load carried
//! by the trusted gravity model and the load correction); what its measured effort gives
//! beyond the modelled load is a hand's torque, and a hand's torque beyond a dead band moves
//! the hold point the way it pushes, never more than the joint's lead ahead of the joint and
//! never faster than its speed limit. Once the hand lets go, the hold point is where the joint
//! is: the servo's stiff loop keeps it there, whatever the model's error (within the dead
//! band). Joint space: rad, rad/s, N·m; `dt` in s.

use ferrobot_protocol::JointConfig;

use super::servo_model::position_lead;
use super::{JointControl, Knot};
use crate::time::Instant;

/// A hand's torque is what the joint's effort gives beyond the modelled load by more than
/// this, N·m (the servos' current sensing and static friction) ...
pub const TEACH_DEADBAND: f32 = 0.15;
/// ... plus this share of the modelled load (the model's error: masses 20 % off the arm
/// still leave it still).
pub const TEACH_MODEL_SHARE: f32 = 0.3;
/// The hold point's speed per N·m of a hand's torque beyond the dead band, rad/s (up to the
/// joint's speed limit).
pub const TEACH_GAIN: f32 = 2.0;

impl JointControl {
    /// Move the hold point with a hand's torque, or hold where the joint is once it lets go.
    /// Without a trusted model (no `model_load`) nothing moves: the joint holds.
    pub(super) fn teach(&mut self, now: Instant, dt: f32, cfg: &JointConfig) {
        let (q, effort) = (self.state.position, self.state.effort);
        let hand = match self.model_load.filter(|g| g.is_finite()) {
            // Servo effort, gravity and hand balance: e + g + h = 0.
            Some(g) if self.measured && q.is_finite() && effort.is_finite() && !self.stopped => {
                let h = -(effort + g);
                let excess = h.abs() - (TEACH_DEADBAND + TEACH_MODEL_SHARE * g.abs());
                (excess > 0.0).then_some(h.signum() * excess)
            }
            _ => None,
        };
        match hand {
            Some(push) => {
                self.teach_push = true;
                let lim = &cfg.limits;
                let v = (push * TEACH_GAIN).clamp(-lim.velocity, lim.velocity);
                let lead = position_lead(cfg);
                let r = self.reference(now).q + v * dt;
                let r = r.clamp(q - lead, q + lead).clamp(lim.min, lim.max);
                // The command steps towards it from where it is, as towards any reference.
                self.queue.clear();
                self.direct = None;
                self.seg_start = Knot {
                    t: now,
                    q: r,
                    qd: 0.0,
                    eff: 0.0,
                };
            }
            // Let go: it stays where it is (outside its limits, the command comes back from
            // there at the speed limit, as in position mode; a command set inside at once
            // would yank it back).
            None if core::mem::take(&mut self.teach_push) && q.is_finite() => {
                self.hold_at(now, q);
            }
            None => {}
        }
    }
}
