//! The physics world: the scene's bodies as rigid bodies in rapier3d, stepped in lockstep
//! with the plants at a fixed [`STEP_US`], the robot's links as kinematic colliders the plants
//! drive, contacts observed by shape queries, and the gripper's grasp as a fixed joint.
//! Deterministic for a seed. Units SI, world frame right-handed with z up; quaternions
//! `[x, y, z, w]`; [`convert`] is the one place where nalgebra's `f64` types meet rapier's
//! `f32`. Design: `docs/design/sim-stubs.md`, "world".

use std::sync::Arc;

use nalgebra::Isometry3;
use rapier3d::prelude::*;

use crate::body::RobotBody;
use crate::chain::ServoChain;
use crate::diff_drive::Pose as BasePose;
use crate::scene::{Scene, SceneError};

mod colliders;
mod contacts;
mod grip;
mod links;

use colliders::{collider, link_collider};
use contacts::Watch;
pub use contacts::{Around, ContactError, RobotContact, RobotContactRecord};

/// The world's fixed step, µs.
pub const STEP_US: u64 = 1000;
/// A finger touches an object at this distance or closer, m.
pub const TOUCH: f64 = 0.0005;
/// The grasp is released when the gripper servo has opened this far beyond the angle at which
/// it closed on the object, rad (0.3 mm of finger travel on the LoCoBot).
pub const RELEASE: f64 = 0.02;
/// A moving link closer than this to a movable body (by their bounding boxes) makes the
/// world step even when every movable body is asleep, m.
pub const NEAR: f64 = 0.02;
/// A scene body reaching this far into a robot link at the start is an overlap, m.
pub const OVERLAP: f64 = 0.001;
/// Length scale of the world, m: rapier's tolerances (allowed penetration 0.1 mm, contact
/// prediction 0.4 mm, sleep thresholds) are fractions of it. The graspable objects are 2-8 cm;
/// at 0.05 m and above a mug's convex hull (a many-sided base) rocks and walks on the table
/// (2 mm/s at 0.05, 10 mm/s at 1), at 0.02 m everything in the bundled scenes comes to rest.
pub const LENGTH_UNIT: f32 = 0.02;
/// Greatest distance between the balls of a movable capsule, as a fraction of its radius.
pub const BALL_SPACING: f32 = 1.0 / 3.0;
/// A movable capsule needing more balls than this (a needle) keeps rapier's capsule.
pub const MAX_BALLS: usize = 64;
/// Lowest and highest point of the bases' bumper ring above the floor, m.
pub const BUMPER_BAND: (f64, f64) = (0.015, 0.105);
/// Standard gravity, m/s².
pub const GRAVITY: f64 = 9.81;
/// A robot link and a scene body are in contact when their shapes are this close or closer
/// (penetrating included), m. rapier's `f32` geometry resolves about 0.1 µm a few metres from
/// the origin; a LoCoBot's wheels stand 0.2 mm above the floor and are not in contact.
pub const CONTACT: f64 = 1e-4;

/// The one place where nalgebra's `f64` types and rapier's `f32` glam types meet.
pub mod convert {
    use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
    use rapier3d::math::{Pose, Rotation, Vector};

    /// A vector (m) for rapier.
    pub fn vector(v: &Vector3<f64>) -> Vector {
        Vector::new(v.x as f32, v.y as f32, v.z as f32)
    }

    /// A point (m) for rapier.
    pub fn point(p: &Point3<f64>) -> Vector {
        vector(&p.coords)
    }

    /// A rapier vector as nalgebra's, m.
    pub fn from_vector(v: Vector) -> Vector3<f64> {
        Vector3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z))
    }

    /// A pose for rapier.
    pub fn pose(p: &Isometry3<f64>) -> Pose {
        let q = p.rotation.quaternion();
        Pose::from_parts(
            vector(&p.translation.vector),
            Rotation::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32).normalize(),
        )
    }

    /// A rapier pose as nalgebra's.
    pub fn from_pose(p: &Pose) -> Isometry3<f64> {
        let r = p.rotation;
        Isometry3::from_parts(
            Translation3::from(from_vector(p.translation)),
            UnitQuaternion::new_normalize(Quaternion::new(
                f64::from(r.w),
                f64::from(r.x),
                f64::from(r.y),
                f64::from(r.z),
            )),
        )
    }
}

/// The user data of robot `i`'s link colliders (a scene body's is its scene index).
fn link_tag(i: usize) -> u128 {
    u128::MAX - i as u128
}

/// A robot's links in the world.
struct Robot {
    body: Arc<RobotBody>,
    /// Height of the root above the floor (a pedestal), m.
    height: f64,
    /// The kinematic body of each link that has shapes ([`ferrobot_kinematics::LinkTree::links`]
    /// order).
    links: Vec<Option<RigidBodyHandle>>,
    grasp: Option<Grasp>,
}

