//! The physical range of every number that crosses the wire, and the checks both ends apply.
//!
//! The firmware refuses a message whose numbers are not finite or lie outside these ranges
//! with a typed [`crate::RejectReason`] (`NotFinite`, `OutOfLimits` or `InvalidConfig`), before
//! anything reaches a controller; the host checks the same ranges where a value enters its
//! API. Ranges are wide enough for any robot Ferrobot drives and narrow enough that no
//! arithmetic on them overflows an `f32`.
//!
//! Safety policy on the wire:
//! * The emergency stop is accepted in every session state and overrides everything.
//! * The host watchdog is armed by the first accepted `Hello` and can then be changed only
//!   within `1..=`[`WATCHDOG_MAX_MS`] ms: it cannot be switched off.
//! * A refused handshake stops the base and holds every joint where it is.

use crate::{JointConfig, JointLimits, JointPoint, PidGains};

/// Shortest servo-loop period, µs (`SetLoopPeriod` refuses less).
pub const LOOP_PERIOD_MIN_US: u32 = 250;
/// Longest servo-loop period, µs (`SetLoopPeriod` refuses more).
pub const LOOP_PERIOD_MAX_US: u32 = 100_000;
/// Longest host watchdog period, ms. Periods of 0 (off) or longer are refused.
pub const WATCHDOG_MAX_MS: u16 = 2000;
/// Largest joint position anything may name (limits, knots, offsets), rad: two turns.
pub const JOINT_POSITION_MAX: f32 = 4.0 * core::f32::consts::PI;
/// Fastest joint speed anything may name (knots, commands, limits), rad/s.
pub const JOINT_SPEED_MAX: f32 = 20.0;
/// Slowest velocity limit a joint may be given, rad/s: a joint found outside newly narrowed
/// limits is brought back at its velocity limit, so that limit may not be near zero.
pub const JOINT_SPEED_LIMIT_MIN: f32 = 0.05;
/// How far outside its limits a joint under control may be before the firmware reports it
/// ([`crate::FaultKind::OutsideLimits`]), rad: what a servo's position loop lets a loaded
/// joint deflect, and the hostile-stream checkers' tolerance.
pub const OUTSIDE_FAULT: f32 = 0.05;

/// Narrowest effort limit `SetLimits` may give a joint, as a share of the effort limit its row
/// was configured with: a joint held to less cannot be trusted to carry its own load (the
/// LoCoBot's shoulder needs about 1.2 N·m of its 3.5 at full reach), and gravity would take it
/// past its limits in the torque modes.
pub const EFFORT_NARROW_MIN_SHARE: f32 = 0.5;
/// Narrowest range a joint's position limits may span, rad: a servo holds a loaded joint
/// some way off its goal, so a range much narrower than that deflection cannot be held.
pub const JOINT_RANGE_MIN: f32 = 0.1;
/// Largest joint effort anything may name (feed-forward, commands, limits), N·m.
pub const JOINT_EFFORT_MAX: f32 = 100.0;
/// Largest gain of the joint PID (each of kp, ki, kd, i_limit, and the position-mode sag
/// integrator's gain).
pub const GAIN_MAX: f32 = 1.0e4;
/// Fastest base speed a command may name, m/s (the firmware further limits it to the base).
pub const BASE_SPEED_MAX: f32 = 2.0;
/// Fastest base turn a command may name, rad/s.
pub const BASE_TURN_MAX: f32 = 20.0;

fn within(x: f32, lo: f32, hi: f32) -> bool {
    x.is_finite() && (lo..=hi).contains(&x)
}

/// Limits within range: positions within ±[`JOINT_POSITION_MAX`] at least
/// [`JOINT_RANGE_MIN`] apart, a velocity limit in
/// [[`JOINT_SPEED_LIMIT_MIN`], [`JOINT_SPEED_MAX`]], an effort limit in
/// [0, [`JOINT_EFFORT_MAX`]].
pub fn limits_ok(l: &JointLimits) -> bool {
    within(l.min, -JOINT_POSITION_MAX, JOINT_POSITION_MAX)
        && within(l.max, -JOINT_POSITION_MAX, JOINT_POSITION_MAX)
        && l.max - l.min >= JOINT_RANGE_MIN
        && within(l.velocity, JOINT_SPEED_LIMIT_MIN, JOINT_SPEED_MAX)
        && within(l.effort, 0.0, JOINT_EFFORT_MAX)
}

