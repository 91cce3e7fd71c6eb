//! The push's strokes: shifting the base beside the table, ranking and trying the pushes,
//! the gripper's stroke along a push, its roll, and the arm's geometry they need.

use std::f64::consts::FRAC_PI_2;

use ferrobot::{Error, Orientation, Result};
use ferrobot_perception::PushPlan;
use nalgebra::{Point3, Vector3};

use super::*;

impl Push<'_> {
    /// The base's move (forward, left; m) from which a flat-topped object can be pushed (any
    /// object if `any` is false: nothing can be pushed from here): the first of
    /// `opts.base_shifts` sideways, and forward until the robot's body (see
    /// [`PushOptions::table_clearance`]) is `opts.table_clearance` from the table's near edge, for which the ranking with the arm's reach moved along finds one. `None`:
    /// no such move.
    pub(super) fn base_shift(
        &self,
        seen: &TableView,
        opts: &PushOptions,
        any: bool,
    ) -> Result<Option<[f64; 2]>> {
        let radius = self
            .config()
            .base
            .as_ref()
            .map(|b| b.footprint_radius)
            .ok_or_else(|| self.missing("base"))?;
        let (lo, hi) = table_bounds(&seen.table);
        // Not the footprint alone: the LoCoBot's plates reach 7 cm further ahead, at the
        // table top's height, and the arm stays folded out of the camera's view as it stands.
        let ahead = self.body_ahead(hi.z + opts.segment.max_height)?;
        let forward = (lo.x - radius.max(ahead) - opts.table_clearance).clamp(0.0, 0.5);
        for &left in &opts.base_shifts {
            let mut params = seen.params;
            params.reach_centre[0] += forward;
            params.reach_centre[1] += left;
            if let Ok(p) = rank_pushes(&seen.points, &seen.objects, &seen.table, &params) {
                if p[0].flat || !any {
                    return Ok(Some([forward, left]));
                }
            }
        }
        Ok(None)
    }
    /// Move the base by `shift` (forward, left; m): sideways by backing `back` (m, room to
    /// turn in place), turning a quarter, driving and turning back, then forward (by `back`
    /// more).
    pub(super) fn shift_base(&self, [forward, left]: [f64; 2], back: f64) -> Result<()> {
        let base = self.base()?;
        let mut forward = forward;
        if left.abs() > 1e-3 {
            if back > 1e-3 {
                base.go_to_relative([-back, 0.0, 0.0])?;
                forward += back;
            }
            let quarter = FRAC_PI_2.copysign(left);
            base.go_to_relative([0.0, 0.0, quarter])?;
            base.go_to_relative([left.abs(), 0.0, 0.0])?;
            base.go_to_relative([0.0, 0.0, -quarter])?;
        }
        if forward > 1e-3 {
            base.go_to_relative([forward, 0.0, 0.0])?;
        }
        Ok(())
    }
    /// Push by the best of `plans` (ranked on `seen`) the arm can make; `base_move` is
    /// reported.
    pub(super) fn push_ranked(
        &self,
        seen: TableView,
        plans: Vec<PushPlan>,
        opts: &PushOptions,
        base_move: [f64; 2],
        side: Side,
    ) -> Result<Pushed> {
        let arm = self.arm()?;
        let tip = self.finger_tip_depth()?;
        let TableView {
            fit,
            objects,
            table,
            params,
            ..
        } = seen;
        // The planning scene: the table and every object seen (the target too, until the
        // strokes, which go through it; added before each attempt).
        arm.remove_all_objects()?;
        let (lo, hi) = table_bounds(&table);
        let top = fit.plane.project(&Point3::from((lo + hi.coords) / 2.0));
        arm.add_table([top.x, top.y, top.z], [hi.x - lo.x, hi.y - lo.y, 0.05])?;
        let id = |k: usize| format!("object{k}");
        let mut boxes = Vec::with_capacity(objects.len());
        for o in &objects {
            let f = &o.features;
            let m = opts.object_margin;
            let bottom = fit.plane.project(&f.centroid).z;
            let size = [
                f.max.x - f.min.x + 2.0 * m,
                f.max.y - f.min.y + 2.0 * m,
                f.max.z - bottom + m,
            ];
            let centre = [
                (f.min.x + f.max.x) / 2.0,
                (f.min.y + f.max.y) / 2.0,
                bottom + size[2] / 2.0,
            ];
            boxes.push((centre, size));
        }
        // The best pushes in turn, until one is made: a push whose approach or strokes the
        // arm cannot reach, or whose lines the planning scene refuses, is given up before
        // the gripper meets its object.
        let mut last = None;
        for plan in plans.into_iter().take(opts.attempts.max(1)) {
            for (k, (centre, size)) in boxes.iter().enumerate() {
                let upright = Orientation::Quaternion([0.0, 0.0, 0.0, 1.0]);
                arm.add_world_object(&id(k), *centre, upright, *size)?;
            }
            match self.push_along(&plan, &id(plan.target), tip, opts, params.gap) {
                Ok((lift, roll)) => {
                    arm.remove_all_objects()?;
                    return Ok(Pushed {
                        plan,
                        objects: objects.into_iter().map(|o| o.features).collect(),
                        lift,
                        roll,
                        base_move,
                        side,
                    });
                }
                Err(e @ (Error::Unreachable { .. } | Error::Planning(_))) => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        arm.remove_all_objects()?;
        Err(last.unwrap_or(Error::Usage("push: no attempt made".into())))
    }
    /// One push along `plan` (the target `id` in the planning scene): approach, the two
    /// strokes, the retreat. Returns the approach's lift and the roll. An
    /// [`Error::Unreachable`] or [`Error::Planning`] comes before the gripper meets the
    /// object, with the gripper back at its approach height.
    pub(super) fn push_along(
        &self,
        plan: &PushPlan,
        id: &str,
        tip: f64,
        opts: &PushOptions,
        gap: f64,
    ) -> Result<(f64, f64)> {
        let arm = self.arm()?;
        // The gripper pointing down, its broad side (the gripper's y axis) across the push.
        let lift_point = |lift: f64| [plan.start.x, plan.start.y, plan.start.z + tip + lift];
        let roll = self.push_roll(lift_point(0.0), plan.heading)?;
        let mut used = None;
        for &lift in &opts.lifts {
            match arm.set_ee_pose_pitch_roll(lift_point(lift), FRAC_PI_2, Some(roll)) {
                Ok(()) => {
                    used = Some(lift);
                    break;
                }
                Err(Error::Unreachable { .. }) => continue,
                Err(e) => return Err(e),
            }
        }
        let lift = used.ok_or_else(|| Error::Unreachable {
            why: format!(
                "no approach above the push's start ({:.3}, {:.3}) m at lifts {:?} m",
                plan.start.x, plan.start.y, opts.lifts
            ),
        })?;
        arm.remove_world_object(id)?;
        // Stroke 1: down beside the object; stroke 2: through it.
        arm.move_ee_xyz([0.0, 0.0, -lift], opts.step)?;
        let d = plan.end - plan.start;
        if let Err(e) = arm.move_ee_xyz([d.x, d.y, d.z], opts.step) {
            // Refused before moving: back up where the next attempt starts from.
            arm.move_ee_xyz_with([0.0, 0.0, lift], opts.step, false)?;
            return Err(e);
        }
        // Clear of the object: back by the gap, then up (unchecked: the pushed object moved
        // away from where it was seen).
        let back = -d.normalize() * gap;
        arm.move_ee_xyz_with([back.x, back.y, 0.0], opts.step, false)?;
        // As high as the arm reaches there, up to the approach's lift.
        for &up in opts.lifts.iter().filter(|&&l| l <= lift) {
            match arm.move_ee_xyz_with([0.0, 0.0, up], opts.step, false) {
                Err(Error::Unreachable { .. }) => continue,
                r => {
                    r?;
                    break;
                }
            }
        }
        Ok((lift, roll))
    }
    /// The roll (rad) that turns the downward-pointing gripper's y axis (its broad side)
    /// across a push of `heading` (rad from +x) at `position`: of the two faces, the one
    /// needing the smaller roll.
    pub(super) fn push_roll(&self, position: [f64; 3], heading: f64) -> Result<f64> {
        let arm = self.arm()?;
        let ee = self.config().arm.as_ref().map(|a| a.ee_frame.clone());
        let ee = ee.ok_or_else(|| self.missing("arm"))?;
        // The gripper's z axis (normal to its broad side) at rolls 0 and 0.1: its yaw moves
        // with the roll at a rate of ±1.
        let yaw = |roll: f64| -> Result<f64> {
            let q = arm.compute_ik_pitch_roll(position, FRAC_PI_2, Some(roll), None)?;
            let r = arm.compute_fk_position(&q, &ee)?.rotation;
            Ok(r[1][2].atan2(r[0][2]))
        };
        let (y0, y1) = (yaw(0.0)?, yaw(0.1)?);
        let rate = if ferrobot_geometry::wrap(y1 - y0) > 0.0 {
            1.0
        } else {
            -1.0
        };
        let face = |h: f64| ferrobot_geometry::wrap(h - y0) * rate;
        let (a, b) = (face(heading), face(heading + std::f64::consts::PI));
        Ok(if a.abs() <= b.abs() { a } else { b })
    }
    /// Where the arm's first joint axis meets `base_link`'s x-y plane, m: the origin of the
    /// first joint's child link at zero angles.
    pub(super) fn shoulder_axis(&self) -> Result<[f64; 2]> {
        let arm = self.arm()?;
        let cfg = self.config();
        let first = cfg
            .arm
            .as_ref()
            .and_then(|a| a.joints.first())
            .and_then(|j| cfg.urdf.joints.iter().find(|u| &u.name == j))
            .ok_or_else(|| self.missing("arm"))?;
        let p = arm.compute_fk_position(&vec![0.0; arm.dof()], &first.child.link)?;
        Ok([p.position[0], p.position[1]])
    }
    /// How far the closed fingers reach beyond the end-effector frame along its x axis (the
    /// gripper's pointing axis), m: from the URDF's finger joints and their links' collision
    /// boxes.
    pub(super) fn finger_tip_depth(&self) -> Result<f64> {
        let cfg = self.config();
        let g = cfg
            .gripper
            .as_ref()
            .ok_or_else(|| self.missing("gripper"))?;
        let mut depth: Option<f64> = None;
        for f in &g.fingers {
            let Some(j) = cfg.urdf.joints.iter().find(|j| j.name == f.joint) else {
                continue;
            };
            let at = ferrobot::kinematics::pose_from_urdf(&j.origin);
            let Some(link) = cfg.urdf.links.iter().find(|l| l.name == j.child.link) else {
                continue;
            };
            for c in &link.collision {
                if let urdf_rs::Geometry::Box { size } = &c.geometry {
                    let pose = at * ferrobot::kinematics::pose_from_urdf(&c.origin);
                    let h = Vector3::new(size[0], size[1], size[2]) / 2.0;
                    for k in 0..8 {
                        let s = |b: usize| if k & (1 << b) == 0 { -1.0 } else { 1.0 };
                        let p = pose * Point3::new(s(0) * h.x, s(1) * h.y, s(2) * h.z);
                        depth = Some(depth.map_or(p.x, |d: f64| d.max(p.x)));
                    }
                }
            }
        }
        depth.ok_or_else(|| Error::Config {
            file: cfg.urdf_file.clone().into(),
            key: "gripper.fingers".into(),
            problem: "no finger link with a collision box to push with".into(),
        })
    }
}
