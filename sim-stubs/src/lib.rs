//! # ferrobot-sim
//!
//! Simulated plants that speak the real wire protocols, so that the firmware's real drivers
//! run in every backend and outside peers (the official ROBOTIS SDK) can talk to them:
//!
//! * [`chain`]: a Dynamixel Protocol 2.0 servo chain of X-series servos ([`servo`]) with
//!   control table, internal PID, motor and gear dynamics, backlash, quantisation, noise,
//!   overload errors, and gravity load from the arm's link masses ([`arm`]);
//! * [`bases`]: a Kobuki and a Create 2 over a differential-drive model ([`diff_drive`]) with
//!   actuator lag, acceleration limits, seeded slip, encoder quantisation and ground truth;
//! * [`lockstep`]: the firmware core and the plants on one virtual clock, with a frame-level
//!   host session;
//! * [`world`]: the scene's rigid bodies and the robot's links in rapier3d, in lockstep with
//!   the plants (contacts drive the bumpers and the gripper's load);
//! * [`shared`]: several robots in one world on one clock;
//! * [`serve`]: the plants on pseudo-terminals in real time (`ferrobot-sim serve`).
//!
//! Every plant is deterministic for a seed.
#![warn(missing_docs)]

pub mod arm;
pub mod bases;
#[cfg(feature = "serve")]
pub mod board;
pub mod body;
pub mod camera;
#[cfg(feature = "serve")]
pub mod camera_server;
pub mod chain;
pub mod conductor;
pub mod console;
pub mod diff_drive;
#[cfg(feature = "serve")]
pub mod firmware_server;
pub mod floor_plan;
pub mod hardware;
pub mod hostile;
pub mod hull;
pub mod lockstep;
pub mod mesh;
pub mod placement;
pub mod render;
pub mod rng;
pub mod robots;
pub mod scene;
pub mod serial_line;
#[cfg(feature = "serve")]
pub mod serve;
pub mod servo;
pub mod shared;
pub mod world;

pub use lockstep::{HostSide, LockstepSim, SimError, SimHost};
