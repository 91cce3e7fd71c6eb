//! Arm planning as the API sees it: the simulated world's objects as planning-scene objects,
//! and re-exports of `ferrobot-planning`.

pub use ferrobot_planning::*;

#[cfg(feature = "sim")]
use ferrobot_sim::body::RobotBody;
#[cfg(feature = "sim")]
use ferrobot_sim::scene::{self as world, Scene};
#[cfg(feature = "sim")]
use nalgebra::Isometry3;

#[cfg(feature = "sim")]
/// A scene body's shape as the planner's (meshes as the convex hull of their vertices).
pub fn shape_of(shape: &world::Shape) -> Shape {
    match shape {
        world::Shape::Box(s) => Shape::Box(*s),
        world::Shape::Cylinder { radius, length } => Shape::Cylinder {
            radius: *radius,
            length: *length,
        },
        world::Shape::Sphere(r) => Shape::Sphere(*r),
        world::Shape::Capsule { radius, length } => Shape::Capsule {
            radius: *radius,
            length: *length,
        },
        world::Shape::Mesh { mesh, .. } => Shape::Hull(mesh.vertices.clone()),
    }
}

#[cfg(feature = "sim")]
/// The pose of the robot's root link in the world of `scene` at its start.
pub fn root_in_world(scene: &Scene) -> Isometry3<f64> {
    RobotBody::root_pose(scene.robot_pose, scene.robot_height)
}

#[cfg(feature = "sim")]
/// Every body of `scene` as a planning-scene object, posed in the frame of the robot's root
/// link when the robot's root is at `root` (world frame).
pub fn scene_objects(scene: &Scene, root: &Isometry3<f64>) -> Vec<WorldObject> {
    let inv = root.inverse();
    scene
        .bodies
        .iter()
        .map(|b| WorldObject {
            id: b.id.clone(),
            shape: shape_of(&b.shape),
            pose: inv * b.pose,
        })
        .collect()
}
