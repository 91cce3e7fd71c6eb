//! Grasping, as PyRobot's grasping example: look at the table (head tilted 0.8 rad down), find
//! the table and the objects on it in one RGB-D frame, choose a top-down grasp
//! ([`ferrobot_perception::grasp`]), plan the arm to a pregrasp above it (planner on,
//! the table as the camera saw it in the planning scene), descend, close, lift.
//!
//! Everything is decided from what the robot senses (the camera's cloud, the joints); the
//! simulator's ground truth plays no part. Frames: `base_link` (x forward, z up), m, rad.

use std::f64::consts::{FRAC_PI_2, PI};

use ferrobot::GripperState;
use ferrobot_perception::{
    detect_grasps, segment_objects, AnalyticScorer, Dbscan, Grasp, GraspModel, GraspParams,
    GripperGeometry, Plane, PlaneFit, RansacParams, SegmentParams, SegmentedObject, TableRegion,
};
use nalgebra::{Point3, Vector3};

use ferrobot::validate;
use ferrobot::{Error, Robot, RobotConfig};

use crate::error::Result;

/// Why a grasp could not be made (the world's fault, not the caller's).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GraspFailure {
    /// The camera saw no object on the table.
    #[error("no object on the table (the camera saw {points} points above it, in no cluster)")]
    NoObject {
        /// Points above the table's plane in the segmentation's band.
        points: usize,
    },
    /// Objects were seen, none of them graspable (too wide for the opening, too low, or
    /// crowded).
    #[error(
        "no feasible grasp on the {objects} objects seen (too wide for the {opening:.3} m \
         opening, too low, or crowded)"
    )]
    NoFeasibleGrasp {
        /// Objects seen.
        objects: usize,
        /// The gripper's opening, m.
        opening: f64,
    },
    /// Feasible grasps were found, and the arm reached none of them.
    #[error("the arm reaches none of the {tried} grasps tried; the last: {why}")]
    OutOfReach {
        /// Grasps tried (IK, then planning).
        tried: usize,
        /// Why the last could not be reached (IK, planning).
        why: String,
    },
    /// The gripper closed fully: nothing was between the fingers.
    #[error("the gripper closed on nothing at ({x:.3}, {y:.3}, {z:.3}) m")]
    ClosedOnNothing {
        /// Where the fingertips were (base_link), m.
        x: f64,
        /// y, m.
        y: f64,
        /// z, m.
        z: f64,
    },
}

/// How to grasp.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspOptions {
    /// Head tilt while looking, rad (PyRobot's example: 0.8).
    pub head_tilt: f64,
    /// Height of the pregrasp above the grasp (of the end effector), m. PyRobot's example
    /// puts the pregrasp at 0.2 m and the grasp at 0.13 m above `base_link` (objects on the
    /// floor): 0.07 m between them. On a table the LoCoBot pointing down does not reach 0.2 m
    /// above a grasp (its top-down reach ends about 0.33 m above `base_link`), so the default
    /// keeps PyRobot's 0.07 m.
    pub pregrasp: f64,
    /// How far the object is lifted after closing, m (back to the pregrasp's height by
    /// default, which the arm is known to reach).
    pub lift: f64,
    /// Plans to a pregrasp tried, best grasp first, until one succeeds: 1..=100 (grasps
    /// with no pointing-down IK solution are passed over without counting).
    pub attempts: usize,
    /// Candidate generation.
    pub params: GraspParams,
    /// The objects' points above the table.
    pub segment: SegmentParams,
    /// DBSCAN's radius, m (PyRobot's pushing example: 0.02).
    pub eps: f64,
    /// DBSCAN's core count (PyRobot's pushing example: 15).
    pub min_samples: usize,
    /// Every how many points of the camera's cloud are used: 1..=16 (2 keeps a point every
    /// 2 mm at the table's distance).
    pub stride: usize,
}

impl Default for GraspOptions {
    /// PyRobot's numbers (tilt 0.8 rad, the pregrasp 0.07 m above the grasp; DBSCAN 0.02 m,
    /// 15 points), lifted back to the pregrasp's height, 5 attempts, every 2nd point.
    fn default() -> Self {
        GraspOptions {
            head_tilt: 0.8,
            pregrasp: 0.07,
            lift: 0.07,
            attempts: 5,
            params: GraspParams::default(),
            segment: SegmentParams::default(),
            eps: 0.02,
            min_samples: 15,
            stride: 2,
        }
    }
}

