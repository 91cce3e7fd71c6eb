//! The error of this crate.

pub use ferrobot_geometry::ValueError;

/// Everything that can go wrong here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A number that is not valid where it was given (not finite, or out of range).
    #[error(transparent)]
    Value(#[from] ValueError),
    /// A vector has the wrong number of values.
    #[error("{what}: expected {expected} values, got {got}")]
    JointCount {
        /// What was passed.
        what: &'static str,
        /// How many were expected.
        expected: usize,
        /// How many were given.
        got: usize,
    },
    /// Odometry calibration could not determine the base's geometry.
    #[error("odometry calibration failed: {why}")]
    Calibration {
        /// Why.
        why: String,
    },
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
