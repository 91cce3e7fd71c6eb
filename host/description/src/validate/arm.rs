//! `[arm]`: its joints in the table, its named poses (home, stow, look) of the right length
//! and within the joints' limits (rad), its tolerances, accelerations (rad/s², defaulting to
//! each joint's speed limit per 0.5 s) and planning range; then the [`Checks`] (its kinematic
//! chain), then its IK solver's joint count.

use std::path::Path;

use super::in_table;
use crate::checks::Checks;
use crate::error::{config_error as cfg_err, in_range as num, Result};
use crate::joints::Joint;
use crate::sections::{ArmConfig, IkKind};

/// Check the arm `arm` against the joint table and the URDF; fill in its default
/// accelerations.
pub(super) fn check(
    arm: &mut ArmConfig,
    joints: &[Joint],
    urdf: &urdf_rs::Robot,
    file: &Path,
    checks: &dyn Checks,
) -> Result<()> {
    if arm.joints.is_empty() {
        return Err(cfg_err(
            file,
            "arm.joints",
            "an arm needs at least one joint",
        ));
    }
    for (i, n) in arm.joints.iter().enumerate() {
        if !in_table(joints, n) {
            return Err(cfg_err(
                file,
                format!("arm.joints[{i}]"),
                format!("{n:?} has no [[joint]] entry"),
            ));
        }
    }
    poses(arm, joints, file)?;
    num(
        file,
        "arm.ik_position_tolerance",
        arm.ik_position_tolerance,
        1e-9,
        0.1,
    )?;
    num(
        file,
        "arm.ik_orientation_tolerance",
        arm.ik_orientation_tolerance,
        1e-9,
        0.5,
    )?;
    num(file, "arm.joint_tolerance", arm.joint_tolerance, 1e-4, 0.5)?;
    accelerations(arm, joints, file)?;
    if let Some(r) = arm.planning_range {
        num(file, "arm.planning_range", r, 0.01, 10.0)?;
    }
    checks.arm(file, urdf, arm, joints)?;
    // The checks found the URDF's chain to move exactly the arm's joints.
    if arm.ik == IkKind::LocobotPitchRoll && arm.joints.len() != 5 {
        return Err(cfg_err(
            file,
            "arm.ik",
            "locobot_pitch_roll needs a 5-joint arm",
        ));
    }
    Ok(())
}

/// Home, stow and look: a value per arm joint, each within its joint's (`f32`) limits.
fn poses(arm: &ArmConfig, joints: &[Joint], file: &Path) -> Result<()> {
    let named = std::iter::once(("arm.home", &arm.home))
        .chain(arm.stow.iter().map(|s| ("arm.stow", s)))
        .chain(arm.look.iter().map(|s| ("arm.look", s)));
    for (key, pose) in named {
        if pose.len() != arm.joints.len() {
            return Err(cfg_err(
                file,
                key,
                format!(
                    "has {} values for {} arm joints",
                    pose.len(),
                    arm.joints.len()
                ),
            ));
        }
        for (i, (n, &q)) in arm.joints.iter().zip(pose).enumerate() {
            let l = joints
                .iter()
                .find(|j| j.name.as_str() == n.as_str())
                .map(|j| j.limits);
            if let Some(l) = l {
                num(file, format!("{key}[{i}]"), q, l.min as f64, l.max as f64)?;
            }
        }
    }
    Ok(())
}

/// The accelerations: a value per arm joint (each joint's speed limit per 0.5 s when none is
/// given), each within [0.01, 1000] rad/s².
fn accelerations(arm: &mut ArmConfig, joints: &[Joint], file: &Path) -> Result<()> {
    if arm.acceleration.is_empty() {
        arm.acceleration = arm
            .joints
            .iter()
            .map(|n| {
                joints
                    .iter()
                    .find(|j| j.name.as_str() == n.as_str())
                    .map_or(1.0, |j| j.limits.velocity as f64)
                    / 0.5
            })
            .collect();
    } else if arm.acceleration.len() != arm.joints.len() {
        return Err(cfg_err(
            file,
            "arm.acceleration",
            format!(
                "has {} values for {} arm joints",
                arm.acceleration.len(),
                arm.joints.len()
            ),
        ));
    }
    for (i, &a) in arm.acceleration.iter().enumerate() {
        num(file, format!("arm.acceleration[{i}]"), a, 0.01, 1000.0)?;
    }
    Ok(())
}
