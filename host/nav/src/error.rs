//! The error of this crate.

pub use ferrobot_geometry::ValueError;

/// Everything that can go wrong here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A NaN or infinite value.
    #[error("{what} is not a finite number: {value}")]
    NotFinite {
        /// What.
        what: String,
        /// The value.
        value: f64,
    },
    /// A finite number outside the accepted range.
    #[error("{what} = {} is outside the accepted range [{}, {}]", ferrobot_geometry::validate::num(*value), ferrobot_geometry::validate::num(*min), ferrobot_geometry::validate::num(*max))]
    OutOfRange {
        /// What.
        what: String,
        /// The value.
        value: f64,
        /// Smallest accepted.
        min: f64,
        /// Largest accepted.
        max: f64,
    },
    /// An occupancy-grid map that cannot be used.
    #[error("invalid map: {why}")]
    InvalidMap {
        /// Why.
        why: String,
    },
}

impl From<ValueError> for Error {
    fn from(e: ValueError) -> Self {
        match e {
            ValueError::NotFinite { what, value } => Error::NotFinite { what, value },
            ValueError::OutOfRange {
                what,
                value,
                min,
                max,
            } => Error::OutOfRange {
                what,
                value,
                min,
                max,
            },
            // `ValueError` is non-exhaustive: anything newer is reported as its message.
            other => Error::OutOfRange {
                what: other.to_string(),
                value: f64::NAN,
                min: f64::NAN,
                max: f64::NAN,
            },
        }
    }
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
