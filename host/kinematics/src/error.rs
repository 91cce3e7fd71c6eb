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
