//! Robot descriptions: a TOML file naming a URDF and describing the arm, gripper, camera,
//! base and the firmware's joint table. Bundled robots (`locobot`, `locobot_lite`, `sawyer`)
//! are compiled in; any other robot is a TOML file plus its URDF on disk.
//!
//! Loading is strict: unknown keys, wrong types and inconsistencies (an arm joint the URDF
//! lacks, a home vector of the wrong length, duplicate servo IDs…) are errors that name the
//! file, the key and the problem. The checks against what runs a robot (the wire's ranges,
//! the firmware, the kinematic chain) are `ferrobot-profile`'s, run among these through
//! [`Checks`].

#![warn(missing_docs)]

pub mod base;
pub mod camera_mount;
pub mod checks;
pub mod config;
pub mod direct;
pub mod error;
pub mod files;
pub mod joints;
pub mod sections;
mod validate;

pub use base::{BaseController, BaseModel, BaseSection, OdometrySection};
pub use camera_mount::{CameraCalibration, CameraMount};
pub use checks::{Checks, DescriptionOnly, JointEntry};
pub use config::{ConfigSource, RobotConfig};
pub use direct::{DeviceSection, DirectSection};
pub use error::{config_error, in_range, Error, Result};
pub use files::{bundled_files, read_bytes, read_text, BUNDLED, MAX_CONFIG_BYTES, MAX_URDF_BYTES};
pub use joints::{
    Joint, JointLimits, JointRole, JointSection, LimitsOverride, PidSection, ServoModel,
    ServoSection,
};
pub use sections::{
    ArmConfig, BusSection, CameraSection, CollisionSection, FingerSection, GripperSection, IkKind,
    MarkerSection, SimSection,
};
