//! The error of this crate.

pub use ferrobot_geometry::ValueError;

/// Everything that can go wrong here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A number or a list of numbers that is not valid where it was given (not finite, out of
    /// range, or of the wrong length).
    #[error(transparent)]
    Value(#[from] ValueError),
    /// Odometry calibration could not determine the base's geometry.
    #[error("odometry calibration failed: {why}")]
    Calibration {
        /// Why.
        why: String,
    },
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
