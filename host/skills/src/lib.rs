//! # ferrobot-skills
//!
//! Tasks built only on `ferrobot`'s public API, as `openrr-apps` sits on `arci`: grasping an
//! object from a table ([`grasp::pick`]), pushing one ([`Skills::push_object`]) and the
//! hand-eye calibration of the head camera ([`Skills::calibrate_camera`]). They run on every
//! backend, since they only look and move through the API. PyRobot's base benchmark
//! ([`base_trials`]) is here too, for the command line and the Python package alike.
//!
//! ```no_run
//! use ferrobot_skills::{grasp, Skills};
//! let bot = ferrobot::Robot::builder("locobot").scene("tabletop").build()?;
//! let grasped = grasp::pick(&bot, &grasp::GraspOptions::default())?;
//! let pushed = bot.push_object(&ferrobot_skills::PushOptions::default())?;
//! # Ok::<(), ferrobot_skills::Error>(())
//! ```
//!
//! Units are SI (m, rad, s); frames as in `ferrobot` (`base_link`: x forward, z up).

#[cfg(feature = "sim")]
pub mod base_trials;
pub mod error;
pub mod grasp;
pub mod hand_eye;
pub mod push;

pub use error::{Error, Result};

// The push and the calibration fail only as the robot does (`ferrobot::Error`); a grasp can
// also fail for the world's reasons ([`GraspFailure`]), hence the skills' own [`Error`].
pub use grasp::{GraspFailure, GraspOptions, Grasped};
pub use hand_eye::{HandEyeOptions, HandEyeReport};
pub use push::{PushOptions, Pushed};

/// The skills as methods of a [`ferrobot::Robot`] (bring the trait into scope to call them).
pub trait Skills {
    /// Pushes one object on the table in front of the robot (see [`push`]).
    fn push_object(&self, opts: &PushOptions) -> ferrobot::Result<Pushed>;
    /// Calibrates the head camera's mount against the marker the gripper carries (see
    /// [`hand_eye`]).
    fn calibrate_camera(&self, opts: &HandEyeOptions) -> ferrobot::Result<HandEyeReport>;
}

impl Skills for ferrobot::Robot {
    fn push_object(&self, opts: &PushOptions) -> ferrobot::Result<Pushed> {
        push::push_object(self, opts)
    }

    fn calibrate_camera(&self, opts: &HandEyeOptions) -> ferrobot::Result<HandEyeReport> {
        hand_eye::calibrate_camera(self, opts)
    }
}
