//! Ferrobot's geometry layer, below every host crate: the one angle wrap and the validation of
//! numbers ([`validate`]). Units are SI; angles in rad.

pub mod validate;

pub use validate::ValueError;

/// Wrap an angle (rad) to (−π, π]: the one convention of every host crate, the firmware and
/// the plants (`ferrobot_protocol::geometry::wrap`).
pub fn wrap(a: f64) -> f64 {
    ferrobot_protocol::geometry::wrap(a)
}

pub use ferrobot_protocol::geometry::arc_step;

#[cfg(test)]
mod tests {
    use super::*;

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
