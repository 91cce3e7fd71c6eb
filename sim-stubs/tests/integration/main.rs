//! `ferrobot-sim`'s integration tests as one binary: a module per former test file.

mod camera;
mod clutter;
mod common;
mod conductor;
// Runs the `ferrobot-sim` binary, built only with the `cli` feature.
#[cfg(feature = "cli")]
mod dynamixel_sdk;
mod estop_states;
mod hostile;
mod hostile_cases;
mod lockstep_arm;
mod lockstep_base;
mod lockstep_faults;
mod physics;
mod scenes;
