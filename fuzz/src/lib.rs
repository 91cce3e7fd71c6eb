//! # ferrobot-fuzz
//!
//! Fuzz targets of the wire codecs and the firmware core (`fuzz_targets/`, run with
//! `cargo fuzz run --features libfuzzer TARGET`). Built without the `libfuzzer` feature, as
//! the workspace's builds and CI build them, each target is an ordinary program whose `main`
//! is [`replay`]: it runs the target once on each input file named on its command line (a
//! crash file that `cargo fuzz` saved, or every file of a corpus directory), so a crash is
//! reproduced, and a corpus re-run, with the stable toolchain and no libFuzzer.

// `cargo fuzz` builds with `--cfg fuzzing`: the targets then have no `main` of their own and
// need libFuzzer's.
#[cfg(all(fuzzing, not(feature = "libfuzzer")))]
compile_error!("fuzzing needs libFuzzer linked: `cargo fuzz run --features libfuzzer TARGET`");

use std::ffi::OsString;
use std::fmt;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Declares a fuzz target's entry points for `run` (a `fn(&[u8])`): libFuzzer's, through
/// `libfuzzer_sys::fuzz_target!`, and, without libFuzzer, a `main` that [`replay`]s the input
/// files named on the command line. The target file still starts with
/// `#![cfg_attr(fuzzing, no_main)]` (an inner attribute, which a macro cannot give).
#[macro_export]
macro_rules! target {
    ($run:path) => {
        $crate::__libfuzzer_sys::fuzz_target!(|data: &[u8]| $run(data));

        /// Without libFuzzer: replay the input files (or corpus directories) named on the
        /// command line.
        #[cfg(not(fuzzing))]
        fn main() -> ::std::process::ExitCode {
            $crate::replay($run, ::std::env::args_os().skip(1))
        }
    };
}

#[doc(hidden)]
pub use libfuzzer_sys as __libfuzzer_sys;

/// Run `target` on every input named by `args` (a program's arguments, without its name): a
/// file, or every file in a directory and its subdirectories, in name order, as libFuzzer
/// reads a corpus. Each input's path is printed on stderr before it runs (as libFuzzer's
/// `Running:` lines), so an abort or a hang names its input too. Fails when an input cannot be
/// read, when a run panics (naming the input), or when the arguments name no input at all (an
/// empty directory); no argument runs the empty input once.
pub fn replay(target: fn(&[u8]), args: impl IntoIterator<Item = OsString>) -> ExitCode {
    let args: Vec<PathBuf> = args.into_iter().map(PathBuf::from).collect();
    match replay_paths(target, &args) {
        Ok(0) => {
            println!("ran the empty input (name input files or corpus directories to replay them)");
            ExitCode::SUCCESS
        }
        Ok(n) => {
            println!("ran {n} inputs");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("{e}");
            ExitCode::FAILURE
        }
    }
}

/// Why a replay failed.
#[derive(Debug, PartialEq)]
pub enum ReplayError {
    /// A named path, or a file in a named directory, could not be read.
    Unreadable(PathBuf, String),
    /// The arguments named only empty directories.
    NoInputs(Vec<PathBuf>),
    /// The target panicked on this input.
    Crash(PathBuf),
}

impl fmt::Display for ReplayError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplayError::Unreadable(p, e) => write!(f, "error: cannot read {}: {e}", p.display()),
            ReplayError::NoInputs(args) => write!(f, "error: no input files in {args:?}"),
            ReplayError::Crash(p) => write!(f, "crash: {}", p.display()),
        }
    }
}

/// [`replay`]'s work: how many inputs ran (0: the empty input, for no arguments).
pub fn replay_paths(target: fn(&[u8]), args: &[PathBuf]) -> Result<usize, ReplayError> {
    if args.is_empty() {
        return run_one(target, &[], Path::new("<empty input>")).map(|()| 0);
    }
    let mut inputs = Vec::new();
    for path in args {
        collect(path, &mut inputs)
            .map_err(|e| ReplayError::Unreadable(path.clone(), e.to_string()))?;
    }
    if inputs.is_empty() {
        return Err(ReplayError::NoInputs(args.to_vec()));
    }
    for path in &inputs {
        let bytes = std::fs::read(path)
            .map_err(|e| ReplayError::Unreadable(path.clone(), e.to_string()))?;
        eprintln!("Running: {}", path.display());
        run_one(target, &bytes, path)?;
    }
    Ok(inputs.len())
}

/// `target` on `bytes`; a panic is a crash of `path`.
fn run_one(target: fn(&[u8]), bytes: &[u8], path: &Path) -> Result<(), ReplayError> {
    std::panic::catch_unwind(|| target(bytes)).map_err(|_| ReplayError::Crash(path.to_path_buf()))
}

/// `path` itself, or the files inside it and its subdirectories, in name order.
fn collect(path: &Path, into: &mut Vec<PathBuf>) -> std::io::Result<()> {
    if path.is_dir() {
        let mut entries = std::fs::read_dir(path)?
            .map(|e| e.map(|e| e.path()))
            .collect::<std::io::Result<Vec<_>>>()?;
        entries.sort();
        for entry in entries {
            collect(&entry, into)?;
        }
    } else {
        // A missing path or a broken link is an error here, not a silent skip.
        std::fs::metadata(path)?;
        into.push(path.to_path_buf());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Panics on inputs that start with 0xFF.
    fn picky(data: &[u8]) {
        assert!(data.first() != Some(&0xFF), "0xFF first");
    }

    #[test]
    fn a_crash_is_reported_with_its_input_and_others_pass() {
        let dir = std::env::temp_dir().join(format!("ferrobot-fuzz-lib-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(dir.join("a"), [1, 2, 3]).unwrap();
        std::fs::write(dir.join("b"), []).unwrap();
        std::fs::write(dir.join("sub").join("c"), [7]).unwrap();
        let args = [dir.clone()];
        assert_eq!(replay_paths(picky, &args), Ok(3), "subdirectories are read");
        std::fs::write(dir.join("sub").join("d"), [0xFF]).unwrap();
        assert_eq!(
            replay_paths(picky, &args),
            Err(ReplayError::Crash(dir.join("sub").join("d")))
        );
        assert_eq!(
            replay(picky, [dir.clone().into_os_string()]),
            ExitCode::FAILURE
        );
        assert_eq!(replay_paths(picky, &[]), Ok(0));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_empty_directory_or_a_missing_path_is_an_error() {
        let dir = std::env::temp_dir().join(format!("ferrobot-fuzz-empty-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("only-a-subdirectory")).unwrap();
        let args = [dir.clone()];
        assert_eq!(
            replay_paths(picky, &args),
            Err(ReplayError::NoInputs(args.to_vec()))
        );
        let missing = dir.join("missing");
        assert!(matches!(
            replay_paths(picky, std::slice::from_ref(&missing)),
            Err(ReplayError::Unreadable(p, _)) if p == missing
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
