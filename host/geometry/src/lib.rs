//! Ferrobot's geometry layer, below every host crate: the one angle wrap, the validation of
//! numbers ([`validate`]) and an inlined sine and cosine ([`trig`]). Units are SI; angles in rad.

pub mod trig;
pub mod validate;

pub use validate::ValueError;

/// Wrap an angle (rad) to (−π, π]: the one convention of every host crate, the firmware and
/// the plants (`ferrobot_planar::wrap` in `f64`, so that literals need no type).
pub fn wrap(a: f64) -> f64 {
    ferrobot_planar::wrap(a)
}

pub use ferrobot_planar::arc_step;

/// A pose in the plane (SE(2)): the position `x`, `y` (m) and heading `theta` (rad) of a frame
/// in a parent frame, e.g. a base in the odometry frame. Arrays `[x, y, θ]` convert both ways.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose2 {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// Heading, rad.
    pub theta: f64,
}

impl Pose2 {
    /// The pose at `x`, `y` (m) with heading `theta` (rad).
    pub const fn new(x: f64, y: f64, theta: f64) -> Self {
        Pose2 { x, y, theta }
    }

    /// `self ⊕ other`: the pose `other`, given in this pose's frame, in the parent frame (the
    /// heading wrapped to (−π, π]).
    pub fn compose(&self, other: &Pose2) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2 {
            x: self.x + c * other.x - s * other.y,
            y: self.y + s * other.x + c * other.y,
            theta: wrap(self.theta + other.theta),
        }
    }

    /// The inverse: the parent frame seen from this pose, so that `p.compose(&p.inverse())`
    /// is the identity.
    pub fn inverse(&self) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2 {
            x: -(c * self.x + s * self.y),
            y: s * self.x - c * self.y,
            theta: wrap(-self.theta),
        }
    }

    /// `self⁻¹ ⊕ other`: `other` seen from this pose.
    pub fn between(&self, other: &Pose2) -> Pose2 {
        self.inverse().compose(other)
    }

    /// As `[x, y, θ]`.
    pub fn to_array(self) -> [f64; 3] {
        [self.x, self.y, self.theta]
    }
}

impl From<[f64; 3]> for Pose2 {
    fn from(p: [f64; 3]) -> Self {
        Pose2::new(p[0], p[1], p[2])
    }
}

impl From<Pose2> for [f64; 3] {
    fn from(p: Pose2) -> Self {
        p.to_array()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_compose_invert_and_relate() {
        let a = Pose2::new(1.0, 2.0, 0.5);
        let b = Pose2::new(-0.3, 0.7, -1.2);
        let id = a.compose(&a.inverse());
        assert!(id.x.abs() < 1e-12 && id.y.abs() < 1e-12 && id.theta.abs() < 1e-12);
        let c = a.compose(&b);
        let back = a.between(&c);
        assert!((back.x - b.x).abs() < 1e-12 && (back.y - b.y).abs() < 1e-12);
        assert!((back.theta - b.theta).abs() < 1e-12);
        // A quarter turn: one metre forward from (0, 0, π/2) is (0, 1).
        let q =
            Pose2::new(0.0, 0.0, std::f64::consts::FRAC_PI_2).compose(&Pose2::new(1.0, 0.0, 0.0));
        assert!(q.x.abs() < 1e-12 && (q.y - 1.0).abs() < 1e-12);
    }

    #[test]
    fn wrap_is_half_open_at_minus_pi() {
        use std::f64::consts::PI;
        assert_eq!(wrap(PI), PI);
        assert_eq!(wrap(-PI), PI);
        assert!((wrap(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap(0.5) - 0.5).abs() < 1e-15);
        assert!((wrap(-0.5 - 2.0 * PI) + 0.5).abs() < 1e-12);
    }
}
