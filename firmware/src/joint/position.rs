//! Position mode: the servo's own position loop tracks a goal the firmware moves every tick,
//! rate-limited towards the interpolated reference within the joint's limits; a joint that
//! runs away or leaves its limits is braked with a goal behind it; a load correction (and the
//! gravity model's goal offset) carries the load the servo's proportional loop would sag
//! under. Joint space: rad, rad/s, N·m; `dt` in s.

use ferrobot_protocol::JointConfig;

use super::limits::{
    position_goal_window, BRAKE_HOLD, BRAKE_MIN, BRAKE_OFFSET, BRAKE_RELEASE_SHARE,
    BRAKE_SPEED_ABS, BRAKE_SPEED_FACTOR, BRAKE_TIME, FAST_TICKS, LEAVING_SPEED,
    SERVO_TIME_CONSTANT,
};
use super::servo_model::{goal_offset_for_effort, position_lead, position_reach};
use super::{JointControl, JointOutput};
use crate::dynamics::supported;
use crate::time::{Duration, Instant};

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

/// How far a position goal may lie beyond [`position_goal_window`] for a joint bearing a
/// measured `effort` (N·m, what its servos give), with the model's goal offset `ff` (rad):
/// `(below, above)`, rad (`below` ≤ 0 ≤ `above`). The bound is the goal offset of the load
/// the effort bears out ([`supported`]). Within it, the model's offset: the goal that holds a
/// joint at a limit against its load lies beyond the limit, but a model that overstates the
/// load (right where it was confirmed, wrong here) must not hold the joint beyond it. For a
/// joint `outside` its limits, also that offset the way its servos push: the goal that holds
/// it against a load bringing it back lies beyond it (a goal at the joint let its load bring
/// it back as fast as the load liked, brake after brake: 0.32 rad/s against 0.05, pointed
/// seed 754).
pub fn goal_window_extension(cfg: &JointConfig, outside: bool, effort: f32, ff: f32) -> (f32, f32) {
    let borne = goal_offset_for_effort(cfg, supported(effort)).abs();
    let ext = if ff.is_finite() {
        ff.clamp(-borne, borne)
    } else {
        0.0
    };
    let pushed = match outside {
        true if effort > 0.0 => borne,
        true if effort < 0.0 => -borne,
        _ => 0.0,
    };
    (ext.min(pushed).min(0.0), ext.max(pushed).max(0.0))
}

impl JointControl {
    /// One position-mode tick: the goal for the servo, rad; `clamped` is set when a limit
    /// held the command back.
    pub(super) fn tick_position(
        &mut self,
        now: Instant,
        dt: f32,
        cfg: &JointConfig,
        last_ff: f32,
        clamped: &mut bool,
    ) -> JointOutput {
        let lim = &cfg.limits;
        let q = self.state.position;
        let qd = self.state.velocity;
        let r = self.reference(now);
        // The modelled gravity load rides in the goal: the servo's proportional loop
        // gives the holding effort at the commanded position.
        let model = self.gravity.filter(|t| t.is_finite());
        let ff = model.map_or(0.0, |t| goal_offset_for_effort(cfg, -t));
        self.feed_forward = ff;
        // The model trusted or no longer: the load correction hands the load over to the
        // model's offset, or takes it back, so that the goal does not move (dropped at once,
        // a loaded joint would fall until braked).
        if model.is_some() != core::mem::replace(&mut self.modelled, model.is_some()) {
            self.sag += last_ff - ff;
        }
        let target = if self.stopped {
            self.cmd
        } else {
            r.q.clamp(lim.min, lim.max)
        };
        *clamped |= target != r.q;
        let mut held = false;
        if self.must_brake(dt, cfg) {
            self.brake();
            *clamped = true;
        } else {
            // A hand's push is a load the model does not carry.
            self.release_brake(cfg, model.is_some() && !self.teach_push);
            held = self.step_command(dt, cfg, target, clamped);
        }
        // Settled: the command has reached a target that stays put (no knot left, or
        // the reference held at a limit).
        // Or held back by the joint: a load (or an obstacle) it must push against.
        // Not while a hand pushes a joint in teach mode: its load is not the arm's.
        let settled = (((self.queue.is_empty() || target != r.q)
            && (target - self.cmd).abs() < 1e-6)
            || held)
            && !self.teach_push;
        // Where the joint has not yet shown the model's whole load, the model carries only
        // what it has shown (`gravity` is cut short of `model_load`): the correction carries
        // the rest, as without a model.
        let cut = match (model, self.model_load) {
            (Some(g), Some(m)) => (g - m).abs() > 1e-6,
            _ => false,
        };
        self.correct_load(now, dt, cfg, settled, (model.is_some() && !cut, ff));
        // The goal stays within the limits, or between them and a joint outside them:
        // never further out than the joint is.
        // Beyond that only by `goal_window_extension`: the load the joint bears.
        let (lo, hi) = position_goal_window(
            lim,
            self.anchor,
            self.braking,
            (q, qd),
            position_reach(cfg, qd),
        );
        let (below, above) =
            goal_window_extension(cfg, self.anchor.is_some(), self.state.effort, ff);
        let (lo, hi) = (lo + below, hi + above);
        let goal = (self.cmd + self.braking_offset(ff) + self.sag).clamp(lo, hi);
        JointOutput::Position(goal)
    }

