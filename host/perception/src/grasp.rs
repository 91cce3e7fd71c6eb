//! Top-down antipodal grasps on the objects of a table, from one cloud: for each object a set
//! of finger lines across it (the first across its narrow width, the rest turned around it),
//! each measured (width between the fingers, clearance of the open fingers as they descend,
//! depth of the grasp) and scored by a [`GraspModel`] (the analytic [`AnalyticScorer`], or a
//! learned model in its place). PyRobot's grasping example does this with a learned network
//! on the colour image; here the geometry is measured directly on the cloud.
//!
//! Frames: everything is in the cloud's frame (m); "up" is the table plane's normal (fit the
//! plane with `up` given), heights are signed distances from the plane, and a grasp's yaw is
//! the finger line's angle about the normal from the cloud's x axis projected on the plane.

use nalgebra::{Point3, Unit, Vector3};

use crate::cloud::check_points;
use crate::error::{PerceptionError, Result};
use crate::plane::Plane;
use crate::segment::SegmentedObject;

/// The gripper as the grasp detector sees it: two fingers closing along a line, pointed down.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperGeometry {
    /// Gap between the fingers' inner faces when open, m (from the robot's description).
    pub opening: f64,
    /// Thickness of a finger along the closing line, m.
    pub finger_thickness: f64,
    /// Width of a finger across the closing line (horizontal), m.
    pub finger_width: f64,
    /// Length of a finger's contact face from its tip upwards, m.
    pub finger_length: f64,
}

impl GripperGeometry {
    /// Checks every size: finite, in (0, 0.5] m.
    pub fn check(&self) -> Result<()> {
        for (name, v) in [
            ("gripper opening", self.opening),
            ("finger thickness", self.finger_thickness),
            ("finger width", self.finger_width),
            ("finger length", self.finger_length),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 0.5) {
                return Err(PerceptionError::Parameter {
                    name,
                    value: v,
                    range: "a finite size in (0, 0.5] m",
                });
            }
        }
        Ok(())
    }
}

/// How candidates are made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspParams {
    /// Finger lines tried per object, evenly spread over half a turn from the one across the
    /// object's narrow width: 1..=64.
    pub yaws: usize,
    /// Deepest the fingertips go below the object's top, m: finite, in (0, 0.5].
    pub target_depth: f64,
    /// Lowest the fingertips go above the table's plane, m: finite, in [0, 0.5].
    pub table_gap: f64,
}

impl Default for GraspParams {
    /// 8 finger lines (22.5 degrees apart), 2 cm deep, fingertips 1 cm above the table.
    fn default() -> Self {
        GraspParams {
            yaws: 8,
            target_depth: 0.02,
            table_gap: 0.01,
        }
    }
}

impl GraspParams {
    /// Checks every setting's range (see each field).
    pub fn check(&self) -> Result<()> {
        let bad = |name, value, range| Err(PerceptionError::Parameter { name, value, range });
        if !(1..=64).contains(&self.yaws) {
            return bad("yaws", self.yaws as f64, "a count in 1..=64");
        }
        if !(self.target_depth.is_finite() && self.target_depth > 0.0 && self.target_depth <= 0.5) {
            return bad(
                "target_depth",
                self.target_depth,
                "a finite depth in (0, 0.5] m",
            );
        }
        if !(self.table_gap.is_finite() && (0.0..=0.5).contains(&self.table_gap)) {
            return bad("table_gap", self.table_gap, "a finite height in [0, 0.5] m");
        }
        Ok(())
    }
}

