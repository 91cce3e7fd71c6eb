//! The joint table: each entry's name once, a known servo model, a sign of ±1, Dynamixel IDs
//! (0-252) used once, a joint of the URDF (the gripper motor excepted) whose limits it
//! overrides per field; then the [`Checks`] of each entry and of the table. And the servo
//! bus's bit rate.

use std::collections::BTreeSet;
use std::path::Path;

use crate::checks::{Checks, JointEntry};
use crate::error::{config_error as cfg_err, in_range as num, Result};
use crate::joints::{Joint, JointLimits, JointRole, JointSection, ServoModel};
use crate::sections::BusSection;

/// The table `sections` resolved against `urdf`, checked.
pub(super) fn table(
    sections: &[JointSection],
    urdf: &urdf_rs::Robot,
    file: &Path,
    checks: &dyn Checks,
) -> Result<Vec<Joint>> {
    checks.table(file, sections)?;
    let mut ids = BTreeSet::new();
    let mut joints: Vec<Joint> = Vec::new();
    for (i, j) in sections.iter().enumerate() {
        let joint = entry(i, j, &joints, &mut ids, urdf, file, checks)?;
        joints.push(joint);
    }
    checks.joints(file, &joints)?;
    Ok(joints)
}

/// Entry `i`, `j`, after the entries `before` (their servo IDs `ids`).
fn entry(
    i: usize,
    j: &JointSection,
    before: &[Joint],
    ids: &mut BTreeSet<u8>,
    urdf: &urdf_rs::Robot,
    file: &Path,
    checks: &dyn Checks,
) -> Result<Joint> {
    let key = |k: &str| format!("joint[{i}].{k}");
    if before.iter().any(|b| b.name == j.name) {
        return Err(cfg_err(
            file,
            key("name"),
            format!("joint {:?} has two [[joint]] entries", j.name),
        ));
    }
    let model = servo(i, j, ids, file)?;
    let (min, max, velocity) = limits(i, j, urdf, file)?;
    let joint = Joint {
        name: j.name.clone(),
        kind: j.kind,
        model,
        servo_id: j.servo.id,
        twin_id: j.servo.twin,
        sign: j.servo.sign,
        offset: j.servo.offset as f32,
        limits: JointLimits {
            min: min as f32,
            max: max as f32,
            velocity: velocity as f32,
            effort: j.effort_limit as f32,
        },
        bounds: (min, max),
        pid: j.pid,
        position_ki: j.position_ki,
    };
    let entry = JointEntry {
        index: i,
        section: j,
        min,
        max,
        velocity,
        joint: &joint,
    };
    checks.joint(file, &entry)?;
    Ok(joint)
}

/// Entry `i`'s servo: a known model, a sign of ±1, Dynamixel IDs (0-252) not in `ids`, which
/// they join.
fn servo(i: usize, j: &JointSection, ids: &mut BTreeSet<u8>, file: &Path) -> Result<ServoModel> {
    let key = |k: &str| format!("joint[{i}].{k}");
    let model = match j.servo.model.as_str() {
        "xm430-w350" => ServoModel::Xm430W350,
        "xl430-w250" => ServoModel::Xl430W250,
        other => {
            return Err(cfg_err(
                file,
                key("servo.model"),
                format!("unknown servo model {other:?}; known: xm430-w350, xl430-w250"),
            ))
        }
    };
    if j.servo.sign != 1 && j.servo.sign != -1 {
        return Err(cfg_err(
            file,
            key("servo.sign"),
            format!("must be 1 or -1, not {}", j.servo.sign),
        ));
    }
    for id in std::iter::once(j.servo.id).chain(j.servo.twin) {
        if id >= 0xFD {
            return Err(cfg_err(
                file,
                key("servo.id"),
                format!("Dynamixel IDs are 0-252, not {id}"),
            ));
        }
        if !ids.insert(id) {
            return Err(cfg_err(
                file,
                key("servo.id"),
                format!("servo ID {id} is used twice"),
            ));
        }
    }
    Ok(model)
}

/// Entry `i`'s limits `(min, max, velocity)`: the URDF's, overridden per field (a gripper
/// motor the URDF lacks: -1.2, 1.6 and 3.0).
fn limits(
    i: usize,
    j: &JointSection,
    urdf: &urdf_rs::Robot,
    file: &Path,
) -> Result<(f64, f64, f64)> {
    let (mut min, mut max, mut velocity) = match urdf.joints.iter().find(|u| u.name == j.name) {
        Some(u) => (u.limit.lower, u.limit.upper, u.limit.velocity),
        None if j.kind == JointRole::Gripper => (-1.2, 1.6, 3.0),
        None => {
            return Err(cfg_err(
                file,
                format!("joint[{i}].name"),
                format!("the URDF has no joint {:?}", j.name),
            ));
        }
    };
    if let Some(o) = &j.limits {
        min = o.min.unwrap_or(min);
        max = o.max.unwrap_or(max);
        velocity = o.velocity.unwrap_or(velocity);
    }
    Ok((min, max, velocity))
}

/// The servo bus `bus`: its bit rate, then the [`Checks`] (its loop period).
pub(super) fn bus(bus: &BusSection, file: &Path, checks: &dyn Checks) -> Result<()> {
    num(file, "bus.baud", bus.baud as f64, 9600.0, 10_500_000.0)?;
    checks.bus(file, bus)
}

/// `[direct]`: its devices' rates, the host loop (the [`Checks`] see it as a bus) and the
/// reply margin; a base cable only on a robot with a `[base]`, and one there.
pub(super) fn direct(
    d: &crate::direct::DirectSection,
    has_base: bool,
    file: &Path,
    checks: &dyn Checks,
) -> Result<()> {
    num(
        file,
        "direct.servo.baud",
        d.servo.baud as f64,
        9600.0,
        10_500_000.0,
    )?;
    if let Some(b) = &d.base {
        num(
            file,
            "direct.base.baud",
            b.baud as f64,
            9600.0,
            10_500_000.0,
        )?;
    }
    for (key, dev) in [
        ("direct.servo.usb", Some(&d.servo)),
        ("direct.base.usb", d.base.as_ref()),
    ] {
        if let Some(dev) = dev.filter(|dev| dev.usb.is_some() && dev.usb_ids().is_none()) {
            return Err(cfg_err(
                file,
                key,
                format!("{:?} is not a USB ID pair \"vvvv:pppp\" in hex", dev.usb),
            ));
        }
    }
    num(
        file,
        "direct.reply_margin_us",
        d.reply_margin_us as f64,
        0.0,
        100_000.0,
    )?;
    if d.base.is_some() != has_base {
        return Err(cfg_err(
            file,
            "direct.base",
            if has_base {
                "the robot has a [base]: say which cable drives it"
            } else {
                "the robot has no [base] for this cable to drive"
            },
        ));
    }
    checks.bus(file, &d.bus())
}
