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
    /// No joint configuration reaches the pose.
    #[error("unreachable pose: {why}")]
    Unreachable {
        /// Why.
        why: String,
    },
    /// An unknown joint or frame name.
    #[error("unknown {what} {name:?}")]
    UnknownName {
        /// `joint` or `frame`.
        what: &'static str,
        /// The name.
        name: String,
    },
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
