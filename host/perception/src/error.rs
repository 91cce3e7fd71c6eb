//! The crate's error.

use std::path::PathBuf;

/// What went wrong in perception: bad inputs are named, never guessed around.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PerceptionError {
    /// A pixel index lies outside the image.
    #[error("pixel (row {row}, column {col}) is outside the {width}x{height} image")]
    PixelOutside {
        /// Row asked for.
        row: i64,
        /// Column asked for.
        col: i64,
        /// Image width, px.
        width: u32,
        /// Image height, px.
        height: u32,
    },
    /// Row and column lists of different lengths.
    #[error("{rows} rows but {cols} columns: give one row and one column per pixel")]
    PixelCount {
        /// Number of rows given.
        rows: usize,
        /// Number of columns given.
        cols: usize,
    },
    /// Intrinsics that no camera has (non-finite or non-positive focal lengths, empty image,
    /// principal point far outside the image).
    #[error("invalid camera intrinsics: {0}")]
    Intrinsics(String),
    /// A depth filter range that keeps nothing or is not finite.
    #[error("invalid depth range ({min}, {max}) m: need 0 <= min < max <= 1000")]
    DepthRange {
        /// Lower bound, m.
        min: f64,
        /// Upper bound, m.
        max: f64,
    },
    /// Images or buffers whose sizes disagree.
    #[error("size mismatch: {0}")]
    Size(String),
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file whose content is not what it should be.
    #[error("{}: {problem}", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

/// The crate's result.
pub type Result<T> = std::result::Result<T, PerceptionError>;
