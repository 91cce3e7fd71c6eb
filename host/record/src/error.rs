//! What can go wrong while recording, replaying or exporting.

use std::path::PathBuf;

/// A recording's error.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// The disk is full (or the file reached its size limit): everything before the last
    /// closed chunk is readable (see [`crate::reader::Reading`]).
    #[error("the disk is full: the recording stopped at {written_s:.3} s of the robot's time; what was written before it is readable")]
    DiskFull {
        /// The newest message written, s on the robot's clock.
        written_s: f64,
    },
    /// Another I/O error.
    #[error("{what} {path}: {source}")]
    Io {
        /// What was being done.
        what: &'static str,
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// The MCAP library's error.
    #[error("MCAP: {0}")]
    Mcap(#[from] mcap::McapError),
    /// The robot refused a subscription or lacks what was asked for.
    #[error(transparent)]
    Robot(#[from] ferrobot::Error),
    /// A value outside its range.
    #[error("{what} must be in [{min}, {max}], not {value}")]
    OutOfRange {
        /// The value's name.
        what: &'static str,
        /// The value.
        value: f64,
        /// Least allowed.
        min: f64,
        /// Most allowed.
        max: f64,
    },
    /// A file that is not an MCAP recording.
    #[error("{} is not an MCAP recording (its first bytes are not MCAP's magic)", path.display())]
    NotMcap {
        /// The file.
        path: PathBuf,
    },
    /// A recorded message that does not decode.
    #[error("a recorded message does not decode: {0}")]
    Decode(String),
    /// Recordings that do not make one dataset (none, no task, different robots or camera
    /// sizes, no joint states).
    #[error("{0}")]
    Dataset(String),
    /// The recorder's thread failed.
    #[error("the recorder's thread panicked")]
    Thread,
}

impl RecordError {
    /// Whether an MCAP error is the disk being full.
    pub(crate) fn is_disk_full(e: &mcap::McapError) -> bool {
        let io = match e {
            mcap::McapError::Io(io) => io,
            _ => return false,
        };
        matches!(
            io.kind(),
            std::io::ErrorKind::StorageFull | std::io::ErrorKind::FileTooLarge
        ) || io.raw_os_error() == Some(28) // ENOSPC, where the kind is not mapped
    }
}

/// `value` within `1..=max`, else [`RecordError::OutOfRange`] naming `what`.
pub(crate) fn check(what: &'static str, value: usize, max: usize) -> Result<(), RecordError> {
    if (1..=max).contains(&value) {
        return Ok(());
    }
    Err(RecordError::OutOfRange {
        what,
        value: value as f64,
        min: 1.0,
        max: max as f64,
    })
}

impl From<RecordError> for ferrobot::Error {
    /// The API's error of a recording's: the robot's own, a range, or an I/O error that keeps
    /// the message (a full disk is `StorageFull`).
    fn from(e: RecordError) -> ferrobot::Error {
        use std::io::{Error as IoError, ErrorKind};
        match e {
            RecordError::Robot(e) => e,
            RecordError::OutOfRange {
                what,
                value,
                min,
                max,
            } => ferrobot::Error::OutOfRange {
                what: what.to_string(),
                value,
                min,
                max,
            },
            RecordError::DiskFull { .. } => {
                ferrobot::Error::Io(IoError::new(ErrorKind::StorageFull, e.to_string()))
            }
            RecordError::NotMcap { .. } | RecordError::Decode(_) | RecordError::Dataset(_) => {
                ferrobot::Error::Usage(e.to_string())
            }
            RecordError::Io { path, source, .. } if source.kind() == ErrorKind::AlreadyExists => {
                ferrobot::Error::PathExists { path }
            }
            RecordError::Io { ref source, .. } => {
                ferrobot::Error::Io(IoError::new(source.kind(), e.to_string()))
            }
            e => ferrobot::Error::Io(IoError::other(e.to_string())),
        }
    }
}
