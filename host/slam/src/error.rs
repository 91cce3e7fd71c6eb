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

/// The bytes of the regular file `path`, at most `max` of them: anything else (a missing
/// file, a device, a folder, a larger file) is an error naming the file.
pub(crate) fn read_file(path: &std::path::Path, max: u64) -> Result<Vec<u8>> {
    let bad = |why: String| Error::File {
        path: path.to_path_buf(),
        why,
    };
    let meta = std::fs::metadata(path).map_err(|e| bad(e.to_string()))?;
    if !meta.is_file() || meta.len() > max {
        return Err(bad(format!("not a regular file of at most {max} bytes")));
    }
    std::fs::read(path).map_err(|e| bad(e.to_string()))
}

/// Writes `data` to `path`; an error names the file.
pub(crate) fn write_file(path: &std::path::Path, data: impl AsRef<[u8]>) -> Result<()> {
    std::fs::write(path, data).map_err(|e| Error::File {
        path: path.to_path_buf(),
        why: e.to_string(),
    })
}
