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
    /// A cloud (or a selection of one) with no points where points are needed.
    #[error("the {what} has no points")]
    EmptyCloud {
        /// Which cloud: "cloud", "object", "plane's inliers", ...
        what: &'static str,
    },
    /// A point with a NaN or infinite coordinate.
    #[error("point {index} is not finite: ({x}, {y}, {z}) m")]
    NonFinitePoint {
        /// Index of the point in its cloud.
        index: usize,
        /// x, m.
        x: f64,
        /// y, m.
        y: f64,
        /// z, m.
        z: f64,
    },
    /// A finite point too far from its frame's origin to come from any sensor (beyond
    /// [`MAX_COORDINATE`](crate::cloud::MAX_COORDINATE) on some axis); squared distances
    /// between such points would overflow.
    #[error("point {index} ({x}, {y}, {z}) m lies beyond +-{limit} m of the origin")]
    PointOutOfRange {
        /// Index of the point in its cloud.
        index: usize,
        /// x, m.
        x: f64,
        /// y, m.
        y: f64,
        /// z, m.
        z: f64,
        /// The limit on each coordinate, m.
        limit: f64,
    },
    /// A parameter outside its range (not finite, not positive, absurdly large).
    #[error("{name} = {value} is out of range: {range}")]
    Parameter {
        /// The parameter.
        name: &'static str,
        /// The value given (counts as a float).
        value: f64,
        /// The range it must lie in, in words.
        range: &'static str,
    },
    /// Fewer points than an algorithm needs.
    #[error("{what} needs at least {need} points, got {got}")]
    TooFewPoints {
        /// What needed them.
        what: &'static str,
        /// Points needed.
        need: usize,
        /// Points given.
        got: usize,
    },
    /// RANSAC found no plane with enough inliers (the cloud holds no plane at the
    /// threshold, or every sample was degenerate).
    #[error(
        "no plane found: the best of {hypotheses} plane hypotheses had {best_inliers} inliers \
         within {threshold} m, fewer than the {min_inliers} required"
    )]
    NoPlane {
        /// Non-degenerate hypotheses scored.
        hypotheses: usize,
        /// Inliers of the best one.
        best_inliers: usize,
        /// Inlier distance, m.
        threshold: f64,
        /// Inliers required.
        min_inliers: usize,
    },
    /// A push, a grasp or a pick was asked for on a table with no object on it (none found
    /// above the table's plane).
    #[error("no object on the table")]
    NoObjectOnTable,
    /// Objects lie on the table, but none can be pushed: every object and direction tried
    /// left the arm's reach, came near another object or drove the object off the table.
    #[error(
        "none of the {objects} objects on the table can be pushed clear of the others within reach"
    )]
    NoPush {
        /// Objects on the table.
        objects: usize,
    },
    /// The fiducial marker was not found in an image (or in any image).
    #[error("marker not seen: {0}")]
    MarkerNotSeen(String),
    /// Hand-eye calibration cannot determine the camera's mount from what it was given (too
    /// few images of the marker, or views that leave a direction unobserved).
    #[error("hand-eye calibration: {0}")]
    HandEye(String),
    /// The k-d tree could not be built (kiddo refused the points).
    #[error("k-d tree: {0}")]
    KdTree(String),
}

impl PerceptionError {
    /// Whether the caller's input is at fault (a bad value, file, image or cloud), as
    /// opposed to the world (no plane where one was expected).
    pub fn is_input(&self) -> bool {
        !matches!(
            self,
            PerceptionError::NoPlane { .. }
                | PerceptionError::NoObjectOnTable
                | PerceptionError::NoPush { .. }
                | PerceptionError::MarkerNotSeen(_)
                | PerceptionError::HandEye(_)
        )
    }
}

/// The crate's result.
pub type Result<T> = std::result::Result<T, PerceptionError>;
