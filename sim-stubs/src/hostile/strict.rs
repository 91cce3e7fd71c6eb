//! A second checker, written to the letter of an outside review (issue 48) rather than to the
//! firmware's own reasoning: simple rules with few exemptions, so that it finds what
//! [`super::Checker`]'s allowances (joints left outside by new limits, braking distances)
//! would let pass.
//!
//! Every joint under control (not the gripper, not limp: its servos configured and torqued;
//! not pressed against a mechanical stop, which moves it as it springs back),
//! once [`SETTLE_US`] has passed since its limits last changed, and not in current mode made weaker than built (an effort limit or a stiffness
//! below half the profile's):
//!
//! * lies within [`POS_TOL`] of its position limits; one taken under control outside them
//!   (gravity took it there while it was limp) may only come back, to within [`POS_TOL`] of
//!   where it was taken or, taken while falling, of where it came to its allowed speed;
//! * moves, over every window of at least [`WINDOW_US`] within such a stretch, no faster on
//!   average than [`SPEED_FACTOR`] × its velocity limit + [`SPEED_ABS`]; one taken under
//!   control faster than that (it fell while limp) may only slow down until it is within it.

use std::collections::VecDeque;

use crate::LockstepSim;
use ferrobot_firmware::bus::ServoStatus;
use ferrobot_firmware::config::RobotProfile;
use ferrobot_protocol::*;

/// Tolerance beyond a position limit, rad.
pub const POS_TOL: f64 = 0.05;
/// Allowed average speed over a window: this factor times the velocity limit ...
pub const SPEED_FACTOR: f64 = 1.5;
/// ... plus this, rad/s.
pub const SPEED_ABS: f64 = 0.15;
/// Shortest window the average speed is taken over, µs.
pub const WINDOW_US: u64 = 20_000;
/// How long after its limits change a joint is not checked, µs (it may be outside them).
pub const SETTLE_US: u64 = 300_000;

#[derive(Clone, Default)]
struct Track {
    limits: Option<JointLimits>,
    /// When the limits last changed (µs).
    changed_at: u64,
    /// Whether it was under control at the last sample.
    controlled: bool,
    /// How far outside its limits a joint was when taken under control (a limp joint that
    /// gravity took there), rad: it may only come back from there; none once back inside.
    entered_outside: Option<f64>,
    /// The speed (rad/s) of a joint taken under control faster than it may move (it fell
    /// while limp): it may only slow down, and the windows start once it is within its
    /// allowed speed; none then.
    entered_fast: Option<f64>,
    /// Samples (µs, rad) of the stretch under check now, oldest first.
    samples: VecDeque<(u64, f64)>,
}

/// The strict checker; see the module doc.
pub struct StrictChecker {
    built: RobotProfile,
    tracks: Vec<Track>,
    /// What was violated, where and when.
    pub violations: Vec<String>,
    /// Checks made.
    pub samples: u64,
    /// Worst excesses seen: beyond a position limit (rad), and average speed over the allowed
    /// one (rad/s).
    pub worst: (f64, f64),
}

impl StrictChecker {
    /// A checker for a robot built as `built` (the profile its firmware started with).
    pub fn new(built: RobotProfile) -> Self {
        StrictChecker {
            built,
            tracks: Vec::new(),
            violations: Vec::new(),
            samples: 0,
            worst: (0.0, 0.0),
        }
    }

    /// Whether joint `j` is checked now: under control, and not made weaker than built in
    /// current mode.
    fn checked(&self, sim: &LockstepSim, j: usize, cfg: &JointConfig) -> bool {
        let fw = &sim.fw;
        let Some(jc) = fw.joints().get(j) else {
            return false;
        };
        let configured = fw
            .bus()
            .servos
            .iter()
            .filter(|s| s.joint as usize == j)
            .all(|s| s.status == ServoStatus::Ok && s.hw_error == 0 && s.ops == 0 && s.torque);
        let weaker = jc.mode == JointMode::Current
            && self.built.joints.get(j).is_some_and(|b| {
                cfg.limits.effort < 0.5 * b.limits.effort || cfg.pid.kp < 0.5 * b.pid.kp
            });
        cfg.kind != JointKind::Gripper && jc.mode != JointMode::Off && configured && !weaker
    }

    /// Check the plants' state now; `what` says where in the stream.
    pub fn check(&mut self, sim: &LockstepSim, what: &str) {
        self.samples += 1;
        let joints = sim.fw.profile().joints.clone();
        self.tracks.resize(joints.len(), Track::default());
        for (j, cfg) in joints.iter().enumerate() {
            self.check_joint(sim, what, j, cfg);
        }
    }

