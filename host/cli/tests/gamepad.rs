//! The gamepad's mapping (`src/cmd/teleop/gamepad.rs`, feature `gamepad`) and its unit tests,
//! compiled on their own: the binary that uses it has no test harness (see Cargo.toml).

#[allow(dead_code)]
#[path = "../src/cmd/teleop/gamepad.rs"]
mod gamepad;
