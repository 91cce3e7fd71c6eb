//! Limit enforcement shared by the modes: the speed envelope near a position limit, the guard
//! of the torque modes, where a position goal may lie, and the thresholds of braking and
//! stopping a joint. Joint space: rad, rad/s, N·m.

use ferrobot_protocol::JointLimits;

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
/// A braked joint is let go once slower than its velocity limit times [`BRAKE_SPEED_FACTOR`]
/// plus this share of [`BRAKE_SPEED_ABS`].
pub const BRAKE_RELEASE_SHARE: f32 = 0.5;
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
pub fn envelope(q: f32, lim: &JointLimits, gain: f32) -> (f32, f32) {
    // Both ends within ±the velocity limit, so they stay ordered even far outside the limits.
    let v = lim.velocity;
    let up = (gain * (lim.max - q)).min(v).max(-v);
    let down = (gain * (lim.min - q)).max(-v).min(v);
    (down, up)
}

/// Where a position goal may lie: within the limits, or, for a joint outside them, between
/// them and its `anchor` (rad): the outermost point it has been allowed, which only ever moves
/// back towards the limits (see [`JointControl::anchor`](super::JointControl::anchor)); while it is `braking`, up to
/// [`BRAKE_OFFSET`] beyond.
pub fn position_goal_range(lim: &JointLimits, anchor: Option<f32>, braking: bool) -> (f32, f32) {
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
    lim: &JointLimits,
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

/// Where a position goal may lie for a joint at `q` moving at `qd`: within
/// [`position_goal_range`], or, while it is braked, behind the moving joint (the other way from its motion) within
/// [`position_reach`](super::position_reach) of it: such a goal slows it.
pub fn position_goal_window(
    lim: &JointLimits,
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