impl GraspOptions {
    /// Checks the ranges (see each field); the perception parameters are checked where used.
    pub fn check(&self) -> Result<()> {
        validate::in_range("head tilt", self.head_tilt, -FRAC_PI_2, FRAC_PI_2)?;
        validate::in_range("pregrasp height", self.pregrasp, 0.0, 1.0)?;
        validate::in_range("lift", self.lift, 0.0, 1.0)?;
        validate::count("grasp attempts", self.attempts, 1..=100)?;
        validate::count("cloud stride", self.stride, 1..=16)?;
        Ok(())
    }
}

/// What the camera saw: the cloud (base_link), the table and the objects on it, and the
/// grasps on them, best first.
#[derive(Debug, Clone)]
pub struct TableView {
    /// The points used (base_link), m.
    pub points: Vec<Point3<f64>>,
    /// The table's plane and its inliers.
    pub table: PlaneFit,
    /// The objects on it.
    pub objects: Vec<SegmentedObject>,
    /// The feasible grasps, best first.
    pub grasps: Vec<Grasp>,
}

/// A grasp made: which, and the gripper's state after the lift.
#[derive(Debug, Clone)]
pub struct Grasped {
    /// The grasp carried out (base_link).
    pub grasp: Grasp,
    /// Objects seen.
    pub objects: usize,
    /// Better grasps passed over because the arm could not reach them (IK or planning).
    pub skipped: usize,
    /// The gripper's state after the lift (holding, unless the object slipped).
    pub state: GripperState,
}

/// The gripper as the grasp detector sees it, from the description: the opening from the
/// fingers' travel at the open tick, the fingers' sizes from their collision boxes in the
/// URDF (length along the gripper's x, which points down in a top-down grasp; thickness along
/// the closing line; width across it). Returns it and the height of the fingertips below the
/// end-effector frame's origin, m.
pub fn gripper_geometry(cfg: &RobotConfig) -> ferrobot::Result<(GripperGeometry, f64)> {
    let missing = |component| Error::NoComponent {
        robot: cfg.name.clone(),
        component,
    };
    let g = cfg.gripper.as_ref().ok_or_else(|| missing("gripper"))?;
    let finger = g
        .fingers
        .first()
        .and_then(|f| cfg.urdf.joints.iter().find(|j| j.name == f.joint))
        .ok_or_else(|| missing("gripper finger joints"))?;
    let link = cfg
        .urdf
        .links
        .iter()
        .find(|l| l.name == finger.child.link)
        .ok_or_else(|| missing("gripper finger link"))?;
    let (size, at) = link
        .collision
        .iter()
        .find_map(|c| match &c.geometry {
            urdf_rs::Geometry::Box { size } => Some((size.0, c.origin.xyz.0)),
            _ => None,
        })
        .ok_or_else(|| missing("gripper finger collision box"))?;
    let open = g.finger_offset(f64::from(g.open_tick));
    let geometry = GripperGeometry {
        opening: 2.0 * (open - g.finger_travel[0]),
        finger_thickness: size[1],
        finger_width: size[2],
        finger_length: size[0],
    };
    let tip = finger.origin.xyz.0[0] + at[0] + size[0] / 2.0;
    Ok((geometry, tip))
}

/// The table: the dominant plane of `points` facing up, or, when most points lie well above
/// it (the camera sees the floor around a table), the dominant plane of those.
fn find_table(points: &[Point3<f64>]) -> Result<PlaneFit> {
    let ransac = RansacParams {
        threshold: 0.005,
        max_tilt: 0.3,
        seed: 1,
        ..Default::default()
    };
    let first = fit_plane(points, &ransac)?;
    let above: Vec<usize> = (0..points.len())
        .filter(|&i| first.plane.signed_distance(&points[i]) > 0.03)
        .collect();
    if above.len() < points.len() / 5 {
        return Ok(first);
    }
    let sub: Vec<Point3<f64>> = above.iter().map(|&i| points[i]).collect();
    match fit_plane(&sub, &ransac) {
        Ok(f) if f.inliers.len() >= points.len() / 10 => {
            // Its inliers in the whole cloud.
            let inliers = (0..points.len())
                .filter(|&i| f.plane.signed_distance(&points[i]).abs() <= ransac.threshold)
                .collect();
            Ok(PlaneFit { inliers, ..f })
        }
        _ => Ok(first),
    }
}

