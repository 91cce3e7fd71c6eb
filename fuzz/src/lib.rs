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

use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Run `target` on every input named by `args`: a file, or every file (not recursively) in a
/// directory, in name order. Prints how many inputs ran; an input whose run panics is named on
/// stderr and ends the replay with a failure. No argument at all runs the empty input once.
pub fn replay(target: fn(&[u8]), args: impl IntoIterator<Item = String>) -> ExitCode {
    let mut inputs = Vec::new();
    for arg in args {
        let path = PathBuf::from(arg);
        if let Err(e) = collect(&path, &mut inputs) {
            eprintln!("error: cannot read {}: {e}", path.display());
            return ExitCode::FAILURE;
        }
    }
    if inputs.is_empty() {
        target(&[]);
        println!("ran the empty input (name input files or corpus directories to replay them)");
        return ExitCode::SUCCESS;
    }
    for path in &inputs {
        let bytes = match std::fs::read(path) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("error: cannot read {}: {e}", path.display());
                return ExitCode::FAILURE;
            }
        };
        let run = std::panic::catch_unwind(|| target(&bytes));
        if run.is_err() {
            eprintln!("crash: {} ({} bytes)", path.display(), bytes.len());
            return ExitCode::FAILURE;
        }
    }
    println!("ran {} inputs", inputs.len());
    ExitCode::SUCCESS
}

/// `path` itself, or the files directly inside it in name order.
fn collect(path: &Path, into: &mut Vec<PathBuf>) -> std::io::Result<()> {
    if path.is_dir() {
        let mut files = std::fs::read_dir(path)?
            .map(|e| e.map(|e| e.path()))
            .collect::<std::io::Result<Vec<_>>>()?;
        files.retain(|p| p.is_file());
        files.sort();
        into.extend(files);
    } else {
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
    fn a_panicking_input_fails_the_replay_and_others_pass() {
        let dir = std::env::temp_dir().join(format!("ferrobot-fuzz-lib-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a"), [1, 2, 3]).unwrap();
        std::fs::write(dir.join("b"), []).unwrap();
        let dir_arg = dir.to_string_lossy().into_owned();
        assert_eq!(replay(picky, [dir_arg.clone()]), ExitCode::SUCCESS);
        std::fs::write(dir.join("c"), [0xFF]).unwrap();
        assert_eq!(replay(picky, [dir_arg]), ExitCode::FAILURE);
        assert_eq!(replay(picky, []), ExitCode::SUCCESS);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
