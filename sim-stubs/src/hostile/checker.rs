//! The invariants, checked on the plants' true state.

use crate::LockstepSim;
use ferrobot_protocol::*;

/// Position tolerance beyond a limit, rad.
pub const POS_TOL: f64 = 0.06;
/// Relative speed tolerance over a velocity limit.
pub const SPEED_TOL: f64 = 0.25;
/// Absolute speed tolerance, rad/s (encoder and dynamics noise).
pub const SPEED_ABS: f64 = 0.25;
/// A joint the checker lets brake first (a limp one taken under control, one that new limits
/// left outside) may still run on for its stopping distance at this deceleration, rad/s²,
/// before it must come back.
pub const BRAKING: f64 = 200.0;

fn stopping(v: f64) -> f64 {
    v * v / (2.0 * BRAKING)
}
/// How long (µs) a joint taken under control (switched on, or switched to another mode) may
/// still run on as it was: its servo changes mode and its first goals go out.
pub const GRACE_US: u64 = 5_000;
/// How far (relative) the plant's link masses may differ from the description's.
pub const MASS_TOL: f64 = 0.2;
/// Relative tolerance over the base's top wheel speed.
pub const WHEEL_TOL: f64 = 0.05;

/// What the checker remembers of a joint.
#[derive(Clone)]
struct Watch {
    row: Option<JointConfig>,
    /// How far outside its limits the joint may still be (it may only come back).
    outside: f64,
    /// How fast it may still move, beyond its limit (it may only slow down).
    speed: f64,
    /// The last sample: time (µs) and output angle (rad).
    last: Option<(u64, f64)>,
    /// Until when (µs) a joint just taken under control may still speed up: its servo is
    /// switched on and its first goals go out.
    grace_until: u64,
    /// Whether the joint was under control at the last sample, and in which mode.
    was_controlled: bool,
    mode: JointMode,
}

impl Watch {
    /// A joint the checker has not seen move yet, with joint-table row `row`.
    fn new(row: Option<JointConfig>) -> Self {
        Watch {
            row,
            outside: 0.0,
            speed: 0.0,
            last: None,
            grace_until: 0,
            was_controlled: false,
            mode: JointMode::Off,
        }
    }
}

/// Checks the invariants on the plants' true state; returns violations found. Every check also
/// runs the [`super::strict::StrictChecker`], whose violations join these.
pub struct Checker {
    watch: Vec<Watch>,
    /// The strict checker beside this one.
    pub strict: super::strict::StrictChecker,
    /// What was violated, where and when.
    pub violations: Vec<String>,
    /// Checks made.
    pub samples: u64,
    /// Worst excess seen on controlled joints: beyond a position limit (rad), and speed over
    /// the velocity limit (rad/s), with where each happened.
    pub worst: (f64, f64),
    /// Where the worst excesses happened.
    pub worst_at: (String, String),
}

fn outside(q: f64, l: &JointLimits) -> f64 {
    (l.min as f64 - q).max(q - l.max as f64).max(0.0)
}

impl Checker {
    /// A checker for `sim`'s joint table.
    pub fn new(sim: &LockstepSim) -> Self {
        let watch = sim
            .fw
            .profile()
            .joints
            .iter()
            .map(|c| Watch::new(Some(c.clone())))
            .collect();
        Checker {
            watch,
            strict: super::strict::StrictChecker::new(sim.fw.profile().clone()),
            violations: Vec::new(),
            samples: 0,
            worst: (0.0, 0.0),
            worst_at: (String::new(), String::new()),
        }
    }

    /// Check the invariants on the plants' state now; `what` says where in the stream.
    pub fn check(&mut self, sim: &LockstepSim, what: &str) {
        self.samples += 1;
        let before = self.strict.violations.len();
        self.strict.check(sim, what);
        let strict = self.strict.violations[before..].iter();
        self.violations
            .extend(strict.map(|v| format!("strict checker: {v}")));
        let fw = &sim.fw;
        let joints = &fw.profile().joints;
        self.watch.resize(joints.len(), Watch::new(None));
        for (j, cfg) in joints.iter().enumerate() {
            self.check_joint(sim, what, j, cfg);
        }
        // Every servo the firmware believes configured runs the mode and torque it asked for.
        for b in fw.bus().servos.iter() {
            let settled = b.status == ferrobot_firmware::bus::ServoStatus::Ok && b.ops == 0;
            if let (true, Some(sv)) = (settled, sim.hw.chain.servo(b.id)) {
                let mode = sv.get(dxl::addr::OPERATING_MODE, 1) as u8;
                if mode != b.mode || (b.torque && !sv.torque_enabled() && sv.hardware_error() == 0)
                {
                    self.violations.push(format!(
                        "{what}: t={} us servo {} runs mode {mode} (torque {}), the firmware asked mode {} (torque {})",
                        sim.now_us(),
                        b.id,
                        sv.torque_enabled(),
                        b.mode,
                        b.torque
                    ));
                }
            }
        }
        if let Some(base) = sim.hw.base.as_ref() {
            let top = fw.profile().base.max_wheel_speed as f64 * (1.0 + WHEEL_TOL);
            let (l, r) = base.drive.speed;
            if l.abs() > top || r.abs() > top {
                self.violations.push(format!(
                    "{what}: t={} us wheels at ({l:.3}, {r:.3}) m/s, top {top:.3}",
                    sim.now_us()
                ));
            }
        }
    }

