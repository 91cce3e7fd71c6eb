//! `[camera]`: the pan and tilt joints in the table, the intrinsics (px), the depth range (m)
//! and rate, the optical frame and the marker's link in the URDF.

use std::path::Path;

use super::in_table;
use crate::error::{config_error as cfg_err, in_range as num, Result};
use crate::joints::Joint;
use crate::sections::CameraSection;

/// Check the camera `c` against the joint table and the URDF.
pub(super) fn check(
    c: &CameraSection,
    joints: &[Joint],
    urdf: &urdf_rs::Robot,
    file: &Path,
) -> Result<()> {
    for (k, n) in [
        ("camera.pan_joint", &c.pan_joint),
        ("camera.tilt_joint", &c.tilt_joint),
    ] {
        if !in_table(joints, n) {
            return Err(cfg_err(file, k, format!("{n:?} has no [[joint]] entry")));
        }
    }
    for (k, v) in [("camera.width", c.width), ("camera.height", c.height)] {
        num(file, k, v as f64, 1.0, 8192.0)?;
    }
    num(file, "camera.fx", c.fx, 1e-3, 1e5)?;
    num(file, "camera.fy", c.fy, 1e-3, 1e5)?;
    num(file, "camera.cx", c.cx, 0.0, c.width as f64)?;
    num(file, "camera.cy", c.cy, 0.0, c.height as f64)?;
    num(file, "camera.depth_min", c.depth_min, 0.0, 100.0)?;
    num(file, "camera.rate", c.rate, 0.1, 1000.0)?;
    num(
        file,
        "camera.depth_max",
        c.depth_max,
        c.depth_min + 1e-3,
        100.0,
    )?;
    if !urdf.links.iter().any(|l| l.name == c.frame) {
        return Err(cfg_err(
            file,
            "camera.frame",
            format!("the URDF has no link {:?}", c.frame),
        ));
    }
    if let Some(m) = &c.marker {
        if !urdf.links.iter().any(|l| l.name == m.link) {
            return Err(cfg_err(
                file,
                "camera.marker.link",
                format!("the URDF has no link {:?}", m.link),
            ));
        }
        num(file, "camera.marker.size", m.size, 1e-3, 1.0)?;
        for v in m.xyz {
            num(file, "camera.marker.xyz", v, -1.0, 1.0)?;
        }
    }
    Ok(())
}
