//! The proportional position law, as PyRobot's base controller: turn towards the goal, drive
//! to it (backwards when it lies behind), turn to the goal heading. Poses `[x, y, θ]` (m, m,
//! rad) in the frame of the goal; commands `(v, ω)` (m/s, rad/s).

use std::time::Duration;

use crate::wrap;

/// Control period of the host-side base laws.
pub const CONTROL_PERIOD: Duration = Duration::from_millis(50);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    TurnToGoal,
    Drive,
    TurnToHeading,
}

/// The proportional position controller, as PyRobot's: turn towards the goal, drive to it
/// (backwards when it lies behind), turn to the goal heading. Speeds are proportional to the
/// remaining error, bounded by the limits, ramped at bounded acceleration, and kept above the
/// base's deadband until within tolerance.
#[derive(Debug, Clone)]
pub struct Proportional {
    goal: [f64; 3],
    phase: Phase,
    backwards: bool,
    v: f64,
    w: f64,
    next: Duration,
    max_v: f64,
    max_w: f64,
    min_w: f64,
    tol_xy: f64,
    tol_th: f64,
}

/// Gains and limits of the proportional controller.
pub mod gains {
    /// Forward speed per metre of remaining distance, 1/s.
    pub const K_V: f64 = 1.0;
    /// Yaw rate per radian of heading error, 1/s.
    pub const K_W: f64 = 2.0;
    /// Forward acceleration bound, m/s².
    pub const ACCEL_V: f64 = 0.5;
    /// Yaw acceleration bound, rad/s².
    pub const ACCEL_W: f64 = 2.0;
    /// Smallest forward speed while not yet within tolerance, m/s.
    pub const MIN_V: f64 = 0.02;
    /// Smallest wheel speed while turning and not yet within tolerance, m/s: above the
    /// deadband of the bases' wheel controllers (Kobuki 5 mm/s, Create 2 10 mm/s).
    pub const MIN_WHEEL: f64 = 0.015;
}

impl Proportional {
    /// Heading error (rad) from `th` to the direction of driving towards the goal offset
    /// `(dx, dy)`: its bearing, or the opposite when driving backwards.
    fn drive_heading_error(&self, dx: f64, dy: f64, th: f64) -> f64 {
        let back = if self.backwards {
            std::f64::consts::PI
        } else {
            0.0
        };
        wrap(dy.atan2(dx) + back - th)
    }

    /// Aims at `goal` (the odometry's frame) from `now` on, keeping the present speeds.
    pub fn retarget(&mut self, goal: [f64; 3], now: Duration) {
        self.goal = goal;
        self.phase = Phase::TurnToGoal;
        self.next = now;
    }

    /// The command `(v, ω)` (m/s, rad/s) at `now` from the odometry pose `[x, y, θ]` (m, m,
    /// rad; the goal's frame): recomputed every [`CONTROL_PERIOD`], held between; `None` once
    /// the goal is reached within its tolerances.
    pub fn step(&mut self, now: Duration, pose: [f64; 3]) -> Option<(f64, f64)> {
        if now < self.next {
            return Some((self.v, self.w));
        }
        self.next = now + CONTROL_PERIOD;
        let dt = CONTROL_PERIOD.as_secs_f64();
        let [x, y, th] = pose;
        let (dx, dy) = (self.goal[0] - x, self.goal[1] - y);
        let dist = dx.hypot(dy);
        let mut v = 0.0;
        let w;
        loop {
            match self.phase {
                Phase::TurnToGoal => {
                    if dist < self.tol_xy {
                        self.phase = Phase::TurnToHeading;
                        continue;
                    }
                    self.backwards = wrap(dy.atan2(dx) - th).abs() > std::f64::consts::FRAC_PI_2;
                    let e = self.drive_heading_error(dx, dy, th);
                    if e.abs() < self.tol_th {
                        self.phase = Phase::Drive;
                        continue;
                    }
                    let p = (gains::K_W * e).clamp(-self.max_w, self.max_w);
                    w = p.signum() * p.abs().max(self.min_w);
                }
                Phase::Drive => {
                    let e = self.drive_heading_error(dx, dy, th);
                    // Distance along the heading; past the goal it turns negative.
                    let along = dist * e.cos();
                    if dist < self.tol_xy {
                        self.phase = Phase::TurnToHeading;
                        continue;
                    }
                    if along < 0.0 {
                        // Passed wide of the tolerance (an overshoot, a slip, a push): aim at
                        // the goal again (backwards when it lies behind), never call it reached.
                        self.phase = Phase::TurnToGoal;
                        continue;
                    }
                    let speed = (gains::K_V * along).clamp(gains::MIN_V, self.max_v);
                    v = if self.backwards { -speed } else { speed };
                    w = (gains::K_W * e).clamp(-self.max_w, self.max_w);
                }
                Phase::TurnToHeading => {
                    let e = wrap(self.goal[2] - th);
                    if e.abs() < self.tol_th {
                        self.v = 0.0;
                        self.w = 0.0;
                        return None;
                    }
                    let p = (gains::K_W * e).clamp(-self.max_w, self.max_w);
                    w = p.signum() * p.abs().max(self.min_w);
                }
            }
            break;
        }
        // Ramp: bounded acceleration (braking to zero is never slower than the bound either).
        self.v += (v - self.v).clamp(-gains::ACCEL_V * dt, gains::ACCEL_V * dt);
        self.w += (w - self.w).clamp(-gains::ACCEL_W * dt, gains::ACCEL_W * dt);
        Some((self.v, self.w))
    }
}