    /// Check joint `j` (row `cfg`) now: within its limits (or coming back) and its speed.
    fn check_joint(&mut self, sim: &LockstepSim, what: &str, j: usize, cfg: &JointConfig) {
        let fw = &sim.fw;
        let Some(servo) = sim.hw.chain.servo(cfg.servo_id) else {
            return;
        };
        let sign = cfg.sign as f64;
        let q = sign * (servo.theta - cfg.offset as f64);
        let w = &mut self.watch[j];
        // The output's speed now (the motor may turn inside the backlash while the joint
        // stands still: that is not the joint moving).
        let now = sim.now_us();
        let qd = sign * servo.output_speed();
        // Time since the last sample, for the allowed speed's fall.
        let dt = w
            .last
            .map_or(0.0, |(t, _)| now.saturating_sub(t) as f64 * 1e-6);
        w.last = Some((now, servo.theta));
        if w.row.as_ref() != Some(cfg) {
            // A new row (limits, servo, sign, offset): the joint may be outside its new
            // limits, and may only come back.
            w.row = Some(cfg.clone());
            w.outside = outside(q, &cfg.limits) + stopping(qd);
            w.speed = qd.abs();
            return;
        }
        let controlled = under_control(sim, j, cfg, servo);
        let d = outside(q, &cfg.limits);
        let vmax = cfg.limits.velocity as f64 * (1.0 + SPEED_TOL) + SPEED_ABS;
        let mode = fw.joints().get(j).map(|c| c.mode).unwrap_or(JointMode::Off);
        if (!w.was_controlled || w.mode != mode) && controlled {
            w.grace_until = now + GRACE_US;
        }
        w.was_controlled = controlled;
        w.mode = mode;
        if !controlled || now < w.grace_until {
            // A limp joint goes where gravity takes it; once under control it must come
            // back from there, and slow down from that speed.
            w.outside = w.outside.max(d + stopping(qd));
            w.speed = w.speed.max(qd.abs());
            return;
        }
        let was = (w.outside, w.speed);
        let state = JointNow {
            j,
            cfg,
            servo,
            q,
            qd,
            d,
        };
        self.judge(sim, what, &state, vmax, was);
        let w = &mut self.watch[j];
        w.outside = w.outside.min(d + stopping(qd));
        // A joint found too fast slows down at most at the braking rate: the allowed speed
        // falls at that rate (never below what it is now).
        w.speed = w.speed.min((w.speed - BRAKING * dt).max(qd.abs()));
    }

    /// Record the worst excesses of joint `n` and its violations: beyond the limits by more
    /// than it was `outside` (rad) or faster than `vmax` or its allowed `speed` (rad/s).
    fn judge(
        &mut self,
        sim: &LockstepSim,
        what: &str,
        n: &JointNow<'_>,
        vmax: f64,
        (outside, speed): (f64, f64),
    ) {
        let fw = &sim.fw;
        let JointNow {
            j,
            cfg,
            servo,
            q,
            qd,
            d,
        } = *n;
        let (dp, dv) = (
            d - outside,
            qd.abs() - (cfg.limits.velocity as f64).max(speed),
        );
        let here = || {
            format!(
                "{what}: t={} us joint {j} ({:?}) at {q:.4} rad, {qd:.3} rad/s, {:?}",
                sim.now_us(),
                fw.joints()[j].mode,
                cfg.limits
            )
        };
        if dp > self.worst.0 {
            self.worst.0 = dp;
            self.worst_at.0 = here();
        }
        if dv > self.worst.1 {
            self.worst.1 = dv;
            self.worst_at.1 = here();
        }
        let servo_state = || {
            format!(
                "{:?}; servo torque {}, error {}, mode {}",
                fw.joints()[j].mode,
                servo.torque_enabled(),
                servo.hardware_error(),
                servo.get(dxl::addr::OPERATING_MODE, 1)
            )
        };
        if d > outside + POS_TOL {
            self.violations.push(format!(
                "{what}: t={} us joint {j} ({}) at {q:.4} rad, {d:.4} rad outside {:?}",
                sim.now_us(),
                servo_state(),
                cfg.limits
            ));
        }
        if qd.abs() > vmax.max(speed + SPEED_ABS) {
            self.violations.push(format!(
                "{what}: t={} us joint {j} ({}) at {q:.4} rad, {qd:.3} rad/s, limits {:?}",
                sim.now_us(),
                servo_state(),
                cfg.limits
            ));
        }
    }
}

/// One joint's state in one check.
struct JointNow<'a> {
    j: usize,
    cfg: &'a JointConfig,
    servo: &'a crate::servo::ServoSim,
    /// Position, rad.
    q: f64,
    /// Output speed, rad/s.
    qd: f64,
    /// How far outside its limits, rad.
    d: f64,
}

/// Whether joint `j` (row `cfg`, servo `servo`) is under the firmware's control: not pressed
/// against a mechanical stop, not the gripper, not off, and its servos configured.
fn under_control(
    sim: &LockstepSim,
    j: usize,
    cfg: &JointConfig,
    servo: &crate::servo::ServoSim,
) -> bool {
    let fw = &sim.fw;
    // Pressed against a mechanical stop (limits set beyond the joint's mechanical
    // range): the stop, not the firmware, decides where the joint is.
    let at_stop = servo
        .stops
        .is_some_and(|(lo, hi)| servo.theta <= lo + 0.02 || servo.theta >= hi - 0.02);
    !at_stop
        && cfg.kind != JointKind::Gripper
        && fw.joints().get(j).is_some_and(|c| c.mode != JointMode::Off)
        && fw
            .bus()
            .servos
            .iter()
            .filter(|s| s.joint as usize == j)
            .all(|s| {
                // Under control once its configuration (a mode change: torque off,
                // mode, goal, torque on) is done: until then the servo is limp.
                s.status == ferrobot_firmware::bus::ServoStatus::Ok && s.hw_error == 0 && s.ops == 0
            })
}