/// PID gains within [0, [`GAIN_MAX`]].
pub fn gains_ok(g: &PidGains) -> bool {
    [g.kp, g.ki, g.kd, g.i_limit]
        .iter()
        .all(|&v| within(v, 0.0, GAIN_MAX))
}

/// What a joint's servos can give, N·m: the model's stall torque, twice for a twin pair.
pub fn strength(c: &JointConfig) -> f32 {
    let servos = if c.twin_id.is_some() { 2.0 } else { 1.0 };
    servos * c.model.spec().stall_torque
}

/// The joint PID's stiffness bound per N·m of the joint's strength, 1/rad: full strength at
/// one encoder tick of error. A stiffer loop only turns the encoder's quantum into full torque
/// back and forth.
pub const KP_PER_STRENGTH: f32 = 1.0 / crate::dxl::units::RAD_PER_TICK;
/// The derivative gain's bound per N·m of strength, s/rad: full strength at one quantum of the
/// servo's velocity reading.
pub const KD_PER_STRENGTH: f32 = 1.0 / crate::dxl::units::RAD_S_PER_VELOCITY_UNIT;
/// The integral gain's bound per N·m of strength, 1/(rad·s): [`KP_PER_STRENGTH`]'s over an
/// integral time of [`INTEGRAL_TIME_MIN`].
pub const KI_PER_STRENGTH: f32 = KP_PER_STRENGTH / INTEGRAL_TIME_MIN;
/// Shortest integral time (kp/ki) the bounds allow, s: ten periods of the servo loop.
pub const INTEGRAL_TIME_MIN: f32 = 0.01;

/// Which of the joint PID's gains, if any, exceeds what joint `c`'s servos can physically use
/// ([`strength`]): kp over [`KP_PER_STRENGTH`], ki over [`KI_PER_STRENGTH`], kd over
/// [`KD_PER_STRENGTH`] times the strength, or an integral limit over the strength itself.
/// `None` when they fit (and are within [`gains_ok`]).
pub fn gains_beyond_servo(g: &PidGains, c: &JointConfig) -> Option<&'static str> {
    let s = strength(c);
    if !gains_ok(g) {
        return Some("a gain outside [0, GAIN_MAX] or not finite");
    }
    [
        (g.kp, KP_PER_STRENGTH * s, "kp"),
        (g.ki, KI_PER_STRENGTH * s, "ki"),
        (g.kd, KD_PER_STRENGTH * s, "kd"),
        (g.i_limit, s, "i_limit"),
    ]
    .into_iter()
    .find(|(v, bound, _)| v > bound)
    .map(|(_, _, name)| name)
}

/// Whether an effort limit (N·m) is more than joint `c`'s servos can give ([`strength`]).
pub fn effort_beyond_servo(effort: f32, c: &JointConfig) -> bool {
    effort > strength(c)
}

/// A joint row within range: sign ±1, limits and gains as above and within what its servos
/// can give ([`gains_beyond_servo`], [`effort_beyond_servo`]), offset within
/// ±[`JOINT_POSITION_MAX`], position integrator gain within [0, [`GAIN_MAX`]], servo IDs below
/// the broadcast ID and a twin different from its primary.
pub fn joint_config_ok(c: &JointConfig) -> bool {
    (c.sign == 1 || c.sign == -1)
        && limits_ok(&c.limits)
        && gains_ok(&c.pid)
        && within(c.offset, -JOINT_POSITION_MAX, JOINT_POSITION_MAX)
        && within(c.position_ki, 0.0, GAIN_MAX)
        && c.servo_id < 0xFD
        && c.twin_id.is_none_or(|t| t < 0xFD && t != c.servo_id)
        && gains_beyond_servo(&c.pid, c).is_none()
        && !effort_beyond_servo(c.limits.effort, c)
}

