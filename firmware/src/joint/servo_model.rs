//! The servo's own position loop as the firmware models it (the e-manual's gain scaling): how
//! far a position goal may lead a joint, how far from it a goal asks for full PWM, and the
//! goal offset that makes the servo give an effort at rest. Angles in rad, efforts in N·m.

use ferrobot_protocol::dxl::units;
use ferrobot_protocol::JointConfig;

/// The servo's position loop, as the servo runs it (the e-manual's gain scaling, no profile):
/// PWM = P/128 · error (ticks) − D/16 · speed (ticks/ms). Returns (P term per rad, D term per
/// rad/s), PWM units.
fn position_loop_gains(cfg: &JointConfig) -> (f32, f32) {
    let tpr = units::TICKS_PER_REV / core::f32::consts::TAU;
    (
        cfg.servo.pos_p as f32 / 128.0 * tpr,
        cfg.servo.pos_d as f32 / 16.0 * tpr * 1e-3,
    )
}

/// How far (rad) a position command may lead the joint: twice the servo's tracking lag at the
/// joint's velocity limit (the goal error at which its position loop, unloaded, drives it at
/// that speed), plus [`LEAD_MIN`].
pub fn position_lead(cfg: &JointConfig) -> f32 {
    let v = cfg.limits.velocity;
    let f = cfg.model.spec().pwm_fraction_for_effort(0.0, v);
    let (kp, kd) = position_loop_gains(cfg);
    if kp <= 0.0 {
        return 0.0;
    }
    let e = (f * units::PWM_MAX + kd * v) / kp;
    if e.is_finite() {
        (LEAD_FACTOR * e.abs() + LEAD_MIN).min(1.0)
    } else {
        0.0
    }
}
/// See [`position_lead`].
pub const LEAD_FACTOR: f32 = 2.0;
/// See [`position_lead`], rad.
pub const LEAD_MIN: f32 = 0.004;

/// How far (rad) from a joint moving at `qd` (rad/s) a position goal drives its servo at full
/// PWM: goals further away ask for nothing more.
pub fn position_reach(cfg: &JointConfig, qd: f32) -> f32 {
    let (kp, kd) = position_loop_gains(cfg);
    if kp <= 0.0 || !qd.is_finite() {
        return 0.0;
    }
    ((units::PWM_MAX + kd * qd.abs()) / kp).min(1.0)
}

/// The goal offset (rad) that makes a joint's servo(s), in position mode at rest, give the
/// effort `tau` (N·m): their proportional loop's stiffness at zero speed; within the goal
/// distance of full PWM. Zero when the gains give no stiffness or `tau` is not finite.
pub fn goal_offset_for_effort(cfg: &JointConfig, tau: f32) -> f32 {
    let (kp, _) = position_loop_gains(cfg);
    let spec = cfg.model.spec();
    let servos = if cfg.twin_id.is_some() { 2.0 } else { 1.0 };
    if kp <= 0.0 || !tau.is_finite() {
        return 0.0;
    }
    let f = spec.pwm_fraction_for_effort(tau / servos, 0.0);
    let reach = position_reach(cfg, 0.0);
    (f * units::PWM_MAX / kp).clamp(-reach, reach)
}
