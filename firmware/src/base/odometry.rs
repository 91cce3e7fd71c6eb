//! Wheel odometry of a differential-drive base, integrated exactly on arcs.

use ferrobot_protocol::geometry::arc_step;
use ferrobot_protocol::Odometry;

/// Integrates wheel travel into a pose.
#[derive(Debug, Clone, Copy, Default)]
pub struct OdometryIntegrator {
    /// Current estimate.
    pub pose: Odometry,
}

impl OdometryIntegrator {
    /// Reset to the origin.
    pub fn reset(&mut self) {
        self.pose = Odometry::default();
    }

    /// Advance by left and right wheel travel (m) over `dt` (s) with wheel separation `track`
    /// (m). The chassis moves on the circular arc the two wheel travels define (a straight line
    /// when they are equal), so the result is exact for constant wheel speeds over the step.
    pub fn update(&mut self, dl: f32, dr: f32, track: f32, dt: f32) {
        self.update_with_heading(dl, dr, (dr - dl) / track, dt);
    }

    /// Advance by left and right wheel travel (m) with the heading change `dth` (rad) measured
    /// independently (a gyro), which wheel-radius and track errors and slip do not bias.
    pub fn update_with_heading(&mut self, dl: f32, dr: f32, dth: f32, dt: f32) {
        let ds = 0.5 * (dl + dr);
        let p = &mut self.pose;
        [p.x, p.y, p.theta] = arc_step([p.x, p.y, p.theta], ds, dth);
        if dt > 0.0 {
            p.v = ds / dt;
            p.w = dth / dt;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrobot_protocol::geometry::wrap;

    /// With a gyro, unequal wheels do not turn the estimate: 1 m of travel whose right wheel
    /// read 1 % more stays straight when the gyro says the heading did not change.
    #[test]
    fn the_gyro_heading_overrides_the_wheels() {
        let mut wheels = OdometryIntegrator::default();
        let mut gyro = OdometryIntegrator::default();
        for _ in 0..100 {
            wheels.update(0.00995, 0.01005, 0.23, 0.01);
            gyro.update_with_heading(0.00995, 0.01005, 0.0, 0.01);
        }
        assert!(
            (wheels.pose.theta - 0.01 / 0.23).abs() < 1e-4,
            "{:?}",
            wheels.pose
        );
        assert!(
            gyro.pose.theta.abs() < 1e-7 && gyro.pose.y.abs() < 1e-7,
            "{:?}",
            gyro.pose
        );
        assert!((gyro.pose.x - 1.0).abs() < 1e-4, "{:?}", gyro.pose);
    }

    #[test]
    fn quarter_circle_is_exact() {
        // Both wheels on a circle of radius 1 m around the point (0, 1): a quarter turn in
        // 100 steps ends at (1, 1) facing +y.
        let track = 0.23f32;
        let quarter = core::f32::consts::FRAC_PI_2;
        let mut o = OdometryIntegrator::default();
        for _ in 0..100 {
            let dth = quarter / 100.0;
            o.update(
                (1.0 - track / 2.0) * dth,
                (1.0 + track / 2.0) * dth,
                track,
                0.01,
            );
        }
        assert!((o.pose.x - 1.0).abs() < 1e-4, "{:?}", o.pose);
        assert!((o.pose.y - 1.0).abs() < 1e-4, "{:?}", o.pose);
        assert!((o.pose.theta - quarter).abs() < 1e-5);
    }

    #[test]
    fn wraps() {
        assert!((wrap(3.5) - (3.5 - core::f32::consts::TAU)).abs() < 1e-6);
        assert!((wrap(-3.5) - (-3.5 + core::f32::consts::TAU)).abs() < 1e-6);
    }
}