/// An object held by the gripper.
#[derive(Debug, Clone, Copy)]
struct Grasp {
    /// Scene index of the object.
    object: usize,
    joint: ImpulseJointHandle,
    /// Gripper servo angle at the contact, rad.
    at: f64,
    /// The obstacle this grasp put on the servo.
    obstacle: (f64, bool),
}

/// The physics world (see the module documentation).
pub struct World {
    pw: PhysicsWorld,
    time_us: u64,
    /// The rigid body of every scene body ([`Scene::bodies`] order).
    bodies: Vec<RigidBodyHandle>,
    /// Their ids.
    ids: Vec<String>,
    /// The robots, in the order they were placed (`None`: a robot without a body); the
    /// single-robot queries ([`World::robot_contacts`], [`World::held`], the contact watch)
    /// are of the first.
    robots: Vec<Option<Robot>>,
    /// Height of a robot's root above the floor (a pedestal), m: the scene's.
    robot_height: f64,
    /// Physics steps taken.
    steps: u64,
    /// Steps in which rapier ran (the others found the world at rest).
    active_steps: u64,
    /// The links whose contacts are recorded at every step, if any.
    watch: Option<Watch>,
}

impl World {
    /// The world of `scene` with `robot`'s links (`None`: no robot body) at the base pose
    /// `base` (x, y in m, heading in rad) and the servos' angles `theta` (rad, chain order).
    /// Fails when a scene body overlaps a robot link at the start, naming both.
    pub fn new(
        scene: &Scene,
        robot: Option<&Arc<RobotBody>>,
        base: BasePose,
        theta: &[f64],
    ) -> Result<World, SceneError> {
        let mut w = World::bodies_of(scene);
        w.add_robot(scene, robot, base, theta)?;
        // Every movable body starts awake (rapier may sleep it once it rests).
        w.wake_all();
        Ok(w)
    }

    /// The world of `scene`'s bodies, no robot yet ([`World::add_robot`] places them). Every
    /// movable body starts awake (rapier may sleep it once it rests).
    pub fn of_scene(scene: &Scene) -> World {
        let mut w = World::bodies_of(scene);
        // Place the colliders with their bodies and fill the broad phase, so that the first
        // queries see the scene.
        w.pw.detect_collisions(&(), &());
        w.wake_all();
        w
    }

    /// The scene's bodies in a new physics world.
    fn bodies_of(scene: &Scene) -> World {
        let mut pw = PhysicsWorld::new();
        pw.gravity = Vector::new(0.0, 0.0, -GRAVITY as f32);
        pw.integration_parameters.dt = STEP_US as f32 * 1e-6;
        pw.integration_parameters.length_unit = LENGTH_UNIT;
        let mut bodies = Vec::with_capacity(scene.bodies.len());
        for (i, b) in scene.bodies.iter().enumerate() {
            let rb = if b.fixed {
                RigidBodyBuilder::fixed()
            } else {
                RigidBodyBuilder::dynamic()
            }
            .pose(convert::pose(&b.pose))
            .user_data(i as u128);
            let h = pw.insert_body(rb);
            if let Some(c) = collider(b) {
                let mut c = c.friction(b.friction as f32).restitution(0.0);
                if !b.fixed {
                    c = c.mass(b.mass as f32);
                }
                pw.insert_collider(c.user_data(i as u128), Some(h));
            }
            bodies.push(h);
        }
        World {
            pw,
            time_us: 0,
            bodies,
            ids: scene.bodies.iter().map(|b| b.id.clone()).collect(),
            robots: Vec::new(),
            robot_height: scene.robot_height,
            steps: 0,
            active_steps: 0,
            watch: None,
        }
    }

    /// Place another robot: `robot`'s links (`None`: a robot without a body, which takes an
    /// index and touches nothing) at the base pose `base` (x, y in m, heading in rad) and the
    /// servos' angles `theta` (rad, chain order). Its index (the order of
    /// [`World::step_robots`]). Fails, and places nothing, when a scene body or another
    /// robot's link overlaps one of its links, naming both.
    pub fn add_robot(
        &mut self,
        scene: &Scene,
        robot: Option<&Arc<RobotBody>>,
        base: BasePose,
        theta: &[f64],
    ) -> Result<usize, SceneError> {
        let index = self.robots.len();
        let robot = robot.map(|body| {
            let mut links = Vec::new();
            for shapes in &body.shapes {
                let colliders: Vec<ColliderBuilder> =
                    shapes.iter().filter_map(link_collider).collect();
                if colliders.is_empty() {
                    links.push(None);
                    continue;
                }
                let h = self
                    .pw
                    .insert_body(RigidBodyBuilder::kinematic_position_based());
                for c in colliders {
                    self.pw
                        .insert_collider(c.user_data(link_tag(index)), Some(h));
                }
                links.push(Some(h));
            }
            Robot {
                body: body.clone(),
                height: self.robot_height,
                links,
                grasp: None,
            }
        });
        self.robots.push(robot);
        let targets = self.link_targets(index, base, theta);
        self.teleport(&targets);
        // Place the colliders with their bodies and fill the broad phase, so that the first
        // queries see the scene.
        self.pw.detect_collisions(&(), &());
        if let Err(e) = self.check_overlap(index, scene) {
            if let Some(Some(r)) = self.robots.pop() {
                for h in r.links.into_iter().flatten() {
                    self.pw.remove_body_with_colliders(h, true);
                }
                self.pw.detect_collisions(&(), &());
            }
            return Err(e);
        }
        Ok(index)
    }

