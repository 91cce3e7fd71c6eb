//! Arm motion planning for Ferrobot.
//!
//! - [`model`]: the robot's collision model from its description: each link's collision
//!   shapes, a conservative sphere set per link for the broad check, and the self-collision
//!   matrix computed by sampling ([`acm`]).
//! - [`scene`]: the planning scene: world objects, objects attached to the gripper, voxels
//!   from a point cloud.
//! - [`checker`]: state and motion (edge) validity against the scene and the robot itself.
//! - [`planner`]: planners behind one trait (RRT-Connect with shortcutting, an informed
//!   asymptotically optimal planner).
//! - [`joint_space`]: the distance between joint vectors.
//! - [`timing`]: time-optimal parameterisation of a path under velocity and acceleration
//!   limits.
//!
//! Units are SI (m, rad, s); poses are in the frame of the robot description's root link
//! unless said otherwise. Algorithms here know nothing of wires, backends or the CLI.

pub mod acm;
pub mod bench;
mod boxes;
pub mod checker;
mod coarse;
mod convert;
pub mod error;
pub mod joint_space;
pub mod lanes;
pub mod model;
pub mod planner;
pub mod scene;
mod segments;
pub mod shape;
pub mod spheres;
pub mod timing;

pub use acm::SelfCollisionMatrix;
pub use checker::{CheckOptions, Checker, Contact, MAX_PADDING};
pub use error::{Error, Result};
pub use model::{config_geometry, CollisionModel, LinkGeometry};
pub use planner::{InformedRrtStar, Plan, PlanOptions, Planner, RrtConnect};
pub use scene::{AttachedObject, PlanningScene, Voxels, WorldObject};
pub use shape::Shape;
pub use timing::{time_optimal, Limits, TimingOptions, Trajectory, TrajectoryPoint};