/// One top-down grasp: where the fingertips' midpoint goes, along which line they close, and
/// what was measured there.
#[derive(Debug, Clone, PartialEq)]
pub struct Grasp {
    /// Index of the object in the list given to [`detect_grasps`].
    pub object: usize,
    /// Midpoint of the two fingertips at the grasp (the fingers' lowest point), m.
    pub position: Point3<f64>,
    /// Unit direction of the closing line, horizontal (in the plane).
    pub closing: Unit<Vector3<f64>>,
    /// Angle of the closing line about the plane's normal, rad, in (-pi/2, pi/2].
    pub yaw: f64,
    /// The object's width between the fingers (along the closing line, in the fingers' band),
    /// m.
    pub width: f64,
    /// Height of the object's top above the plane, m.
    pub top: f64,
    /// How far the fingertips reach below the object's top, m.
    pub depth: f64,
    /// Smallest horizontal gap between the open fingers and any point above the fingertips
    /// (the object's own included), m; 0 when a point lies where a finger descends.
    pub clearance: f64,
    /// The model's score (higher is better).
    pub score: f64,
}

/// What a [`GraspModel`] sees of one candidate.
#[derive(Debug, Clone, Copy)]
pub struct GraspCandidate<'a> {
    /// The candidate, measured ([`Grasp::score`] is 0 until scored).
    pub grasp: &'a Grasp,
    /// The object it grasps.
    pub object: &'a SegmentedObject,
    /// The whole cloud (m).
    pub points: &'a [Point3<f64>],
    /// The table's plane.
    pub plane: &'a Plane,
    /// The gripper.
    pub gripper: &'a GripperGeometry,
}

/// Scores grasp candidates: the analytic [`AnalyticScorer`], or a learned model.
pub trait GraspModel: Send + Sync {
    /// The candidate's score (higher is better), or `None` when it cannot succeed.
    fn score(&self, candidate: &GraspCandidate<'_>) -> Option<f64>;
}

/// The analytic scorer: a candidate is feasible when the object fits between the open fingers
/// with `min_gap` to spare on each side, nothing lies within `min_clearance` of where the
/// fingers descend, and the fingers reach at least `min_depth` below the object's top; its
/// score (0 to 3) adds the side gap, the clearance and the depth, each as a fraction of what
/// counts as plenty (`good_gap`, `good_clearance`, the finger's length).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnalyticScorer {
    /// Least gap between the object and each inner finger face, m.
    pub min_gap: f64,
    /// A side gap this large scores full marks, m.
    pub good_gap: f64,
    /// Least clearance of the fingers' paths, m.
    pub min_clearance: f64,
    /// A clearance this large scores full marks, m.
    pub good_clearance: f64,
    /// Least depth of the grasp, m.
    pub min_depth: f64,
}

impl Default for AnalyticScorer {
    /// 3 mm side gaps (1 cm is plenty), 3 mm clearance (1 cm is plenty), 1 cm deep.
    fn default() -> Self {
        AnalyticScorer {
            min_gap: 0.003,
            good_gap: 0.01,
            min_clearance: 0.003,
            good_clearance: 0.01,
            min_depth: 0.01,
        }
    }
}

impl GraspModel for AnalyticScorer {
    fn score(&self, c: &GraspCandidate<'_>) -> Option<f64> {
        let g = c.grasp;
        let gap = (c.gripper.opening - g.width) / 2.0;
        if gap < self.min_gap || g.clearance < self.min_clearance || g.depth < self.min_depth {
            return None;
        }
        let part = |v: f64, full: f64| (v / full).clamp(0.0, 1.0);
        Some(
            part(gap, self.good_gap)
                + part(g.clearance, self.good_clearance)
                + part(g.depth, c.gripper.finger_length),
        )
    }
}

/// The in-plane axes: `e1` the cloud's x (or y) projected on the plane, `e2 = n x e1`.
fn plane_axes(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let pick = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = (pick - n * n.dot(&pick)).normalize();
    (e1, n.cross(&e1))
}

/// Angle folded into (-pi/2, pi/2] (a line's direction).
fn fold(a: f64) -> f64 {
    let pi = std::f64::consts::PI;
    let mut a = a.rem_euclid(pi);
    if a > pi / 2.0 {
        a -= pi;
    }
    a
}

