//! What the CLI's test files share.

use std::process::Command;

/// Run the `ferrobot` binary with `args`: whether it succeeded, its standard output as JSON
/// (`Null` when it is not JSON), and its standard output and error as text.
pub fn ferrobot(args: &[&str]) -> (bool, serde_json::Value, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(args)
        .output()
        .expect("runs");
    let v = serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), v, text)
}