    /// Check joint `j` (row `cfg`) now.
    fn check_joint(&mut self, sim: &LockstepSim, what: &str, j: usize, cfg: &JointConfig) {
        let now = sim.now_us();
        let Some(servo) = sim.hw.chain.servo(cfg.servo_id) else {
            return;
        };
        let q = cfg.sign as f64 * (servo.theta - cfg.offset as f64);
        // Against a mechanical stop (it fell there while limp), the stop moves the joint
        // as it springs back, not the firmware.
        let at_stop = servo
            .stops
            .is_some_and(|(lo, hi)| servo.theta <= lo + 0.02 || servo.theta >= hi - 0.02);
        let controlled = self.checked(sim, j, cfg);
        let t = &mut self.tracks[j];
        let l = cfg.limits;
        let beyond = (l.min as f64 - q).max(q - l.max as f64);
        let qd = (cfg.sign as f64 * servo.output_speed()).abs();
        let allowed = SPEED_FACTOR * l.velocity as f64 + SPEED_ABS;
        if t.limits != Some(cfg.limits) {
            // New limits are no excuse: once settled, it must be within them.
            t.limits = Some(cfg.limits);
            t.changed_at = now;
            t.entered_outside = None;
            t.entered_fast = None;
        }
        if controlled && !t.controlled {
            // Taken under control (it was limp): from where gravity took it, and as fast.
            t.entered_outside = (beyond > 0.0).then_some(beyond);
            t.entered_fast = (qd > allowed).then_some(qd);
        }
        t.controlled = controlled;
        if !controlled || at_stop || now < t.changed_at + SETTLE_US {
            t.samples.clear();
            return;
        }
        let tol = tolerance(t, beyond);
        let here = |kind: &str| {
            format!(
                "{what}: t={now} us joint {j} ({:?}) {kind} at {q:.4} rad, limits {l:?}",
                sim.fw.joints()[j].mode
            )
        };
        if t.entered_outside.is_none() && beyond > self.worst.0 {
            self.worst.0 = beyond;
        }
        if beyond > tol {
            self.violations
                .push(here(&format!("{beyond:.4} rad beyond a limit")));
        }
        if let Some(v) = t.entered_fast {
            // Braking from the speed it was taken at: it may only slow down (above the
            // noise of the speed reading).
            if qd > v + SPEED_ABS {
                self.violations.push(here(&format!(
                    "{qd:.3} rad/s, faster than the {v:.3} rad/s it was taken under control at"
                )));
            }
            if qd > allowed {
                t.entered_fast = Some(v.min(qd).max(allowed));
                return;
            }
            t.entered_fast = None;
        }
        if let Some((v, t0)) = window_speed(t, now, q) {
            self.worst.1 = self.worst.1.max(v - allowed);
            if v > allowed {
                self.violations.push(here(&format!(
                    "{v:.3} rad/s on average over {:.0} ms (allowed {allowed:.3})",
                    (now - t0) as f64 * 1e-3
                )));
            }
        }
    }
}

/// How far (rad) beyond a limit joint track `t` may be when it is `beyond` it now. A joint
/// taken under control outside its limits may only come back; while it brakes from the speed
/// it was taken at, it may go on as far as it brakes.
fn tolerance(t: &mut Track, beyond: f64) -> f64 {
    if t.entered_fast.is_some() && beyond > 0.0 {
        t.entered_outside = Some(t.entered_outside.unwrap_or(0.0).max(beyond));
    }
    match t.entered_outside {
        Some(e) if beyond > 0.0 => POS_TOL + e,
        _ => {
            t.entered_outside = None;
            POS_TOL
        }
    }
}

/// Add the sample `q` (rad) at `now` (µs) to `t`'s window; the average speed (rad/s) since the
/// newest sample at least [`WINDOW_US`] old, with that sample's time, once there is one.
fn window_speed(t: &mut Track, now: u64, q: f64) -> Option<(f64, u64)> {
    t.samples.push_back((now, q));
    // The newest sample at least a window old, and the average speed since.
    while t.samples.get(1).is_some_and(|s| now - s.0 >= WINDOW_US) {
        t.samples.pop_front();
    }
    let &(t0, q0) = t.samples.front().filter(|s| now - s.0 >= WINDOW_US)?;
    Some(((q - q0).abs() / ((now - t0) as f64 * 1e-6), t0))
}