    /// Whether the joint must be braked: measured running away (faster than its limit allows,
    /// [`FAST_TICKS`] ticks in a row the same way) or moving further out beyond a limit.
    fn must_brake(&mut self, dt: f32, cfg: &JointConfig) -> bool {
        let lim = &cfg.limits;
        let q = self.state.position;
        let qd = self.state.velocity;
        // Between two setpoints of a slow loop the servo catches up with a step of the
        // command faster than the command moves: that is not running away.
        // A braked joint is let go only once well below the speed that braked it: let go
        // just below it, a joint dragged on (a limp neighbour's swing, a load the model does
        // not know) speeds up again at once, and brake after brake its average speed stays
        // above the limit (0.234 rad/s against 0.232 allowed, pointed seed 709).
        let factor = BRAKE_SPEED_FACTOR.max(dt / SERVO_TIME_CONSTANT);
        let margin = if self.braking {
            BRAKE_RELEASE_SHARE * BRAKE_SPEED_ABS
        } else {
            BRAKE_SPEED_ABS
        };
        let fast = lim.velocity * factor + margin;
        let leaving = (q > lim.max && qd > LEAVING_SPEED) || (q < lim.min && qd < -LEAVING_SPEED);
        self.fast_ticks = match (qd.abs() > fast, qd > 0.0) {
            (true, true) => self.fast_ticks.max(0).saturating_add(1),
            (true, false) => self.fast_ticks.min(0).saturating_sub(1),
            (false, _) => 0,
        };
        let runaway = self.fast_ticks.unsigned_abs() >= FAST_TICKS;
        self.measured && (runaway || leaving)
    }

    /// Brake a joint that runs away: its goal goes behind it.
    fn brake(&mut self) {
        let q = self.state.position;
        let qd = self.state.velocity;
        // Brake: the goal stays behind the joint (at least its speed times
        // BRAKE_TIME, and as far as the joint has since run on), so the servo
        // pushes back harder the further it goes; once it has slowed down, the
        // command is brought near where it is, so it never races back to a
        // command it left far behind.
        // The goal never moves the way the joint runs.
        // The load correction becomes part of the goal, so the goal the servo
        // holds against its load does not jump when braking starts.
        self.cmd += core::mem::take(&mut self.sag);
        let behind = q - qd.signum() * (qd.abs() * BRAKE_TIME).clamp(BRAKE_MIN, BRAKE_OFFSET);
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
    }

    /// The model's goal offset `ff` (rad) as the goal carries it: while braking, none of it
    /// the way the joint runs. The brake puts the command behind the joint; a model wrong
    /// about the load (its size or its sign) must not carry the goal back towards it or
    /// beyond (a joint rising at 0.3 rad/s, its model's offset 0.07 rad where the load it
    /// bore needed 0.02: pointed seed 707; one falling at 0.3 rad/s under an emergency stop,
    /// its model's offset pointing down: seed 735). With a true model, an offset the way
    /// the joint runs only weakens the brake; the load itself brakes it then.
    fn braking_offset(&self, ff: f32) -> f32 {
        let qd = self.state.velocity;
        if !self.braking || !qd.is_finite() {
            ff
        } else if qd > 0.0 {
            ff.min(0.0)
        } else if qd < 0.0 {
            ff.max(0.0)
        } else {
            ff
        }
    }

    /// Once a braked joint no longer runs away, let go of the brake where it rests (with a
    /// gravity model, `modelled`, the model carries its load).
    fn release_brake(&mut self, cfg: &JointConfig, modelled: bool) {
        let lim = &cfg.limits;
        let q = self.state.position;
        if core::mem::take(&mut self.braking) {
            // Where the joint came to rest; outside its limits keeping up to
            // BRAKE_HOLD of the goal offset that stopped it (the load that pushed
            // it out may need it to hold there).
            // Under an emergency stop too: the arm must stay where it stopped,
            // and a goal where it is would let its load carry it on, brake after
            // brake.
            let outside = q < lim.min || q > lim.max;
            let kept = self.cmd.clamp(q - BRAKE_HOLD, q + BRAKE_HOLD);
            self.cmd = if modelled {
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
    }

    /// Step the command towards `target` at the velocity limit, never leading the joint by
    /// more than its lead; `clamped` is set when that holds it back from the reference.
    /// Returns whether the joint held the command back.
    fn step_command(
        &mut self,
        dt: f32,
        cfg: &JointConfig,
        target: f32,
        clamped: &mut bool,
    ) -> bool {
        let lim = &cfg.limits;
        let q = self.state.position;
        let qd = self.state.velocity;
        let step = lim.velocity * dt;
        let delta = target - self.cmd;
        if delta.abs() > step {
            *clamped |= !self.queue.is_empty() || delta.abs() > step * 1.5;
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
        self.cmd != free
    }

    /// The load correction: an integrator that shifts the goal until the joint meets its
    /// `settled` command, bounded by what the gravity model (`modelled`, with its goal offset
    /// `ff`, rad) leaves to it, or by [`SAG_MAX`] without one or for a stalled joint.
    fn correct_load(
        &mut self,
        now: Instant,
        dt: f32,
        cfg: &JointConfig,
        settled: bool,
        (modelled, ff): (bool, f32),
    ) {
        let lim = &cfg.limits;
        let q = self.state.position;
        let qd = self.state.velocity;
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
        // With a model the correction only mends its error; without one, stalled, or pushed
        // by a hand in teach mode (a load the model does not know), it carries the whole load.
        let bound = match modelled {
            true if !stalled && !self.teach_push => SAG_MODEL_SHARE * ff.abs() + SAG_MODEL_MIN,
            _ => SAG_MAX,
        };
        if (settled || (outside && !self.stopped)) && self.measured && cfg.position_ki > 0.0 {
            self.sag += cfg.position_ki * (self.cmd - q) * dt;
        }
        self.sag = self.sag.clamp(-bound, bound);
    }
}