/// Distance from `(s, t)` to the axis-aligned rectangle `[s0, s1] x [-h, h]`.
fn rect_distance(s: f64, t: f64, s0: f64, s1: f64, h: f64) -> f64 {
    let ds = (s0 - s).max(s - s1).max(0.0);
    let dt = (t.abs() - h).max(0.0);
    ds.hypot(dt)
}

/// The grasps on `objects` (found in `points`, on the table `plane`), scored by `model`,
/// best first; infeasible candidates are left out, so an empty list means no object can be
/// grasped. Errors: bad parameters or gripper sizes, non-finite or out-of-range points, an
/// object's index outside the cloud.
pub fn detect_grasps(
    points: &[Point3<f64>],
    plane: &Plane,
    objects: &[SegmentedObject],
    gripper: &GripperGeometry,
    params: &GraspParams,
    model: &dyn GraspModel,
) -> Result<Vec<Grasp>> {
    params.check()?;
    gripper.check()?;
    check_points(points)?;
    if let Some(&bad) = objects
        .iter()
        .flat_map(|o| o.indices.iter())
        .find(|&&i| i >= points.len())
    {
        return Err(PerceptionError::Parameter {
            name: "object point index",
            value: bad as f64,
            range: "an index into the cloud",
        });
    }
    let n = plane.normal.into_inner();
    let (e1, e2) = plane_axes(&n);
    // Everything standing above the fingertips' lowest height may be in a finger's way.
    let low = params.table_gap.max(0.0);
    let standing: Vec<(f64, f64, f64)> = points
        .iter()
        .filter_map(|p| {
            let h = plane.signed_distance(p);
            (h > low * 0.5).then(|| (p.coords.dot(&e1), p.coords.dot(&e2), h))
        })
        .collect();
    let reach = gripper.opening / 2.0 + gripper.finger_thickness + gripper.finger_width + 0.01;
    let frame = PlaneFrame { e1, e2, n, plane };
    let mut out = Vec::new();
    for (k, object) in objects.iter().enumerate() {
        if object.indices.is_empty() {
            continue;
        }
        let view = ObjectView::new(points, &frame, object, &standing, reach);
        for j in 0..params.yaws {
            let yaw = fold(
                view.long
                    + std::f64::consts::FRAC_PI_2
                    + j as f64 * std::f64::consts::PI / params.yaws as f64,
            );
            let Some(mut grasp) = view.measure(k, yaw, &frame, gripper, params) else {
                continue;
            };
            let candidate = GraspCandidate {
                grasp: &grasp,
                object,
                points,
                plane,
                gripper,
            };
            if let Some(score) = model.score(&candidate).filter(|s| s.is_finite()) {
                grasp.score = score;
                out.push(grasp);
            }
        }
    }
    out.sort_by(|a, b| b.score.total_cmp(&a.score));
    Ok(out)
}

/// The table's plane with its in-plane axes `e1`, `e2` ([`plane_axes`]) and normal `n`.
struct PlaneFrame<'a> {
    e1: Vector3<f64>,
    e2: Vector3<f64>,
    n: Vector3<f64>,
    plane: &'a Plane,
}

/// One object as its finger lines see it, in plane coordinates `(a, b, height)` (m): its
/// points, the centre of its top, its long axis (rad from `e1`), and the standing points near
/// it (that a finger may meet).
struct ObjectView {
    own: Vec<(f64, f64, f64)>,
    ca: f64,
    cb: f64,
    long: f64,
    near: Vec<(f64, f64, f64)>,
}

