//! `ferrobot-sim`'s integration tests as one binary: a module per former test file.

mod arm_gravity;
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
mod hull;
mod lockstep_arm;
mod lockstep_base;
mod lockstep_faults;
mod mesh;
mod physics;
mod placement;
mod scenes;
mod shared;
mod teach;