/// Heaviest link an arm's gravity model may name, kg.
pub const LINK_MASS_MAX: f32 = 50.0;
/// Farthest a link's joint origin or centre of mass may lie from its joint, m.
pub const LINK_REACH_MAX: f32 = 2.0;
/// How far a link's axis may be from unit length.
pub const LINK_AXIS_TOLERANCE: f32 = 1e-3;

/// Why one link of an arm's gravity model is refused, if it is: a number not finite, a mass
/// outside [0, [`LINK_MASS_MAX`]], an origin or centre of mass farther than
/// [`LINK_REACH_MAX`], an angle of its fixed rotation beyond ±2π, or an axis not of unit
/// length within [`LINK_AXIS_TOLERANCE`].
pub fn arm_link_error(l: &crate::ArmLink) -> Option<crate::RejectReason> {
    let all = [l.origin, l.rpy, l.axis, l.com, [l.mass; 3]];
    if all.iter().flatten().any(|x| !x.is_finite()) {
        return Some(crate::RejectReason::NotFinite);
    }
    // Squared norms: no square root in `no_std` without libm, and none needed.
    let norm2 = |v: [f32; 3]| v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    let reach2 = LINK_REACH_MAX * LINK_REACH_MAX;
    // |v|² within (1 ± tol)² of 1: within 2·tol to first order.
    let ok = within(l.mass, 0.0, LINK_MASS_MAX)
        && norm2(l.origin) <= reach2
        && norm2(l.com) <= reach2
        && l.rpy.iter().all(|a| a.abs() <= core::f32::consts::TAU)
        && (norm2(l.axis) - 1.0).abs() <= 2.0 * LINK_AXIS_TOLERANCE;
    (!ok).then_some(crate::RejectReason::InvalidConfig)
}

/// Why a knot is refused, if it is: not finite, or a speed or effort out of range, or a
/// position outside the joint's limits.
pub fn point_error(p: &JointPoint, limits: &JointLimits) -> Option<crate::RejectReason> {
    if !(p.position.is_finite() && p.velocity.is_finite() && p.effort.is_finite()) {
        return Some(crate::RejectReason::NotFinite);
    }
    let ok = (limits.min..=limits.max).contains(&p.position)
        && p.velocity.abs() <= JOINT_SPEED_MAX
        && p.effort.abs() <= JOINT_EFFORT_MAX;
    (!ok).then_some(crate::RejectReason::OutOfLimits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hostile_limits_are_refused() {
        let ok = JointLimits {
            min: -1.57,
            max: 1.57,
            velocity: 1.0,
            effort: 4.0,
        };
        assert!(limits_ok(&ok));
        for bad in [
            JointLimits {
                velocity: 1e-45,
                ..ok
            },
            JointLimits {
                velocity: f32::MAX,
                ..ok
            },
            JointLimits {
                min: f32::NEG_INFINITY,
                ..ok
            },
            JointLimits {
                max: f32::NAN,
                ..ok
            },
            JointLimits { min: 2.0, ..ok },
            JointLimits { effort: -1.0, ..ok },
            JointLimits { max: 1e9, ..ok },
        ] {
            assert!(!limits_ok(&bad), "{bad:?}");
        }
    }

    #[test]
    fn hostile_knots_are_refused() {
        let l = JointLimits {
            min: -1.0,
            max: 1.0,
            velocity: 1.0,
            effort: 4.0,
        };
        let at = |position, velocity, effort| JointPoint {
            position,
            velocity,
            effort,
        };
        assert_eq!(point_error(&at(0.5, 0.1, 0.0), &l), None);
        assert_eq!(
            point_error(&at(0.5, f32::MAX, 0.0), &l),
            Some(crate::RejectReason::OutOfLimits)
        );
        assert_eq!(
            point_error(&at(0.5, 0.0, f32::NAN), &l),
            Some(crate::RejectReason::NotFinite)
        );
        assert_eq!(
            point_error(&at(1.5, 0.0, 0.0), &l),
            Some(crate::RejectReason::OutOfLimits)
        );
    }
}
