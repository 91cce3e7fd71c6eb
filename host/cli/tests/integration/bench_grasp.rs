//! `ferrobot bench grasp`: one seeded trial on the in-process simulator and the same trial,
//! unchanged, against the real firmware in QEMU (`--backend emulated`, the board's ELF built
//! by `scripts/build-boards.sh`, which CI runs first): the JSON summary's shape, and the object
//! lifted 5 cm and held 2 s by the simulator's ground truth on both backends.

use std::path::Path;
use std::process::Command;

/// Runs `ferrobot bench grasp locobot --trials 1 --seed 1 --json` with `extra` from the
/// repository's root (where the default firmware path points); returns the JSON and all text.
fn bench(extra: &[&str]) -> (serde_json::Value, String) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .current_dir(&root)
        .args(["bench", "grasp", "locobot", "--scene", "tabletop"])
        .args(["--trials", "1", "--seed", "1", "--json"])
        .args(extra)
        .output()
        .expect("runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{text}");
    let v = serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
    (v, text)
}

fn check(v: &serde_json::Value, text: &str) {
    assert_eq!(v["trials"], 1, "{text}");
    assert_eq!(v["success_rate"], 1.0, "{text}");
    assert_eq!(v["failures"].as_array().map(Vec::len), Some(0), "{text}");
    let t = v["time_s"]["median"].as_f64().expect("a median time");
    // Look, plan, descend, close, lift: seconds of simulated time, not minutes.
    assert!(t > 1.0 && t < 60.0, "{t} s: {text}");
}

#[test]
fn one_grasp_trial_on_the_simulator() {
    let (v, text) = bench(&[]);
    check(&v, &text);
}

#[test]
fn one_grasp_trial_through_the_firmware_in_qemu() {
    let (v, text) = bench(&["--backend", "emulated"]);
    check(&v, &text);
}