    /// The robots placed ([`World::add_robot`]), with or without a body.
    pub fn robots(&self) -> usize {
        self.robots.len()
    }

    /// Robot `i`, when it has a body.
    fn robot(&self, i: usize) -> Option<&Robot> {
        self.robots.get(i).and_then(Option::as_ref)
    }

    /// Wake every movable body: the engine moves each again until it has been at rest long
    /// enough to sleep (rapier's 2 s). A body asleep does not move at all; a world kept awake
    /// (by a moving robot, a rolling object) shows what the engine does to a resting one.
    pub fn wake_all(&mut self) {
        for h in &self.bodies {
            if let Some(b) = self.pw.bodies.get_mut(*h) {
                if b.is_dynamic() {
                    b.wake_up(true);
                }
            }
        }
    }

    /// Simulated time of the world, µs.
    pub fn time_us(&self) -> u64 {
        self.time_us
    }

    /// When the next step is due, µs.
    pub fn next_step(&self) -> u64 {
        self.time_us + STEP_US
    }

    /// Physics steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Steps in which the physics engine ran (the others found the world at rest).
    pub fn active_steps(&self) -> u64 {
        self.active_steps
    }

    /// Take the step that ends at [`World::next_step`] with the only robot
    /// ([`World::step_robots`]).
    pub fn step(&mut self, base: BasePose, chain: &mut ServoChain) {
        self.step_robots(&mut [(base, chain)]);
    }

    /// Take the step that ends at [`World::next_step`]: move each robot's links to its
    /// plants' state there (`robots`, in [`World::add_robot`] order: the base's true pose and
    /// the chain, whose servos' true angles place the links), step the physics, and let each
    /// gripper grasp or release (which sets or clears its servo's obstacle in the chain). A
    /// world at rest (every movable body asleep, no link within [`NEAR`] of one) is not
    /// stepped: only the links move, and they are put in place. Robots beyond `robots` stay
    /// where they are.
    pub fn step_robots(&mut self, robots: &mut [(BasePose, &mut ServoChain)]) {
        let thetas: Vec<Vec<f64>> = robots
            .iter()
            .map(|(_, c)| c.servos.iter().map(|s| s.theta).collect())
            .collect();
        let mut targets = Vec::new();
        for (i, ((base, _), theta)) in robots.iter().zip(&thetas).enumerate() {
            targets.extend(self.link_targets(i, *base, theta));
        }
        if self.busy(&targets) {
            self.drive(&targets);
            self.pw.step();
            self.active_steps += 1;
        } else {
            // Every movable body asleep and no link near one: stepping would only move the
            // links.
            self.teleport(&targets);
        }
        self.time_us += STEP_US;
        self.steps += 1;
        for (i, ((_, chain), theta)) in robots.iter_mut().zip(&thetas).enumerate() {
            self.grip(i, theta, chain);
        }
        if self.watch.is_some() {
            self.record_contacts();
        }
    }

    /// Pose of the colliders of robot link `link` ([`ferrobot_kinematics::LinkTree::links`]
    /// index) in the world now.
    pub fn link_collider_poses(&self, link: usize) -> Vec<Isometry3<f64>> {
        let Some(h) = self
            .robot(0)
            .and_then(|r| r.links.get(link).copied().flatten())
        else {
            return Vec::new();
        };
        self.pw.bodies.get(h).map_or(Vec::new(), |b| {
            b.colliders()
                .iter()
                .filter_map(|c| self.pw.colliders.get(*c))
                .map(|c| convert::from_pose(c.position()))
                .collect()
        })
    }

    /// The scene body the (first robot's) gripper holds ([`Scene::bodies`] index), if any.
    pub fn held(&self) -> Option<usize> {
        self.held_by(0)
    }

    /// The scene body robot `i`'s gripper holds ([`Scene::bodies`] index), if any.
    pub fn held_by(&self, i: usize) -> Option<usize> {
        self.robot(i)?.grasp.map(|g| g.object)
    }

    /// The scene bodies' ids ([`Scene::bodies`] order).
    pub fn body_ids(&self) -> &[String] {
        &self.ids
    }

    /// Pose of every scene body now ([`Scene::bodies`] order).
    pub fn body_poses(&self) -> Vec<Isometry3<f64>> {
        self.bodies
            .iter()
            .map(|h| {
                self.pw
                    .bodies
                    .get(*h)
                    .map_or(Isometry3::identity(), |b| convert::from_pose(b.position()))
            })
            .collect()
    }
}