impl ObjectView {
    /// `object` of `points` seen on `frame`'s plane; `standing` are every point above the
    /// fingertips' lowest height, kept within `reach + 0.1` m of the top's centre.
    fn new(
        points: &[Point3<f64>],
        frame: &PlaneFrame<'_>,
        object: &SegmentedObject,
        standing: &[(f64, f64, f64)],
        reach: f64,
    ) -> Self {
        let (e1, e2, plane) = (frame.e1, frame.e2, frame.plane);
        let own: Vec<(f64, f64, f64)> = object
            .indices
            .iter()
            .map(|&i| {
                let p = points[i];
                (
                    p.coords.dot(&e1),
                    p.coords.dot(&e2),
                    plane.signed_distance(&p),
                )
            })
            .collect();
        // The centre of its top (within 5 mm of its highest point): what a camera above sees
        // whole, where the sides it sees are only the near ones.
        let high = own.iter().map(|p| p.2).fold(f64::NEG_INFINITY, f64::max);
        let crown: Vec<&(f64, f64, f64)> = own.iter().filter(|p| p.2 > high - 0.005).collect();
        let m = crown.len() as f64;
        let (ca, cb) = crown
            .iter()
            .fold((0.0, 0.0), |(a, b), p| (a + p.0 / m, b + p.1 / m));
        // The object's long axis in the plane (2-D principal axis).
        let (mut saa, mut sab, mut sbb) = (0.0, 0.0, 0.0);
        for p in &crown {
            let (da, db) = (p.0 - ca, p.1 - cb);
            saa += da * da;
            sab += da * db;
            sbb += db * db;
        }
        let long = 0.5 * f64::atan2(2.0 * sab, saa - sbb);
        let near: Vec<(f64, f64, f64)> = standing
            .iter()
            .copied()
            .filter(|p| (p.0 - ca).hypot(p.1 - cb) < reach + 0.1)
            .collect();
        ObjectView {
            own,
            ca,
            cb,
            long,
            near,
        }
    }

