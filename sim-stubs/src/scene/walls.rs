//! A wall of the scene as boxes: the pieces between its door openings and a lintel above each.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::file::WallFile;
use super::{Body, Ctx, Result, Shape, MAX_EXTENT};

/// A wall as boxes: the pieces between its door openings and a lintel above each.
pub(super) fn wall_bodies(cx: &Ctx<'_>, i: usize, w: &WallFile) -> Result<Vec<Body>> {
    let key = format!("wall[{i}]");
    for v in w.from.iter().chain(&w.to) {
        cx.finite(&format!("{key}.from/to"), *v, -MAX_EXTENT, MAX_EXTENT)?;
    }
    let height = cx.positive(&format!("{key}.height"), w.height)?;
    let thick = cx.positive(&format!("{key}.thickness"), w.thickness)?;
    let colour = cx.colour(&format!("{key}.colour"), w.colour)?;
    let texture = w
        .texture
        .as_ref()
        .map(|t| cx.texture(&format!("{key}.texture"), t, colour))
        .transpose()?;
    let a = Vector3::new(w.from[0], w.from[1], 0.0);
    let d = Vector3::new(w.to[0] - w.from[0], w.to[1] - w.from[1], 0.0);
    let len = d.norm();
    if len < 0.01 {
        return Err(cx.err(format!("{key}.to"), "a wall needs two distinct ends"));
    }
    let dir = d / len;
    let rot = UnitQuaternion::from_euler_angles(0.0, 0.0, dir.y.atan2(dir.x));
    if w.doors.len() > 6 {
        return Err(cx.err(format!("{key}.doors"), "at most 6 doors per wall"));
    }
    // Openings sorted along the wall, each inside it and apart from the others.
    let mut doors: Vec<(f64, f64, f64)> = Vec::new();
    for (k, dr) in w.doors.iter().enumerate() {
        let dk = format!("{key}.doors[{k}]");
        let at = cx.finite(&format!("{dk}.at"), dr.at, 0.0, len)?;
        let width = cx.positive(&format!("{dk}.width"), dr.width)?;
        let dh = cx.positive(&format!("{dk}.height"), dr.height)?;
        if at + width > len + 1e-9 {
            return Err(cx.err(
                format!("{dk}.width"),
                format!(
                    "the opening ends at {} m, beyond the wall's {len} m",
                    at + width
                ),
            ));
        }
        if dh > height {
            return Err(cx.err(
                format!("{dk}.height"),
                format!("{dh} m is higher than the wall ({height} m)"),
            ));
        }
        doors.push((at, at + width, dh));
    }
    doors.sort_by(|x, y| x.0.total_cmp(&y.0));
    for p in doors.windows(2) {
        if p[1].0 < p[0].1 {
            return Err(cx.err(format!("{key}.doors"), "door openings overlap"));
        }
    }
    let mut out = Vec::new();
    let mut piece = |s0: f64, s1: f64, z0: f64, z1: f64| {
        if s1 - s0 < 1e-6 || z1 - z0 < 1e-6 {
            return;
        }
        let centre = a + dir * ((s0 + s1) / 2.0) + Vector3::z() * ((z0 + z1) / 2.0);
        out.push(Body {
            id: format!("wall{i}.{}", out.len()),
            shape: Shape::Box([s1 - s0, thick, z1 - z0]),
            pose: Isometry3::from_parts(Translation3::from(centre), rot),
            mass: 0.0,
            friction: 0.6,
            colour,
            texture: texture.clone(),
            fixed: true,
        });
    };
    let mut s = 0.0;
    for &(d0, d1, dh) in &doors {
        piece(s, d0, 0.0, height);
        piece(d0, d1, dh, height);
        s = d1;
    }
    piece(s, len, 0.0, height);
    Ok(out)
}
