//! Collision checking vectorised over configurations, in VAMP's manner (Thomason, Kingston and
//! Kavraki, ICRA 2024): the robot's spheres placed for [`WIDTH`] configurations at once by
//! forward kinematics compiled from the collision model ([`SphereProgram`]), in `f32` lanes,
//! with a scalar path that gives the same bits for each configuration.
//!
//! Frames: the robot's root frame; lengths in m, angles in rad.

mod environment;
mod lane;
mod program;

pub use environment::Environment;
pub use lane::{sin_cos, splat_all, Lane, Wide, WIDTH};
pub use program::{Frame, ProgramSphere, SphereProgram};
