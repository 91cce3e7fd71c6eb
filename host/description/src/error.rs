//! Errors of a description, and the two helpers every check builds them with: an error naming
//! the file, the key and the problem, and the check of a number against a closed range.

use std::path::{Path, PathBuf};

/// Everything that can go wrong with a description.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// No bundled robot of that name.
    #[error("unknown robot {name:?}; bundled robots are: {known}")]
    UnknownRobot {
        /// The name asked for.
        name: String,
        /// The bundled names, comma-separated.
        known: String,
    },
    /// A configuration file is missing, unreadable or invalid.
    #[error("{file}: {key}: {problem}", file = file.display())]
    Config {
        /// The file.
        file: PathBuf,
        /// The key (dotted path) concerned, or `-` for the whole file.
        key: String,
        /// What is wrong.
        problem: String,
    },
    /// An unknown name (a base controller).
    #[error("unknown {what} {name:?}")]
    UnknownName {
        /// What kind of name.
        what: &'static str,
        /// The name.
        name: String,
    },
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// The error that `key` (a dotted path, or `-` for the whole file) of `file` has `problem`.
pub fn config_error(file: &Path, key: impl Into<String>, problem: impl Into<String>) -> Error {
    Error::Config {
        file: file.to_path_buf(),
        key: key.into(),
        problem: problem.into(),
    }
}

/// `value` finite and within `[lo, hi]`, or an error naming the file and the key.
pub fn in_range(file: &Path, key: impl Into<String>, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        return Ok(());
    }
    Err(config_error(
        file,
        key,
        format!("{value} is not a finite number in [{lo}, {hi}]"),
    ))
}
