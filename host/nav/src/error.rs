//! The error of this crate.

pub use ferrobot_geometry::ValueError;

/// Everything that can go wrong here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A number that is not valid where it was given (not finite, or out of range).
    #[error(transparent)]
    Value(#[from] ValueError),
    /// An occupancy-grid map that cannot be used.
    #[error("invalid map: {why}")]
    InvalidMap {
        /// Why.
        why: String,
    },
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
