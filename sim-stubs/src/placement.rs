//! Seeded placement of a scene's movable objects on their support: each object resting on a
//! static box (a table) is put at a uniformly random position on its top, at least `gap` from
//! the others and from the top's edges, turned by a uniformly random yaw, its height and tilt
//! kept. Benchmarks place the objects anew for every trial this way; a seed gives the same
//! placement on every machine.
//!
//! Footprints are bounding circles (the horizontal half-diagonal of the body's box), so
//! placements never overlap whatever the yaw; rejection sampling, a bounded number of draws
//! per object.

use nalgebra::{Translation3, UnitQuaternion, Vector3};

use crate::rng::SimRng;
use crate::scene::{Scene, SceneError};

/// Draws per object before the placement gives up.
pub const MAX_DRAWS: usize = 2000;

/// Greatest distance of an object's bottom above the support's top for it to count as resting
/// on it, m.
pub const RESTING: f64 = 0.01;

/// Place every movable body resting on the static body `support` at random on its top (see
/// the module), by `seed`; `gap` (m, finite, in [0, 1]) between footprints and from the
/// edges. Returns the ids of the bodies placed, in scene order. Errors: no static body
/// `support`, a bad gap, or no room for an object after [`MAX_DRAWS`] draws (too many or
/// too large objects for the top).
pub fn scatter_on(
    scene: &mut Scene,
    support: &str,
    seed: u64,
    gap: f64,
) -> Result<Vec<String>, SceneError> {
    let invalid = |key: &str, problem: String| SceneError::Invalid {
        file: scene.file.clone(),
        key: key.to_string(),
        problem,
    };
    if !(gap.is_finite() && (0.0..=1.0).contains(&gap)) {
        return Err(invalid(
            "gap",
            format!("{gap} m: need a finite gap in [0, 1] m"),
        ));
    }
    let Some(table) = scene.bodies.iter().find(|b| b.id == support && b.fixed) else {
        return Err(invalid(
            support,
            "no static body of that id to place objects on".into(),
        ));
    };
    let (lo, hi) = table.world_bounds();
    let movers: Vec<usize> = scene
        .bodies
        .iter()
        .enumerate()
        .filter(|(_, b)| {
            let (blo, _) = b.world_bounds();
            let c = b.pose.translation.vector;
            !b.fixed
                && (lo.x..=hi.x).contains(&c.x)
                && (lo.y..=hi.y).contains(&c.y)
                && (blo.z - hi.z).abs() <= RESTING
        })
        .map(|(i, _)| i)
        .collect();
    let mut rng = SimRng::new(seed, 0x5ca7);
    let mut placed: Vec<([f64; 2], f64)> = Vec::new();
    let mut ids = Vec::new();
    for i in movers {
        let b = &scene.bodies[i];
        let (blo, bhi) = b.world_bounds();
        let r = ((bhi.x - blo.x).powi(2) + (bhi.y - blo.y).powi(2)).sqrt() / 2.0;
        let (x0, x1) = (lo.x + r + gap, hi.x - r - gap);
        let (y0, y1) = (lo.y + r + gap, hi.y - r - gap);
        if x0 > x1 || y0 > y1 {
            return Err(invalid(
                &b.id,
                format!("{:.3} m across: wider than the top of {support:?}", 2.0 * r),
            ));
        }
        let spot = (0..MAX_DRAWS).find_map(|_| {
            let p = [
                x0 + (x1 - x0) * rng.uniform(),
                y0 + (y1 - y0) * rng.uniform(),
            ];
            let yaw = std::f64::consts::TAU * rng.uniform();
            placed
                .iter()
                .all(|(q, rq)| (p[0] - q[0]).hypot(p[1] - q[1]) >= r + rq + gap)
                .then_some((p, yaw))
        });
        let Some((p, yaw)) = spot else {
            return Err(invalid(
                &b.id,
                format!(
                    "no room on {support:?} after {MAX_DRAWS} draws ({} objects placed)",
                    placed.len()
                ),
            ));
        };
        placed.push((p, r));
        let b = &mut scene.bodies[i];
        let z = b.pose.translation.vector.z;
        b.pose.rotation =
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * b.pose.rotation;
        b.pose.translation = Translation3::new(p[0], p[1], z);
        ids.push(b.id.clone());
    }
    Ok(ids)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every object of the tabletop lands on the table, apart from the others and inside the
    /// edges by the gap, the same for a seed and different for another.
    #[test]
    fn the_tabletops_objects_are_scattered_apart_on_the_table() {
        let gap = 0.02;
        let mut a = Scene::bundled("tabletop").unwrap();
        let ids = scatter_on(&mut a, "table", 7, gap).unwrap();
        assert_eq!(ids.len(), 10, "{ids:?}");
        let original = Scene::bundled("tabletop").unwrap();
        let (lo, hi) = a.body("table").unwrap().world_bounds();
        let foot: Vec<([f64; 2], f64)> = ids
            .iter()
            .map(|id| {
                let (blo, bhi) = a.body(id).unwrap().world_bounds();
                assert!(
                    blo.x >= lo.x + gap - 1e-9 && bhi.x <= hi.x - gap + 1e-9,
                    "{id}"
                );
                assert!(
                    blo.y >= lo.y + gap - 1e-9 && bhi.y <= hi.y - gap + 1e-9,
                    "{id}"
                );
                assert!((blo.z - hi.z).abs() <= RESTING, "{id} rests at {}", blo.z);
                let c = a.body(id).unwrap().pose.translation.vector;
                // The footprint's circle, from the body's box before it was turned.
                let (olo, ohi) = original.body(id).unwrap().world_bounds();
                ([c.x, c.y], (ohi - olo).xy().norm() / 2.0)
            })
            .collect();
        for (i, (p, r)) in foot.iter().enumerate() {
            for (q, s) in &foot[i + 1..] {
                let d = (p[0] - q[0]).hypot(p[1] - q[1]);
                assert!(d + 1e-9 >= r + s + gap, "{d} m apart, radii {r} and {s}");
            }
        }
        let mut b = Scene::bundled("tabletop").unwrap();
        scatter_on(&mut b, "table", 7, gap).unwrap();
        assert_eq!(a, b);
        let mut c = Scene::bundled("tabletop").unwrap();
        scatter_on(&mut c, "table", 8, gap).unwrap();
        assert_ne!(a, c);
    }

    #[test]
    fn a_missing_support_or_a_bad_gap_or_no_room_is_an_error() {
        let mut s = Scene::bundled("tabletop").unwrap();
        assert!(scatter_on(&mut s, "desk", 1, 0.02).is_err());
        assert!(scatter_on(&mut s, "red_cube", 1, 0.02).is_err());
        assert!(scatter_on(&mut s, "table", 1, f64::NAN).is_err());
        assert!(scatter_on(&mut s, "table", 1, -0.1).is_err());
        let e = scatter_on(&mut s, "table", 1, 0.3).unwrap_err();
        assert!(e.to_string().contains("table"), "{e}");
    }
}