    /// The grasp of object `k` with the fingers closing along `yaw`, measured (its score 0);
    /// `None` when none of the object's points lies in the fingers' band.
    fn measure(
        &self,
        k: usize,
        yaw: f64,
        frame: &PlaneFrame<'_>,
        gripper: &GripperGeometry,
        params: &GraspParams,
    ) -> Option<Grasp> {
        let (own, near, ca, cb) = (&self.own, &self.near, self.ca, self.cb);
        let (e1, e2, n, plane) = (frame.e1, frame.e2, frame.n, frame.plane);
        let (sy, cy) = yaw.sin_cos();
        let to_st = |a: f64, b: f64| {
            let (da, db) = (a - ca, b - cb);
            (da * cy + db * sy, -da * sy + db * cy)
        };
        // The object's points in the fingers' band.
        let half = gripper.finger_width / 2.0;
        let band: Vec<(f64, f64)> = own
            .iter()
            .map(|p| (to_st(p.0, p.1), p.2))
            .filter(|&((_, t), _)| t.abs() <= half)
            .map(|((s, _), h)| (s, h))
            .collect();
        if band.is_empty() {
            return None;
        }
        let (smin, smax, top) = band.iter().fold(
            (f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
            |(lo, hi, top), &(s, h)| (lo.min(s), hi.max(s), top.max(h)),
        );
        let width = smax - smin;
        let mid = (smin + smax) / 2.0;
        let tip = (top - params.target_depth).max(params.table_gap);
        let depth = (top - tip).min(gripper.finger_length);
        let inner = gripper.opening / 2.0;
        let outer = inner + gripper.finger_thickness;
        let clearance = near
            .iter()
            .filter(|p| p.2 > tip)
            .map(|p| {
                let (s, t) = to_st(p.0, p.1);
                let s = s - mid;
                rect_distance(s, t, inner, outer, half)
                    .min(rect_distance(s, t, -outer, -inner, half))
            })
            .fold(f64::INFINITY, f64::min)
            .min(1.0);
        let (a, b) = (ca + mid * cy, cb + mid * sy);
        let position = Point3::from(e1 * a + e2 * b + n * (plane.offset + tip));
        Some(Grasp {
            object: k,
            position,
            closing: Unit::new_normalize(e1 * cy + e2 * sy),
            yaw,
            width,
            top,
            depth,
            clearance,
            score: 0.0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::Dbscan;
    use crate::plane::{fit_plane, RansacParams};
    use crate::segment::{segment_objects, SegmentParams};
    use crate::synthetic::{DepthCamera, Solid, Tabletop};

    /// The LoCoBot's gripper: 4.9 cm open, 1 x 2 x 3 cm fingers.
    const GRIPPER: GripperGeometry = GripperGeometry {
        opening: 0.049,
        finger_thickness: 0.01,
        finger_width: 0.02,
        finger_length: 0.03,
    };

    use crate::locobot_camera::locobot_intrinsics;

    /// A table top at 0.1 m with `objects` on it, seen by the LoCoBot's camera (exact depth).
    fn look(objects: Vec<Solid>) -> (Vec<Point3<f64>>, Plane, Vec<SegmentedObject>) {
        let mut scene = Tabletop::random(1, 0, 0.05);
        scene.objects = objects;
        let cam = DepthCamera {
            noise_at_1m: 0.0,
            ..DepthCamera::looking_down(locobot_intrinsics()).scaled(0.5)
        };
        let pts = cam.cloud(&scene, 1).unwrap().points;
        let fit = fit_plane(
            &pts,
            &RansacParams {
                threshold: 0.005,
                max_tilt: 0.3,
                ..Default::default()
            },
        )
        .unwrap();
        let objects = segment_objects(
            &pts,
            &fit,
            &SegmentParams::default(),
            &Dbscan::new(0.02, 10).unwrap(),
        )
        .unwrap();
        (pts, fit.plane, objects)
    }

    fn block(x: f64, y: f64, size: [f64; 3], yaw: f64) -> Solid {
        Solid::Box {
            centre: Point3::new(x, y, 0.1 + size[2] / 2.0),
            size: Vector3::from(size),
            yaw,
        }
    }

    fn detect(pts: &[Point3<f64>], plane: &Plane, objs: &[SegmentedObject]) -> Vec<Grasp> {
        detect_grasps(
            pts,
            plane,
            objs,
            &GRIPPER,
            &GraspParams::default(),
            &AnalyticScorer::default(),
        )
        .unwrap()
    }

    #[test]
    fn a_long_block_is_grasped_across_its_narrow_width() {
        // A 2 x 8 x 4 cm block turned 0.5 rad: the best grasp closes across its 2 cm side
        // (within 12 degrees: candidates are 22.5 degrees apart, the first across the
        // measured long axis), centred on it within 5 mm, 2 cm deep.
        for (x, y, yaw) in [(0.45, 0.0, 0.5), (0.4, 0.1, -1.0), (0.5, -0.1, 1.4)] {
            let (pts, plane, objs) = look(vec![block(x, y, [0.02, 0.08, 0.04], yaw)]);
            assert_eq!(objs.len(), 1);
            let g = &detect(&pts, &plane, &objs)[0];
            let want = fold(yaw);
            let err = fold(g.yaw - want).abs();
            assert!(err < 12f64.to_radians(), "yaw {} want {want}", g.yaw);
            assert!((g.width - 0.02).abs() < 0.006, "width {}", g.width);
            let off = (g.position.xy() - Point3::new(x, y, 0.0).xy()).norm();
            assert!(off < 0.005, "off by {off}");
            assert!((g.top - 0.04).abs() < 0.003, "top {}", g.top);
            assert!((g.depth - 0.02).abs() < 0.003 && (g.position.z - 0.12).abs() < 0.003);
            assert!(g.clearance > 0.01);
        }
    }

    #[test]
    fn too_wide_objects_and_low_ones_have_no_grasp() {
        // A 6 cm cube is wider than the 4.9 cm opening every way; an 8 mm domino gives the
        // fingers no depth above the 1 cm table gap.
        let (pts, plane, objs) = look(vec![
            block(0.45, 0.1, [0.06, 0.06, 0.05], 0.3),
            block(0.45, -0.1, [0.02, 0.04, 0.008], 0.0),
        ]);
        assert!(!objs.is_empty());
        assert!(detect(&pts, &plane, &objs).is_empty());
    }

    #[test]
    fn a_neighbour_in_the_fingers_way_turns_the_grasp() {
        // A 3 cm cube with a tall block 2.5 cm beside it along y: closing along y would put a
        // finger into the block, so the chosen line runs along x (within 12 degrees), and no
        // feasible candidate has a finger within 3 mm of anything.
        let (pts, plane, objs) = look(vec![
            block(0.45, 0.0, [0.03, 0.03, 0.03], 0.0),
            block(0.45, 0.04, [0.06, 0.01, 0.06], 0.0),
        ]);
        assert_eq!(objs.len(), 2);
        let grasps = detect(&pts, &plane, &objs);
        let cube = objs
            .iter()
            .position(|o| o.features.centroid.y.abs() < 0.01)
            .unwrap();
        let g = grasps.iter().find(|g| g.object == cube).unwrap();
        assert!(fold(g.yaw).abs() < 12f64.to_radians(), "yaw {}", g.yaw);
        assert!(grasps.iter().all(|g| g.clearance >= 0.003));
        // The scores rank: best first.
        assert!(grasps.windows(2).all(|w| w[0].score >= w[1].score));
    }

    #[test]
    fn a_learned_model_replaces_the_scorer() {
        // A model that wants the closing line along x ranks that candidate first.
        struct AlongX;
        impl GraspModel for AlongX {
            fn score(&self, c: &GraspCandidate<'_>) -> Option<f64> {
                Some(c.grasp.closing.x.abs())
            }
        }
        let (pts, plane, objs) = look(vec![block(0.45, 0.0, [0.03, 0.03, 0.03], 0.7)]);
        let g = detect_grasps(
            &pts,
            &plane,
            &objs,
            &GRIPPER,
            &GraspParams::default(),
            &AlongX,
        )
        .unwrap();
        assert!(
            g[0].yaw.abs() <= std::f64::consts::PI / 16.0 + 1e-9,
            "{}",
            g[0].yaw
        );
        assert!(g.iter().all(|c| c.closing.x.abs() <= g[0].closing.x.abs()));
        assert_eq!(g.len(), 8);
    }

    #[test]
    fn bad_input_is_a_typed_error() {
        let (mut pts, plane, objs) = look(vec![block(0.45, 0.0, [0.03, 0.03, 0.03], 0.0)]);
        let s = AnalyticScorer::default();
        let run = |pts: &[Point3<f64>], g: &GripperGeometry, p: &GraspParams| {
            detect_grasps(pts, &plane, &objs, g, p, &s)
        };
        for p in [
            GraspParams {
                yaws: 0,
                ..Default::default()
            },
            GraspParams {
                target_depth: f64::NAN,
                ..Default::default()
            },
            GraspParams {
                table_gap: -1.0,
                ..Default::default()
            },
        ] {
            assert!(matches!(
                run(&pts, &GRIPPER, &p),
                Err(PerceptionError::Parameter { .. })
            ));
        }
        let wide = GripperGeometry {
            opening: f64::INFINITY,
            ..GRIPPER
        };
        assert!(matches!(
            run(&pts, &wide, &GraspParams::default()),
            Err(PerceptionError::Parameter { .. })
        ));
        assert!(matches!(
            run(&pts[..5], &GRIPPER, &GraspParams::default()),
            Err(PerceptionError::Parameter { .. })
        ));
        pts[3].x = f64::NAN;
        assert!(matches!(
            run(&pts, &GRIPPER, &GraspParams::default()),
            Err(PerceptionError::NonFinitePoint { index: 3, .. })
        ));
        // No objects: no grasps, no error.
        let none = detect_grasps(
            &pts[4..],
            &plane,
            &[],
            &GRIPPER,
            &GraspParams::default(),
            &s,
        )
        .unwrap();
        assert!(none.is_empty());
    }
}