impl Proportional {
    /// A law to `goal` `[x, y, θ]` (m, m, rad) starting at rest: speeds bounded by `max_v`
    /// (m/s) and `max_w` (rad/s), turns at least `min_w` (rad/s, above the wheels' deadband)
    /// until within `tol_xy` (m) and `tol_th` (rad).
    pub fn new(
        goal: [f64; 3],
        max_v: f64,
        max_w: f64,
        min_w: f64,
        tol_xy: f64,
        tol_th: f64,
    ) -> Self {
        Proportional {
            goal,
            phase: Phase::TurnToGoal,
            backwards: false,
            v: 0.0,
            w: 0.0,
            next: Duration::ZERO,
            max_v,
            max_w,
            min_w,
            tol_xy,
            tol_th,
        }
    }

    /// The same law with its speed bounds `max_v` (m/s) and `max_w` (rad/s) replaced.
    pub fn with_speed_limits(mut self, max_v: f64, max_w: f64) -> Self {
        self.max_v = max_v;
        self.max_w = max_w;
        self
    }

    /// The same law, its first command computed at `now` (by default at its first step).
    pub fn starting_at(mut self, now: Duration) -> Self {
        self.next = now;
        self
    }

    /// Takes over a base moving at `(v, ω)` (m/s, rad/s) at `now` (e.g. from a local planner
    /// that hands over near the goal).
    pub fn take_over(&mut self, now: Duration, last: (f64, f64)) {
        self.next = now;
        self.v = last.0;
        self.w = last.1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The odometry pose `[x, y, θ]` as the wire carries it (f32).
    fn at(pose: [f64; 3]) -> [f64; 3] {
        pose.map(|x| x as f32 as f64)
    }

    /// A goal at (1, 0) heading 0, being driven to at 0.2 m/s (the Kobuki's limits and
    /// tolerances).
    fn driving() -> Proportional {
        Proportional {
            goal: [1.0, 0.0, 0.0],
            phase: Phase::Drive,
            backwards: false,
            v: 0.2,
            w: 0.0,
            next: Duration::ZERO,
            max_v: 0.5,
            max_w: 1.0,
            min_w: gains::MIN_WHEEL / (0.5 * 0.23),
            tol_xy: 0.02,
            tol_th: 0.05,
        }
    }

    /// Past the goal and 0.3 m to its side, with the goal's heading: the goal is driven to
    /// again, not reached (it was reported reached 0.32 m away), and a unicycle following the
    /// commands ends within the tolerances.
    #[test]
    fn a_goal_passed_wide_of_its_tolerance_is_driven_to_again() {
        let mut g = driving();
        let mut pose = [1.1, 0.3, 0.0];
        let dt = CONTROL_PERIOD.as_secs_f64();
        let mut now = Duration::ZERO;
        let mut steps = 0;
        while let Some((v, w)) = g.step(now, at(pose)) {
            pose[0] += v * pose[2].cos() * dt;
            pose[1] += v * pose[2].sin() * dt;
            pose[2] = wrap(pose[2] + w * dt);
            now += CONTROL_PERIOD;
            steps += 1;
            assert!(steps < 1200, "not reached in 60 s: at {pose:?}");
        }
        assert!(steps > 0, "reported reached at {pose:?}");
        let dist = (pose[0] - 1.0).hypot(pose[1]);
        assert!(dist < 0.02 && pose[2].abs() < 0.05, "ended at {pose:?}");
        // Within the tolerances it is reached at once.
        assert_eq!(driving().step(Duration::ZERO, at([1.01, 0.0, 0.0])), None);
    }
}
