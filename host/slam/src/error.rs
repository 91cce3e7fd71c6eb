//! The error of this crate.

/// Everything that can go wrong here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Settings or a camera model that cannot be used.
    #[error("invalid SLAM settings: {why}")]
    InvalidSettings {
        /// Why.
        why: String,
    },
    /// A frame that cannot be used (sizes, non-finite numbers).
    #[error("invalid frame: {why}")]
    InvalidFrame {
        /// Why.
        why: String,
    },
    /// A trajectory file or dataset that cannot be read or written.
    #[error("{}: {why}", path.display())]
    File {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        why: String,
    },
    /// Trajectories that cannot be compared.
    #[error("cannot compare trajectories: {why}")]
    Trajectory {
        /// Why.
        why: String,
    },
}

/// This crate's result.
pub type Result<T, E = Error> = core::result::Result<T, E>;
