//! A described robot made whole. A robot's description (`ferrobot-description`) is checked
//! against what runs it: the wire's ranges (`ferrobot_protocol::ranges`, the joint count),
//! the firmware (its servo bus) and the arm's kinematic chain, with errors naming the file
//! and key as the description's do. Every loader of a robot that is to run loads it here
//! ([`load`], [`bundled`], [`from_file`], [`parse`]). From a loaded description come the
//! firmware profile a board runs ([`firmware_profile`]), the firmware's joint table, the arm
//! chain, the gripper driver, the wheel geometry and the base kind as the protocol names it.

#![warn(missing_docs)]

mod checks;
mod derive;
mod dynamics;

use std::path::Path;

use ferrobot_description::{ConfigSource, Result, RobotConfig};

pub use checks::ProfileChecks;
pub use derive::{
    arm_chain, base_kind, direct_profile, firmware_profile, gripper_driver, joint_row, joint_table,
    nominal_geometry, odometry_geometry,
};
pub use dynamics::{arm_links, arm_model, ModelLink};

/// Load a robot from `source` with `overrides` (dotted keys) applied, checked whole: the
/// description's checks and [`ProfileChecks`].
pub fn load(source: &ConfigSource, overrides: &[(String, toml::Value)]) -> Result<RobotConfig> {
    RobotConfig::load_with(source, overrides, &ProfileChecks)
}

/// A bundled robot by name, checked whole.
pub fn bundled(name: &str) -> Result<RobotConfig> {
    load(&ConfigSource::Bundled(name.to_string()), &[])
}

/// A robot from a TOML file (its `urdf` path relative to the file), checked whole.
pub fn from_file(path: impl AsRef<Path>) -> Result<RobotConfig> {
    load(&ConfigSource::File(path.as_ref().to_path_buf()), &[])
}

/// A robot from TOML text (named `file` in errors), `read_urdf` fetching the URDF it names,
/// checked whole.
pub fn parse(
    text: &str,
    file: &Path,
    read_urdf: impl FnOnce(&str) -> Result<String>,
) -> Result<RobotConfig> {
    RobotConfig::parse_with(text, file, read_urdf, &ProfileChecks)
}
