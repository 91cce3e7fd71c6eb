//! `ferrobot`'s integration tests as one binary: a module per former test file.

mod api_sim;
mod base_control;
mod camera;
mod common;
mod concurrency;
mod hostile_api;
mod kinematics;
mod navigation;
mod planning;
#[cfg(feature = "serial")]
mod realsense;
mod shared_world;
mod slam;
mod stow;
mod subscriptions;
mod teach;
mod world;
