//! Teleoperation without I/O: key events and the robot's clock go in, robot commands come out.
//!
//! The key map is data ([`KeyMap`], PyRobot's `teleop.yaml` by default); the core
//! ([`Teleop`]) turns key presses, auto-repeats and releases into discrete steps (end
//! effector, wrist joints, gripper, pan/tilt) and into base velocities held while their keys
//! are. A terminal that reports key releases gives exact holds; one that does not has its
//! releases inferred from the auto-repeats ([`HoldTiming`]). Nothing here knows of terminals,
//! robots or backends: a shell reads the keys, executes the [`Command`]s and lets time pass.
//!
//! Units are SI: m, rad, m/s, rad/s; times are the robot's clock in seconds.

pub mod core;
pub mod keymap;

pub use crate::core::{Command, HoldTiming, Teleop, TIME_RESOLUTION};
pub use keymap::{Action, Binding, GripperAction, Key, KeyEvent, KeyKind, KeyMap, Step};
