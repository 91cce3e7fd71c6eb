//! Each fuzz target, built as a replay program (no libFuzzer), runs clean on a seeded handful
//! of inputs from a corpus directory and on a single input file.

use std::path::PathBuf;
use std::process::Command;

/// A directory of `n` inputs from a seeded generator, 0 to 599 bytes long; a byte in four is a
/// frame or packet delimiter's usual value, so that decoders get past their first byte.
fn corpus(name: &str, n: usize) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ferrobot-fuzz-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("corpus directory");
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    for i in 0..n {
        let len = (next() % 600) as usize;
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                let r = next();
                match r % 4 {
                    0 => [0x00, 0xFF, 0xFD, 0xAA, 0x55][(r >> 8) as usize % 5],
                    _ => (r >> 16) as u8,
                }
            })
            .collect();
        std::fs::write(dir.join(format!("input-{i:02}")), bytes).expect("input");
    }
    dir
}

/// Runs the replay program `exe` on `args`; its stdout (fails the test if the program fails).
fn replay(exe: &str, args: &[PathBuf]) -> String {
    let out = Command::new(exe).args(args).output().expect("runs");
    assert!(
        out.status.success(),
        "{exe} failed on {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn every_target_replays_a_corpus_and_a_file() {
    let targets = [
        ("host_frames", env!("CARGO_BIN_EXE_host_frames"), 24),
        ("dxl_packets", env!("CARGO_BIN_EXE_dxl_packets"), 24),
        ("base_packets", env!("CARGO_BIN_EXE_base_packets"), 24),
        // Each input runs the lockstep simulator for seconds of simulated time.
        ("firmware_core", env!("CARGO_BIN_EXE_firmware_core"), 8),
    ];
    for (name, exe, n) in targets {
        let dir = corpus(name, n);
        let out = replay(exe, std::slice::from_ref(&dir));
        assert!(out.contains(&format!("ran {n} inputs")), "{name}: {out}");
        let out = replay(exe, &[dir.join("input-00")]);
        assert!(out.contains("ran 1 inputs"), "{name}: {out}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn a_missing_input_is_an_error_not_a_pass() {
    let out = Command::new(env!("CARGO_BIN_EXE_host_frames"))
        .arg("/nonexistent/ferrobot-fuzz-input")
        .output()
        .expect("runs");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read"));
}