fn fit_plane(points: &[Point3<f64>], p: &RansacParams) -> Result<PlaneFit> {
    Ok(ferrobot_perception::fit_plane(points, p)?)
}

/// The table, the objects and the grasps in `points` (base_link, m), scored by `model`.
/// Errors: an empty or non-finite cloud, bad options, no table plane.
pub fn view_table(
    points: Vec<Point3<f64>>,
    gripper: &GripperGeometry,
    opts: &GraspOptions,
    model: &dyn GraspModel,
) -> Result<TableView> {
    opts.check()?;
    let table = find_table(&points)?;
    let dbscan = Dbscan::new(opts.eps, opts.min_samples)?;
    let objects = segment_objects(&points, &table, &opts.segment, &dbscan)?;
    let grasps = detect_grasps(
        &points,
        &table.plane,
        &objects,
        gripper,
        &opts.params,
        model,
    )?;
    Ok(TableView {
        points,
        table,
        objects,
        grasps,
    })
}

/// Look at the table: head to pan 0 and `opts.head_tilt`, one frame, its cloud in base_link
/// (every `opts.stride`-th point), the table, objects and grasps ([`view_table`]).
pub fn look(robot: &Robot, opts: &GraspOptions, model: &dyn GraspModel) -> Result<TableView> {
    opts.check()?;
    let (gripper, _) = gripper_geometry(robot.config())?;
    let camera = robot.camera()?;
    camera.head()?.set_pan_tilt(0.0, opts.head_tilt)?;
    let cloud = camera.get_current_pcd(false)?;
    let points: Vec<Point3<f64>> = cloud.points.into_iter().step_by(opts.stride).collect();
    if points.is_empty() {
        return Err(ferrobot_perception::PerceptionError::EmptyCloud {
            what: "camera's cloud",
        }
        .into());
    }
    view_table(points, &gripper, opts, model)
}

/// The table as a box for the planning scene (base_link): the hull of the plane's inliers,
/// from the floor (z = the plane's height minus `depth`) to the plane.
fn table_box(view: &TableView) -> Result<([f64; 3], [f64; 3])> {
    let region = TableRegion::new(&view.points, &view.table)?;
    let corners: Vec<Point3<f64>> = region
        .hull
        .iter()
        .map(|&[u, v]| region.origin + region.u * u + region.v * v)
        .collect();
    let lo = corners
        .iter()
        .fold(Vector3::repeat(f64::INFINITY), |m, p| m.inf(&p.coords));
    let hi = corners
        .iter()
        .fold(Vector3::repeat(f64::NEG_INFINITY), |m, p| m.sup(&p.coords));
    let Plane { normal, offset } = view.table.plane;
    let c = (lo + hi) / 2.0;
    let top = (offset - normal.x * c.x - normal.y * c.y) / normal.z.max(1e-6);
    let thick = top.clamp(0.01, 1.0);
    Ok(([c.x, c.y, top], [hi.x - lo.x, hi.y - lo.y, thick]))
}

/// Look, choose, and pick the best grasp the arm reaches: open the gripper, plan to the
/// pregrasp `opts.pregrasp` above it (the table in the planning scene), descend, close, lift
/// `opts.lift`. The arm first goes out of the camera's view: to the description's look pose
/// (`[arm] look`), or else its stow pose, when it has one. Errors: [`GraspFailure`]s (no object, no feasible or reachable
/// grasp, closed on nothing: the gripper is opened and the arm raised again), and those of
/// the parts (camera, planning, motions).
pub fn pick(robot: &Robot, opts: &GraspOptions) -> Result<Grasped> {
    pick_with(robot, opts, &AnalyticScorer::default())
}

