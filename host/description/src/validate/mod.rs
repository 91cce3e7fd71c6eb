//! The checks of a description against itself, section by section, in the order that decides
//! which error a configuration with several meets first: the joint table, the arm, the
//! gripper, the camera, the base, the bus, the collision matrix. The [`Checks`] beyond the
//! description run at their places among them.

mod arm;
mod base;
mod camera;
mod collision;
mod gripper;
mod joints;

use std::path::Path;

use crate::checks::Checks;
use crate::config::RobotConfig;
use crate::error::Result;
use crate::joints::Joint;
use crate::sections::ConfigFile;

/// The configuration `raw` with its parsed `urdf`, checked (errors name `file`).
pub(crate) fn validate(
    mut raw: ConfigFile,
    urdf: urdf_rs::Robot,
    file: &Path,
    checks: &dyn Checks,
) -> Result<RobotConfig> {
    let joints = joints::table(&raw.joints, &urdf, file, checks)?;
    if let Some(arm) = &mut raw.arm {
        arm::check(arm, &joints, &urdf, file, checks)?;
    }
    gripper::check(raw.gripper.as_ref(), &joints, &urdf, file)?;
    if let Some(c) = &raw.camera {
        camera::check(c, &joints, &urdf, file)?;
    }
    if let Some(b) = &raw.base {
        base::check(b, file, checks)?;
    }
    let bus = raw.bus.unwrap_or_default();
    joints::bus(&bus, file, checks)?;
    if let Some(d) = &raw.direct {
        joints::direct(d, raw.base.is_some(), file, checks)?;
    }
    if let Some(c) = &raw.collision {
        collision::check(c, &urdf, file)?;
    }
    Ok(RobotConfig {
        name: raw.name,
        file: file.to_path_buf(),
        board_profile: raw.board_profile,
        bus,
        direct: raw.direct,
        urdf_file: raw.urdf,
        collision: raw.collision,
        urdf,
        arm: raw.arm,
        gripper: raw.gripper,
        camera: raw.camera,
        base: raw.base,
        joints,
        sim_gravity: raw.sim.map(|s| s.gravity).unwrap_or(true),
    })
}

/// Whether the joint table has an entry `name`.
fn in_table(joints: &[Joint], name: &str) -> bool {
    joints.iter().any(|j| j.name.as_str() == name)
}
