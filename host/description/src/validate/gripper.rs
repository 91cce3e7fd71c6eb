//! `[gripper]`: present when the table has a gripper motor, its ticks within a turn and in
//! order, its fingers prismatic joints of the URDF, its finger travel (m), its motor a
//! `gripper` entry of the joint table.

use std::path::Path;

use crate::error::{config_error as cfg_err, in_range as num, Result};
use crate::joints::{Joint, JointRole};
use crate::sections::GripperSection;

/// Check the gripper `gripper` (if any) against the joint table and the URDF.
pub(super) fn check(
    gripper: Option<&GripperSection>,
    joints: &[Joint],
    urdf: &urdf_rs::Robot,
    file: &Path,
) -> Result<()> {
    if let (None, Some(j)) = (
        gripper,
        joints.iter().find(|j| j.kind == JointRole::Gripper),
    ) {
        return Err(cfg_err(
            file,
            "gripper",
            format!("joint {:?} is a gripper but there is no [gripper]", j.name),
        ));
    }
    let Some(g) = gripper else {
        return Ok(());
    };
    for (k, v) in [
        ("gripper.open_tick", g.open_tick),
        ("gripper.closed_tick", g.closed_tick),
        ("gripper.stops[0]", g.stops[0]),
        ("gripper.stops[1]", g.stops[1]),
    ] {
        num(file, k, v as f64, 0.0, 4095.0)?;
    }
    let order = "the ticks must satisfy stops[0] < closed_tick < open_tick <= stops[1]";
    for (k, ok) in [
        ("gripper.closed_tick", g.stops[0] < g.closed_tick),
        ("gripper.open_tick", g.closed_tick < g.open_tick),
        ("gripper.stops[1]", g.open_tick <= g.stops[1]),
    ] {
        if !ok {
            return Err(cfg_err(file, k, order));
        }
    }
    fingers(g, urdf, file)?;
    if !joints
        .iter()
        .any(|j| j.name.as_str() == g.joint && j.kind == JointRole::Gripper)
    {
        return Err(cfg_err(
            file,
            "gripper.joint",
            format!("{:?} is not a [[joint]] of kind \"gripper\"", g.joint),
        ));
    }
    Ok(())
}

/// The fingers: prismatic joints of the URDF, signs ±1, travel within 0.5 m and opening.
fn fingers(g: &GripperSection, urdf: &urdf_rs::Robot, file: &Path) -> Result<()> {
    for (k, f) in g.fingers.iter().enumerate() {
        let key = format!("gripper.fingers[{k}]");
        match urdf.joints.iter().find(|j| j.name == f.joint) {
            Some(j) if j.joint_type == urdf_rs::JointType::Prismatic => {}
            _ => {
                return Err(cfg_err(
                    file,
                    format!("{key}.joint"),
                    format!("{:?} is not a prismatic joint of the URDF", f.joint),
                ))
            }
        }
        if f.sign != 1.0 && f.sign != -1.0 {
            return Err(cfg_err(file, format!("{key}.sign"), "the sign is 1 or -1"));
        }
    }
    for v in g.finger_travel {
        num(file, "gripper.finger_travel", v, 0.0, 0.5)?;
    }
    if !g.fingers.is_empty() && g.finger_travel[0] >= g.finger_travel[1] {
        return Err(cfg_err(
            file,
            "gripper.finger_travel",
            "a finger is farther from the centre open than closed",
        ));
    }
    Ok(())
}