/// [`pick`] with another [`GraspModel`].
pub fn pick_with(robot: &Robot, opts: &GraspOptions, model: &dyn GraspModel) -> Result<Grasped> {
    opts.check()?;
    let arm = robot.arm()?;
    let gripper = robot.gripper()?;
    let (geometry, tip) = gripper_geometry(robot.config())?;
    gripper.open()?;
    let arm_cfg = robot.config().arm.as_ref();
    match arm_cfg.and_then(|a| a.look.clone()) {
        Some(q) => arm.set_joint_positions(&q)?,
        None if arm_cfg.is_some_and(|a| a.stow.is_some()) => arm.stow()?,
        None => {}
    }
    let view = look(robot, opts, model)?;
    if view.objects.is_empty() {
        let band = ferrobot_perception::above_table(&view.points, &view.table, &opts.segment)?;
        return Err(GraspFailure::NoObject { points: band.len() }.into());
    }
    let (top, size) = table_box(&view)?;
    arm.add_table(top, size)?;
    if view.grasps.is_empty() {
        return Err(GraspFailure::NoFeasibleGrasp {
            objects: view.objects.len(),
            opening: geometry.opening,
        }
        .into());
    }
    // Grasps the arm cannot reach pointing down (no IK solution) are passed over at once;
    // planning to a pregrasp is tried `opts.attempts` times at most.
    let (mut skipped, mut planned) = (0, 0);
    let mut why = String::new();
    for g in &view.grasps {
        if planned == opts.attempts {
            break;
        }
        let ee = g.position + Vector3::z() * tip;
        let above = [ee.x, ee.y, ee.z + opts.pregrasp];
        let reached = top_down(robot, above, g.yaw).and_then(|q| {
            planned += 1;
            arm.set_joint_positions(&q)
        });
        if let Err(e) = reached {
            skipped += 1;
            why = format!(
                "pregrasp ({:.3}, {:.3}, {:.3}) m: {e}",
                above[0], above[1], above[2]
            );
            continue;
        }
        arm.move_ee_xyz([0.0, 0.0, -opts.pregrasp], 0.01)?;
        let state = gripper.close()?;
        if state != GripperState::Holding {
            gripper.open()?;
            arm.move_ee_xyz([0.0, 0.0, opts.pregrasp], 0.01)?;
            return Err(GraspFailure::ClosedOnNothing {
                x: g.position.x,
                y: g.position.y,
                z: g.position.z,
            }
            .into());
        }
        arm.move_ee_xyz([0.0, 0.0, opts.lift], 0.01)?;
        return Ok(Grasped {
            grasp: g.clone(),
            objects: view.objects.len(),
            skipped,
            state: gripper.get_state()?,
        });
    }
    Err(GraspFailure::OutOfReach {
        tried: skipped,
        why,
    }
    .into())
}

/// Joint angles putting the end effector at `position` (base_link, m) pointing down, its
/// fingers closing along `yaw` (rad about z): the fingers' line with no roll, read on the
/// forward kinematics (the arm's yaw axis is not base_link's origin), turned onto `yaw` by the
/// roll, whose sign is checked on the forward kinematics too.
fn top_down(robot: &Robot, position: [f64; 3], yaw: f64) -> ferrobot::Result<Vec<f64>> {
    let arm = robot.arm()?;
    let ee = robot
        .config()
        .arm
        .as_ref()
        .map(|a| a.ee_frame.clone())
        .unwrap_or_default();
    let fold = |a: f64| (a + FRAC_PI_2).rem_euclid(PI) - FRAC_PI_2;
    // The gripper's y axis (the fingers' line) about z in base_link.
    let line = |q: &[f64]| -> ferrobot::Result<f64> {
        let r = arm.compute_fk_position(q, &ee)?.rotation;
        Ok(r[1][1].atan2(r[0][1]))
    };
    let q0 = arm.compute_ik_pitch_roll(position, FRAC_PI_2, Some(0.0), None)?;
    let turn = fold(yaw - line(&q0)?);
    for r in [turn, -turn] {
        let q = arm.compute_ik_pitch_roll(position, FRAC_PI_2, Some(r), Some(&q0))?;
        if fold(line(&q)? - yaw).abs() < 0.05 {
            return Ok(q);
        }
    }
    Err(Error::Unreachable {
        why: format!("no roll of the pointing-down gripper closes along yaw {yaw:.3} rad"),
    })
}
