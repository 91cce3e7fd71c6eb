//! Seeded placement of a scene's movable bodies, for trials that need the objects somewhere new
//! each time (the grasping and pushing benchmarks). Each body keeps how it rests (its height and
//! tilt: a lying capsule stays lying) and is turned by a random heading about the vertical;
//! footprints are circles holding the body at any heading, kept apart by a gap; rejection
//! sampling with a bounded number of draws. A seed gives the same placement on every machine.
//!
//! * [`scatter`]: chosen bodies in a rectangle of the floor plane, optionally within an arm's
//!   reach of a point (grasping: only where the arm reaches top-down).
//! * [`scatter_on`]: every body resting on a static support (a table) anywhere on its top,
//!   the edges kept by the gap (pushing).
//!
//! World frame, z up, m and rad.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::rng::SimRng;
use crate::scene::{Result, Scene, SceneError};

/// Attempts per body before placement starts over.
pub const TRIES: usize = 1000;
/// Times placement starts over (the bodies placed so far may have left no room for the
/// next) before it gives up.
pub const RESTARTS: usize = 100;

/// A rectangle of the floor plane, world frame, m: `x[0] <= x <= x[1]`, `y[0] <= y <= y[1]`;
/// optionally only its part within a radius of a point (an arm's reach) for the bodies'
/// centres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    /// Range of x, m.
    pub x: [f64; 2],
    /// Range of y, m.
    pub y: [f64; 2],
    /// Centres lie within this distance (m, the third value) of this point (x, y, m).
    pub within: Option<[f64; 3]>,
}

/// Half sizes (x, y, z, m) of the box holding the body's shape turned as the body stands:
/// its tilt kept, its heading removed.
pub fn standing_half_extents(body: &crate::scene::Body) -> Vector3<f64> {
    let (roll, pitch, _) = body.pose.rotation.euler_angles();
    let tilt = UnitQuaternion::from_euler_angles(roll, pitch, 0.0).to_rotation_matrix();
    tilt.matrix().abs() * body.shape.half_extents()
}

/// Radius of a vertical cylinder about the body's origin that holds it at any heading, m.
pub fn footprint(body: &crate::scene::Body) -> f64 {
    let h = standing_half_extents(body);
    h.x.hypot(h.y)
}

/// `scene` with the movable bodies `ids` (all movable bodies when empty) placed at random
/// (`seed`) in `region`: each body's footprint (the circle holding it) inside the region and
/// at least `gap` (m) from every other placed body's; the other bodies stay where they were.
/// Errors: an id that is not a movable body, a region or gap that is not finite (or empty),
/// or no room for every body after [`RESTARTS`] tries.
pub fn scatter(scene: &Scene, ids: &[&str], region: Region, seed: u64, gap: f64) -> Result<Scene> {
    let invalid = |key: &str, problem: String| SceneError::Invalid {
        file: scene.file.clone(),
        key: key.to_string(),
        problem,
    };
    let finite = region
        .x
        .iter()
        .chain(&region.y)
        .chain(region.within.iter().flatten())
        .all(|v| v.is_finite());
    if !(finite && region.x[0] <= region.x[1] && region.y[0] <= region.y[1]) {
        return Err(invalid(
            "placement.region",
            format!("{region:?} is not a finite, non-empty rectangle"),
        ));
    }
    if !(gap.is_finite() && (0.0..=10.0).contains(&gap)) {
        return Err(invalid(
            "placement.gap",
            format!("{gap} m is not a finite gap in [0, 10] m"),
        ));
    }
    for id in ids {
        if !scene.bodies.iter().any(|b| b.id == *id && !b.fixed) {
            return Err(invalid(
                "placement.ids",
                format!("{id:?} is not a movable body of the scene"),
            ));
        }
    }
    let mut rng = SimRng::new(seed, 0x9a5);
    let mut stuck = String::new();
    for _ in 0..RESTARTS {
        match place(scene, ids, region, gap, &mut rng) {
            Ok(out) => return Ok(out),
            Err(why) => stuck = why,
        }
    }
    Err(invalid(
        "placement",
        format!("{stuck} after {RESTARTS} restarts of {TRIES} tries each"),
    ))
}

/// One attempt of [`scatter`]: the bodies placed in turn; `Err` names the first body with
/// no room left.
fn place(
    scene: &Scene,
    ids: &[&str],
    region: Region,
    gap: f64,
    rng: &mut SimRng,
) -> std::result::Result<Scene, String> {
    let mut out = scene.clone();
    let mut placed: Vec<(f64, f64, f64)> = Vec::new();
    for body in out.bodies.iter_mut().filter(|b| !b.fixed) {
        if !ids.is_empty() && !ids.contains(&body.id.as_str()) {
            continue;
        }
        let r = footprint(body);
        let (xs, ys) = (
            [region.x[0] + r, region.x[1] - r],
            [region.y[0] + r, region.y[1] - r],
        );
        let mut spot = None;
        for _ in 0..TRIES {
            let x = xs[0] + (xs[1] - xs[0]) * rng.uniform();
            let y = ys[0] + (ys[1] - ys[0]) * rng.uniform();
            let yaw = std::f64::consts::TAU * rng.uniform();
            let free = placed
                .iter()
                .all(|&(px, py, pr)| (x - px).hypot(y - py) >= r + pr + gap);
            let near = region
                .within
                .is_none_or(|[cx, cy, d]| (x - cx).hypot(y - cy) <= d);
            if xs[0] <= xs[1] && ys[0] <= ys[1] && free && near {
                spot = Some((x, y, yaw));
                break;
            }
        }
        let (x, y, yaw) = spot.ok_or_else(|| {
            format!(
                "no room for {:?} ({r:.3} m footprint) in {region:?} {gap} m from the others",
                body.id
            )
        })?;
        placed.push((x, y, r));
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw);
        body.pose = Isometry3::from_parts(
            Translation3::new(x, y, body.pose.translation.z),
            turn * body.pose.rotation,
        );
    }
    Ok(out)
}

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
pub fn scatter_on(scene: &mut Scene, support: &str, seed: u64, gap: f64) -> Result<Vec<String>> {
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
