//! The arm's planning scene, PyRobot's MoveIt object API: objects in the world (boxes,
//! shapes, the table, the simulated world's bodies, a point cloud), objects attached to the
//! gripper, the collision model and checkers built on them, and the arm's collision state now.
//! Frames: the arm's base frame unless said otherwise; m, rad.

use std::sync::Arc;

use ferrobot_planning::{CheckOptions, Checker, CollisionModel, Contact, Shape, Voxels};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use parking_lot::Mutex;

use crate::arm::{Arm, Orientation};
use crate::arm_parts::ArmPlanning;
use crate::error::Result;

pub(crate) fn pose_of(position: [f64; 3], q: UnitQuaternion<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(position[0], position[1], position[2]), q)
}

impl Arm {
    pub(crate) fn planning(&self) -> parking_lot::MutexGuard<'_, ArmPlanning> {
        self.parts_planning().lock()
    }
    pub(crate) fn parts_planning(&self) -> &Mutex<ArmPlanning> {
        &self.parts().planning
    }
    /// The collision model, built on first use.
    pub(crate) fn model(&self) -> Result<Arc<CollisionModel>> {
        let mut p = self.planning();
        if let Some(m) = &p.model {
            return Ok(m.clone());
        }
        let m = Arc::new(CollisionModel::from_config(self.robot.cfg())?);
        p.model = Some(m.clone());
        Ok(m)
    }
    /// A checker of the scene as it is now, with the fingers and the head where they are.
    pub(crate) fn checker(&self) -> Result<Checker> {
        self.checker_allowing(&[])
    }
    /// [`Arm::checker`] with link pairs `allowed` to touch besides the matrix's.
    pub(crate) fn checker_allowing(&self, allowed: &[(String, String)]) -> Result<Checker> {
        let mut model = (*self.model()?).clone();
        for (a, b) in allowed {
            model.allow_pair(a, b);
        }
        let cfg = self.robot.cfg();
        let t = self.robot.telemetry()?;
        let fixed: Vec<String> = model.fixed_values().into_iter().map(|(n, _)| n).collect();
        for name in fixed {
            if let Some(i) = cfg.joint_index(&name) {
                if let Some(s) = t.joints.get(i) {
                    model.set_measured_value(&name, f64::from(s.position))?;
                }
            }
        }
        if let Some(g) = &cfg.gripper {
            if let Some(i) = cfg.joint_index(&g.joint) {
                if let Some(s) = t.joints.get(i) {
                    let ticks = f64::from(s.position)
                        / f64::from(ferrobot_protocol::dxl::units::RAD_PER_TICK)
                        + f64::from(ferrobot_protocol::dxl::units::CENTER_TICK);
                    for (joint, v) in g.finger_positions(ticks) {
                        model.set_measured_value(&joint, v)?;
                    }
                }
            }
        }
        let scene = self.planning().scene.clone();
        Ok(Checker::new(
            Arc::new(model),
            &scene,
            CheckOptions::default(),
        )?)
    }
    /// Adds (or replaces) a box `id` of full extents `size` (m) at `position` (m) with
    /// `orientation` in the arm's base frame (PyRobot's `add_world_object`).
    pub fn add_world_object(
        &self,
        id: &str,
        position: [f64; 3],
        orientation: Orientation,
        size: [f64; 3],
    ) -> Result<()> {
        self.add_world_shape(id, Shape::Box(size), position, orientation)
    }
    /// Adds (or replaces) an object `id` of any shape at `position` (m) with `orientation` in
    /// the arm's base frame. An id that names one of the robot's links is an error.
    pub fn add_world_shape(
        &self,
        id: &str,
        shape: Shape,
        position: [f64; 3],
        orientation: Orientation,
    ) -> Result<()> {
        let q = orientation.to_quaternion()?;
        ferrobot_planning::checker::check_not_a_link(&*self.model()?, id)?;
        let base = self.base_frame_in_root()?;
        self.planning()
            .scene
            .add_object(id, shape, base * pose_of(position, q))?;
        Ok(())
    }
    /// A table: a box of full extents `size` (m) whose top centre is at `top` (m, base frame),
    /// named `table` (PyRobot's `add_table`).
    pub fn add_table(&self, top: [f64; 3], size: [f64; 3]) -> Result<()> {
        let centre = [top[0], top[1], top[2] - size[2] / 2.0];
        self.add_world_object(
            "table",
            centre,
            Orientation::Quaternion([0.0, 0.0, 0.0, 1.0]),
            size,
        )
    }
    /// Removes object `id` (in the world or attached); an unknown id is an error.
    pub fn remove_world_object(&self, id: &str) -> Result<()> {
        self.planning().scene.remove_object(id)?;
        Ok(())
    }
    /// Attaches a box `id` of full extents `size` (m) at `position` (m) with `orientation` in
    /// the end-effector frame: it moves with the gripper and is checked against the world and the
    /// arm; the gripper and its fingers may touch it (PyRobot's `attach_arm_object`).
    pub fn attach_arm_object(
        &self,
        id: &str,
        position: [f64; 3],
        orientation: Orientation,
        size: [f64; 3],
    ) -> Result<()> {
        let q = orientation.to_quaternion()?;
        ferrobot_planning::checker::check_not_a_link(&*self.model()?, id)?;
        let cfg = self.robot.cfg();
        let ee = self.cfg_arm().ee_frame.clone();
        let mut touch: Vec<String> = cfg
            .gripper
            .iter()
            .flat_map(|g| g.fingers.iter())
            .filter_map(|f| cfg.urdf.joints.iter().find(|j| j.name == f.joint))
            .map(|j| j.child.link.clone())
            .collect();
        // The links the end effector is fixed to touch it too (a frame link without geometry
        // sits on the wrist).
        touch.extend(
            cfg.urdf
                .joints
                .iter()
                .filter(|j| j.child.link == ee && matches!(j.joint_type, urdf_rs::JointType::Fixed))
                .map(|j| j.parent.link.clone()),
        );
        self.planning()
            .scene
            .attach(id, &ee, Shape::Box(size), pose_of(position, q), touch)?;
        Ok(())
    }
    /// Detaches (and forgets) object `id`; an id not attached is an error.
    pub fn detach_arm_object(&self, id: &str) -> Result<()> {
        self.planning().scene.detach(id, None)?;
        Ok(())
    }
    /// Detach object `id` from the end effector and leave it in the planning scene where it
    /// is now (at the measured joints): what a gripper letting go of it does.
    pub fn release_arm_object(&self, id: &str) -> Result<()> {
        let attached = self
            .planning()
            .scene
            .attached()
            .find(|a| a.id == id)
            .map(|a| (a.link.clone(), a.pose));
        let Some((link, offset)) = attached else {
            // Not attached: the scene's own error names it.
            return self.detach_arm_object(id);
        };
        let model = self.model()?;
        let root = model.tree().root().to_string();
        let link_in_root = self.robot.link_transform(&link, &root)?;
        self.planning()
            .scene
            .detach(id, Some(link_in_root * offset))?;
        Ok(())
    }
    /// Removes every object, attached or not, and the point-cloud voxels.
    pub fn remove_all_objects(&self) -> Result<()> {
        self.planning().scene.clear();
        Ok(())
    }
    #[cfg(feature = "sim")]
    /// Adds the bodies of the world the robot was built in ([`crate::Robot::scene`]), posed
    /// for the robot at the scene's start pose (objects moved since, or a base that drove
    /// away, are not followed). Returns how many.
    pub fn add_scene_objects(&self) -> Result<usize> {
        let scene = self.robot.scene();
        let root = crate::planning::root_in_world(&scene);
        let objects = crate::planning::scene_objects(&scene, &root);
        let n = objects.len();
        let mut p = self.planning();
        for o in objects {
            p.scene.add_object(&o.id, o.shape, o.pose)?;
        }
        Ok(n)
    }
    /// Replaces the voxels from a point cloud (m, in the arm's base frame) with cubes of
    /// `voxel` m (within [`ferrobot_planning::scene::VOXEL_RANGE`]); `None` removes them.
    /// Non-finite points, points beyond 1 km and more than
    /// [`ferrobot_planning::scene::MAX_VOXELS`] cubes are errors that leave the voxels as they
    /// were.
    pub fn set_point_cloud(&self, points: Option<&[[f64; 3]]>, voxel: f64) -> Result<()> {
        let v = match points {
            Some(p) => {
                let base = self.base_frame_in_root()?;
                let pts: Vec<Point3<f64>> = p.iter().map(|&x| base * Point3::from(x)).collect();
                Some(Voxels::from_points(&pts, voxel)?)
            }
            None => None,
        };
        self.planning().scene.set_voxels(v)?;
        Ok(())
    }
    /// The arm's base frame in the URDF root's frame (the planner's frame is the root's).
    pub(crate) fn base_frame_in_root(&self) -> Result<Isometry3<f64>> {
        // The collision model's tree, built once, rather than the URDF parsed again.
        let model = self.model()?;
        let tree = model.tree();
        let poses = tree.poses(&[]);
        Ok(tree.transform(&poses, &self.cfg_arm().base_frame, tree.root())?)
    }
    /// The first contact of the arm in its current configuration (links by URDF name, objects
    /// by id), or `None` when free (PyRobot's `get_collision_state`).
    pub fn get_collision_state(&self) -> Result<Option<Contact>> {
        let q = self.get_joint_angles()?;
        let c = self.checker()?;
        // The measured angles may sit a hair past a limit: clamp for the check.
        let q: Vec<f64> = q
            .iter()
            .zip(c.model().limits())
            .map(|(v, (lo, hi))| v.clamp(*lo, *hi))
            .collect();
        Ok(c.contact(&q))
    }
}
