//! `ferrobot info`: a robot's joints, limits and components.

use serde_json::json;

use super::common::load;

/// Describe `robot` as one JSON line, or as indented JSON without `json`.
pub fn run(robot: &str, json: bool) -> ferrobot::Result<()> {
    let cfg = load(robot)?;
    let joints: Vec<_> = cfg
        .joints
        .iter()
        .map(|j| {
            json!({"name": j.name.as_str(), "kind": format!("{:?}", j.kind).to_lowercase(), "servo_id": j.servo_id,
                   "twin_id": j.twin_id, "min": j.limits.min, "max": j.limits.max,
                   "velocity": j.limits.velocity, "effort": j.limits.effort})
        })
        .collect();
    let arm = cfg.arm.as_ref().map(|a| json!({"joints": a.joints, "base_frame": a.base_frame, "ee_frame": a.ee_frame, "home": a.home, "ik": format!("{:?}", a.ik)}));
    let base = cfg.base.as_ref().map(|b| json!({"kind": format!("{:?}", b.kind), "wheel_radius": b.wheel_radius, "track": b.track}));
    let v = json!({"robot": cfg.name, "file": cfg.file.display().to_string(), "arm": arm, "gripper": cfg.gripper.as_ref().map(|g| &g.joint),
                   "camera": cfg.camera.as_ref().map(|c| json!({"pan": c.pan_joint, "tilt": c.tilt_joint, "frame": c.frame, "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy})),
                   "base": base, "joints": joints});
    if json {
        println!("{v}");
    } else {
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
    }
    Ok(())
}
