//! The physics world: the scene's bodies as rigid bodies in rapier3d, stepped in lockstep
//! with the plants, and the robot's links as colliders the plants drive.
//!
//! * Static scene bodies ([`Body::fixed`]: the floor, walls, furniture) are fixed rigid
//!   bodies; movable ones are dynamic rigid bodies with their mass (inertia from the shape at
//!   uniform density) and friction. Primitives map to rapier's shapes (cylinders and capsules
//!   along z as in the scene; a movable capsule is a chain of balls, [`BALL_SPACING`], up to
//!   [`MAX_BALLS`]: rapier's own rolls away by itself); a movable mesh is its convex hull (rapier's dynamic bodies
//!   need convex or decomposed shapes; the bundled objects are convex or nearly so), touching
//!   with whole faces ([`crate::hull::Hull`]: parry alone lets a many-sided face, a mug's
//!   base, touch at four neighbouring corners, and the mug walks), a static
//!   mesh its exact triangle mesh. A mesh rapier cannot build (degenerate: no hull, no
//!   triangles) gets no collider: it is seen by the camera but not touched.
//! * The robot's links with collision shapes are kinematic (position-based) bodies, moved at
//!   every step to the poses the plants give: the base's ground truth and the servos' true
//!   angles through [`RobotBody::link_poses`]. They push movable objects and are never pushed
//!   (rapier does not wake a sleeping body that a kinematic one runs into: the world wakes
//!   what a moving link touches). Kinematic bodies do not collide with fixed ones in rapier;
//!   the base's contact with fixed geometry is the base plant's ([`Surroundings`]: it stalls
//!   against walls and furniture, and its bumper reports contacts with anything, fixed or
//!   movable, by bearing). Not modelled: the arm meeting fixed geometry (it passes through a
//!   table; no servo is blocked by it) and the robot's links meeting each other.
//! * Contacts of the robot's links with any scene body, fixed or movable, the floor
//!   included, are *observed*, not simulated, by exact shape queries:
//!   [`World::robot_contacts`] now, and a record over a motion while watched
//!   ([`World::watch_robot_contacts`], [`World::take_robot_contacts`]). A link passing
//!   through a table is seen there, though nothing stops it. The queries change nothing in
//!   the world.
//! * The gripper: when both fingers touch the same movable object (within [`TOUCH`]) from
//!   either side (its centre between them: a closed pair pushing an object with one finger's
//!   outer face does not grasp it), the gripper servo is blocked at its angle of that instant (the servo's obstacle), so its
//!   position stops and its current rises as a real Dynamixel's do on an object, and the
//!   firmware's gripper state machine reports holding; the fingers' colliders stay at the
//!   contact angle meanwhile (the object is rigid: the servo's contact spring is the
//!   compliance). The object is carried by a **grasp constraint**: a fixed joint between the
//!   palm and the object, made at that instant and released when the servo opens
//!   [`RELEASE`] beyond the contact angle. Why not friction: two kinematic fingers squeezing
//!   a body are an over-constrained, infinitely stiff vice in rapier; the normal force (and so
//!   the friction that would carry the object) is set by the solver's penetration correction,
//!   not by the servo's torque, and depends on step size and iteration count. The constraint
//!   is exact and deterministic; what it does not model is an object slipping out of a weak
//!   grasp.
//!
//! Time: a fixed step of [`STEP_US`] (1 ms), on the base plant's 1 ms grid: the base and the
//! world see each other every base step, the base at its top speed (0.7 m/s) moves 0.7 mm and
//! a closing finger a few hundredths of a millimetre per step (inside the touch tolerance),
//! and 2-8 cm objects stay stable with rapier's default four solver iterations. An empty
//! scene has no world at all; a world at rest (every movable body asleep, no link within
//! [`NEAR`] of one) is not stepped: the links are put in place, nothing else would change.
//!
//! Determinism: rapier is deterministic for the same inputs on one platform and build
//! (single-threaded, no `parallel` feature), so a run is bit-identical for the same seed;
//! `enhanced-determinism` (cross-platform identity, at a cost) is not needed.
//!
//! Units SI, world frame right-handed with z up; quaternions `[x, y, z, w]`. rapier works in
//! `f32` with glam math; [`convert`] is the one place where nalgebra's `f64` types meet it.

use std::collections::BTreeMap;
use std::sync::Arc;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::parry::bounding_volume::BoundingVolume;
use rapier3d::prelude::*;

use crate::body::RobotBody;
use crate::chain::ServoChain;
use crate::diff_drive::{Pose as BasePose, Surroundings, Touch};
use crate::scene::{Body, Scene, SceneError, Shape};

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

/// A robot link touching or penetrating a scene body now ([`World::robot_contacts`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotContact {
    /// The link's name (URDF).
    pub link: String,
    /// The scene body's id.
    pub body: String,
    /// Penetration depth, m, ≥ 0: the deepest over the link's and the body's shapes; 0 when
    /// they are within [`CONTACT`] of each other without penetrating.
    pub depth: f64,
}

/// A robot link and a scene body that touched while watched
/// ([`World::watch_robot_contacts`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotContactRecord {
    /// The link's name (URDF).
    pub link: String,
    /// The scene body's id.
    pub body: String,
    /// World time of the first check in which they touched, µs.
    pub first_us: u64,
    /// World time of the last check in which they touched, µs.
    pub last_us: u64,
    /// Checks (world steps, and the one when watching starts) in which they touched.
    pub steps: u64,
    /// Deepest penetration seen, m, ≥ 0 (see [`RobotContact::depth`]).
    pub max_depth: f64,
}

/// A contact watch that cannot be set up.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ContactError {
    /// The robot has no link of that name.
    #[error("the robot has no link {link:?} (its links: {known})")]
    UnknownLink {
        /// The name asked for.
        link: String,
        /// The robot's links, comma-separated (empty without a robot body).
        known: String,
    },
}

/// What a watch has seen of one (link, body) pair.
#[derive(Debug, Clone, Copy)]
struct Seen {
    first_us: u64,
    last_us: u64,
    steps: u64,
    max_depth: f64,
}

/// The links watched for contacts and what they touched, by (link index, scene index).
#[derive(Debug, Clone, Default)]
struct Watch {
    links: Vec<usize>,
    seen: BTreeMap<(usize, usize), Seen>,
}

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

/// The robot's links in the world.
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
    robot: Option<Robot>,
    /// Physics steps taken.
    steps: u64,
    /// Steps in which rapier ran (the others found the world at rest).
    active_steps: u64,
    /// The links whose contacts are recorded at every step, if any.
    watch: Option<Watch>,
}

fn collider(b: &Body) -> Option<ColliderBuilder> {
    let f = |v: f64| v as f32;
    let upright = |c: ColliderBuilder| {
        // rapier's cylinders stand along y; the scene's along z.
        c.position(Pose::from_rotation(
            rapier3d::math::Rotation::from_rotation_x(std::f32::consts::FRAC_PI_2),
        ))
    };
    let c = match &b.shape {
        Shape::Box(s) => ColliderBuilder::cuboid(f(s[0] / 2.0), f(s[1] / 2.0), f(s[2] / 2.0)),
        Shape::Cylinder { radius, length } => {
            upright(ColliderBuilder::cylinder(f(length / 2.0), f(*radius)))
        }
        Shape::Capsule { radius, length }
            if !b.fixed && balls(f(*radius), f(*length)) <= MAX_BALLS =>
        {
            ColliderBuilder::compound(ball_chain(f(*radius), f(*length)))
        }
        Shape::Capsule { radius, length } => {
            ColliderBuilder::capsule_z(f(length / 2.0), f(*radius))
        }
        Shape::Sphere(r) => ColliderBuilder::ball(f(*r)),
        Shape::Mesh { mesh, .. } => {
            let v: Vec<Vector> = mesh.vertices.iter().map(convert::point).collect();
            if b.fixed {
                ColliderBuilder::trimesh(v, mesh.triangles.clone()).ok()?
            } else {
                ColliderBuilder::new(SharedShape::new(crate::hull::Hull::new(&v)?))
            }
        }
    };
    Some(c)
}

/// A movable capsule (along z, `length` between its end centres, m) as balls of its
/// `radius` along its axis, at most [`BALL_SPACING`] of the radius apart (the side's ripples
/// are under 1.4 % of the radius). Why: rapier's capsule lying on a box, once awake, rolls on by
/// itself and gathers speed (0.1-4 m in 20 s kept awake), while balls roll true on it.
fn ball_chain(radius: f32, length: f32) -> Vec<(Pose, SharedShape)> {
    let n = balls(radius, length) - 1;
    (0..=n)
        .map(|i| {
            let z = -length / 2.0 + length * i as f32 / n as f32;
            (
                Pose::from_translation(Vector::new(0.0, 0.0, z)),
                SharedShape::ball(radius),
            )
        })
        .collect()
}

/// How many balls [`ball_chain`] makes of a capsule (saturating for absurd ones).
fn balls(radius: f32, length: f32) -> usize {
    let gaps = (length / (BALL_SPACING * radius)).ceil();
    if gaps.is_finite() && gaps < MAX_BALLS as f32 {
        gaps.max(1.0) as usize + 1
    } else {
        usize::MAX
    }
}

fn link_collider(s: &crate::body::LinkShape) -> Option<ColliderBuilder> {
    let body = Body {
        id: String::new(),
        shape: s.shape.clone(),
        pose: Isometry3::identity(),
        mass: 0.0,
        friction: 0.8,
        colour: [0.0; 3],
        texture: None,
        fixed: false,
    };
    let c = collider(&body)?;
    // The shape's own orientation (cylinders upright) after the link's origin.
    let own = c.position;
    Some(c.position(convert::pose(&s.origin) * own).friction(0.8))
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
        let robot = match robot {
            Some(body) => {
                let mut links = Vec::new();
                for shapes in &body.shapes {
                    let colliders: Vec<ColliderBuilder> =
                        shapes.iter().filter_map(link_collider).collect();
                    if colliders.is_empty() {
                        links.push(None);
                        continue;
                    }
                    let h = pw.insert_body(RigidBodyBuilder::kinematic_position_based());
                    for c in colliders {
                        pw.insert_collider(c.user_data(u128::MAX), Some(h));
                    }
                    links.push(Some(h));
                }
                Some(Robot {
                    body: body.clone(),
                    height: scene.robot_height,
                    links,
                    grasp: None,
                })
            }
            None => None,
        };
        let mut w = World {
            pw,
            time_us: 0,
            bodies,
            ids: scene.bodies.iter().map(|b| b.id.clone()).collect(),
            robot,
            steps: 0,
            active_steps: 0,
            watch: None,
        };
        let targets = w.link_targets(base, theta);
        w.teleport(&targets);
        // Place the colliders with their bodies and fill the broad phase, so that the first
        // queries see the scene.
        w.pw.detect_collisions(&(), &());
        w.check_overlap(scene)?;
        // Every movable body starts awake (rapier may sleep it once it rests).
        w.wake_all();
        Ok(w)
    }

    /// Where the robot's link bodies belong for the plants' state: each link body with its
    /// pose (the fingers held at the contact angle while the gripper holds an object).
    fn link_targets(&self, base: BasePose, theta: &[f64]) -> Vec<(RigidBodyHandle, Pose)> {
        let Some(r) = &self.robot else {
            return Vec::new();
        };
        let mut theta = theta.to_vec();
        if let (Some(g), Some(hand)) = (&r.grasp, r.body.hand()) {
            if let Some(t) = theta.get_mut(hand.servo) {
                *t = if hand.closed < hand.open {
                    t.max(g.at)
                } else {
                    t.min(g.at)
                };
            }
        }
        let root = RobotBody::root_pose(base, r.height);
        let q = r.body.joint_values(&theta);
        let poses = r.body.link_poses(&root, &q);
        r.links
            .iter()
            .zip(&poses)
            .filter_map(|(h, p)| h.map(|h| (h, convert::pose(p))))
            .collect()
    }

    /// Put the link bodies at `targets` now, outside a step.
    fn teleport(&mut self, targets: &[(RigidBodyHandle, Pose)]) {
        for (h, p) in targets {
            if let Some(rb) = self.pw.bodies.get_mut(*h) {
                rb.set_position(*p, false);
            }
        }
    }

    /// Send the link bodies to `targets` in the next step, waking what the moving ones touch
    /// (rapier does not wake a sleeping body that a kinematic one runs into).
    fn drive(&mut self, targets: &[(RigidBodyHandle, Pose)]) {
        let mut moving = Vec::new();
        for (h, p) in targets {
            if let Some(rb) = self.pw.bodies.get_mut(*h) {
                if rb.position() != p {
                    moving.extend(rb.colliders().iter().copied());
                }
                rb.set_next_kinematic_position(*p);
            }
        }
        let mut wake = Vec::new();
        for &c in &moving {
            for pair in self.pw.narrow_phase.contact_pairs_with(c) {
                let other = if pair.collider1 == c {
                    pair.collider2
                } else {
                    pair.collider1
                };
                if let Some(b) = self.pw.colliders.get(other).and_then(|o| o.parent()) {
                    wake.push(b);
                }
            }
        }
        for b in wake {
            if let Some(rb) = self.pw.bodies.get_mut(b) {
                if rb.is_dynamic() && rb.is_sleeping() {
                    rb.wake_up(true);
                }
            }
        }
    }

    /// Whether a link moving to `targets` comes within [`NEAR`] of a movable body, or any
    /// movable body is awake: the engine has something to do.
    fn busy(&self, targets: &[(RigidBodyHandle, Pose)]) -> bool {
        let bodies = &self.pw.bodies;
        let movable: Vec<&RigidBody> = self
            .bodies
            .iter()
            .filter_map(|h| bodies.get(*h))
            .filter(|b| b.is_dynamic())
            .collect();
        if movable.iter().any(|b| !b.is_sleeping()) {
            return true;
        }
        let mut swept = Vec::new();
        for (h, p) in targets {
            let Some(rb) = bodies.get(*h) else { continue };
            if rb.position() == p {
                continue;
            }
            for ch in rb.colliders() {
                let Some(c) = self.pw.colliders.get(*ch) else {
                    continue;
                };
                let local = c.position_wrt_parent().copied().unwrap_or(Pose::IDENTITY);
                let to = c.shape().compute_aabb(&(*p * local));
                swept.push(c.compute_aabb().merged(&to).loosened(NEAR as f32));
            }
        }
        if swept.is_empty() {
            return false;
        }
        movable.iter().any(|b| {
            b.colliders().iter().any(|ch| {
                self.pw.colliders.get(*ch).is_some_and(|c| {
                    let a = c.compute_aabb();
                    swept.iter().any(|s| s.intersects(&a))
                })
            })
        })
    }

    fn check_overlap(&self, scene: &Scene) -> Result<(), SceneError> {
        let Some(r) = &self.robot else { return Ok(()) };
        let names: Vec<&str> = r.body.tree.links().collect();
        for (i, h) in self.bodies.iter().enumerate() {
            let Some(rb) = self.pw.bodies.get(*h) else {
                continue;
            };
            for ch in rb.colliders() {
                let Some(c) = self.pw.colliders.get(*ch) else {
                    continue;
                };
                let aabb = c.compute_aabb();
                for (li, lh) in r.links.iter().enumerate() {
                    let Some(lb) = lh.and_then(|h| self.pw.bodies.get(h)) else {
                        continue;
                    };
                    for lch in lb.colliders() {
                        let Some(lc) = self.pw.colliders.get(*lch) else {
                            continue;
                        };
                        if !aabb.intersects(&lc.compute_aabb()) {
                            continue;
                        }
                        let hit = rapier3d::parry::query::contact(
                            c.position(),
                            c.shape(),
                            lc.position(),
                            lc.shape(),
                            0.0,
                        );
                        if let Ok(Some(k)) = hit {
                            if f64::from(k.dist) < -OVERLAP {
                                return Err(SceneError::Overlap {
                                    object: scene
                                        .bodies
                                        .get(i)
                                        .map(|b| b.id.clone())
                                        .unwrap_or_default(),
                                    link: names.get(li).copied().unwrap_or("?").to_string(),
                                });
                            }
                        }
                    }
                }
            }
        }
        Ok(())
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

    /// Take the step that ends at [`World::next_step`]: move the robot's links to the plants'
    /// state there (`base`: the base's true pose; the chain: the servos' true angles), step
    /// the physics, and let the gripper grasp or release (which sets or clears the gripper
    /// servo's obstacle in `chain`). A world at rest (every movable body asleep, no link
    /// within [`NEAR`] of one) is not stepped: only the links move, and they are put in place.
    pub fn step(&mut self, base: BasePose, chain: &mut ServoChain) {
        let theta: Vec<f64> = chain.servos.iter().map(|s| s.theta).collect();
        let targets = self.link_targets(base, &theta);
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
        self.grip(&theta, chain);
        if self.watch.is_some() {
            self.record_contacts();
        }
    }

    /// Grasp when both fingers touch one movable object; release when the servo has opened.
    fn grip(&mut self, theta: &[f64], chain: &mut ServoChain) {
        let Some(r) = &self.robot else { return };
        let Some(hand) = r.body.hand().cloned() else {
            return;
        };
        let Some(&angle) = theta.get(hand.servo) else {
            return;
        };
        // Closing moves the servo angle towards the closed stop.
        let closing_down = hand.closed < hand.open;
        if let Some(g) = r.grasp {
            let opened = if closing_down {
                angle - g.at
            } else {
                g.at - angle
            };
            if opened > RELEASE {
                self.pw.remove_impulse_joint(g.joint);
                if let Some(s) = chain.servos.get_mut(hand.servo) {
                    if s.obstacle == Some(g.obstacle) {
                        s.obstacle = None;
                    }
                }
                if let Some(rb) = self
                    .bodies
                    .get(g.object)
                    .and_then(|h| self.pw.bodies.get_mut(*h))
                {
                    rb.wake_up(true);
                }
                if let Some(r) = &mut self.robot {
                    r.grasp = None;
                }
            }
            return;
        }
        let finger_colliders: Vec<Vec<ColliderHandle>> = hand
            .fingers
            .iter()
            .map(|&f| {
                r.links
                    .get(f)
                    .copied()
                    .flatten()
                    .and_then(|h| self.pw.bodies.get(h))
                    .map(|b| b.colliders().to_vec())
                    .unwrap_or_default()
            })
            .collect();
        if finger_colliders.len() < 2 || finger_colliders.iter().any(Vec::is_empty) {
            return;
        }
        // Movable objects near the first finger (by the broad phase's boxes, with a margin for
        // their motion in the last step), then whether every finger touches one.
        let Some(first) = finger_colliders
            .first()
            .and_then(|c| c.first())
            .and_then(|h| self.pw.colliders.get(*h))
        else {
            return;
        };
        let near = first.compute_aabb().loosened(0.01);
        let candidates: Vec<ColliderHandle> = self
            .pw
            .intersect_aabb_conservative(near, QueryFilter::only_dynamic())
            .map(|(h, _)| h)
            .collect();
        // An object is grasped only from both sides: its centre lies between the first two
        // fingers along the line joining them (not beside a closed pair that pushes it).
        let centre = |f: &Vec<ColliderHandle>| {
            f.first()
                .and_then(|h| self.pw.colliders.get(*h))
                .map(|c| c.position().translation)
        };
        let (Some(a), Some(b)) = (
            finger_colliders.first().and_then(centre),
            finger_colliders.get(1).and_then(centre),
        ) else {
            return;
        };
        let between = |o: Vector| {
            let ab = b - a;
            let t = (o - a).dot(ab);
            t > 0.0 && t < ab.length_squared()
        };
        for ch in candidates {
            let Some(c) = self.pw.colliders.get(ch) else {
                continue;
            };
            let object = c.user_data as usize;
            if object >= self.bodies.len() {
                continue;
            }
            let touches = |fc: &Vec<ColliderHandle>| {
                fc.iter().any(|h| {
                    self.pw.colliders.get(*h).is_some_and(|f| {
                        rapier3d::parry::query::distance(
                            f.position(),
                            f.shape(),
                            c.position(),
                            c.shape(),
                        )
                        .is_ok_and(|d| f64::from(d.distance) <= TOUCH)
                    })
                })
            };
            if !finger_colliders.iter().all(touches) || !between(c.position().translation) {
                continue;
            }
            let (Some(palm), Some(oh)) = (
                r.links.get(hand.palm).copied().flatten(),
                self.bodies.get(object).copied(),
            ) else {
                continue;
            };
            let (Some(pb), Some(ob)) = (self.pw.bodies.get(palm), self.pw.bodies.get(oh)) else {
                continue;
            };
            let frame1 = pb.position().inv_mul(ob.position());
            let joint = FixedJointBuilder::new()
                .local_frame1(frame1)
                .local_frame2(Pose::IDENTITY)
                .contacts_enabled(false);
            let joint = self.pw.insert_impulse_joint(palm, oh, joint);
            if let Some(ob) = self.pw.bodies.get_mut(oh) {
                ob.wake_up(true);
            }
            let obstacle = (angle, closing_down);
            if let Some(s) = chain.servos.get_mut(hand.servo) {
                s.obstacle = Some(obstacle);
            }
            if let Some(r) = &mut self.robot {
                r.grasp = Some(Grasp {
                    object,
                    joint,
                    at: angle,
                    obstacle,
                });
            }
            return;
        }
    }

    /// Pose of the colliders of robot link `link` ([`ferrobot_kinematics::LinkTree::links`]
    /// index) in the world now.
    pub fn link_collider_poses(&self, link: usize) -> Vec<Isometry3<f64>> {
        let Some(h) = self
            .robot
            .as_ref()
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

    /// The scene body the gripper holds ([`Scene::bodies`] index), if any.
    pub fn held(&self) -> Option<usize> {
        self.robot.as_ref()?.grasp.map(|g| g.object)
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

    /// Names (URDF) of the robot's links that have collision shapes, in
    /// [`ferrobot_kinematics::LinkTree::links`] order; empty without a robot body.
    pub fn robot_links(&self) -> Vec<String> {
        let Some(r) = &self.robot else {
            return Vec::new();
        };
        r.body
            .tree
            .links()
            .zip(&r.links)
            .filter(|(_, h)| h.is_some())
            .map(|(n, _)| n.to_string())
            .collect()
    }

    /// Every (robot link, scene body) pair in contact now (within [`CONTACT`], penetrating
    /// included), for every link with shapes against every scene body, fixed or movable, the
    /// floor and walls included; in link order ([`ferrobot_kinematics::LinkTree::links`]),
    /// then scene order. Exact shapes (a movable mesh's convex hull, as the engine has it; a
    /// link entirely inside a static mesh, which has no inside, is not seen). The object the
    /// gripper holds is in contact with its fingers. Empty without a robot body.
    pub fn robot_contacts(&self) -> Vec<RobotContact> {
        let Some(r) = &self.robot else {
            return Vec::new();
        };
        let links: Vec<usize> = (0..r.links.len()).collect();
        self.contacts_of(&links)
            .into_iter()
            .map(|(l, b, depth)| RobotContact {
                link: self.link_name(l),
                body: self.ids.get(b).cloned().unwrap_or_default(),
                depth,
            })
            .collect()
    }

    /// Record, from now on and at every step, which of the robot's `links` (URDF names)
    /// touch which scene bodies (as [`World::robot_contacts`] sees them), with the first and
    /// last time, the number of steps and the deepest penetration of each pair; read with
    /// [`World::take_robot_contacts`]. Checks once now, too. Replaces an earlier watch and
    /// drops what it recorded. Checked once per step ([`STEP_US`]: a link moving at 1 m/s
    /// advances 1 mm between checks). Costs nothing while nothing is watched; a watch costs
    /// one bounding-box test per scene body and link shape per step, and an exact query per
    /// pair whose boxes meet (all 18 of the LoCoBot's links in the tabletop: about 4 µs a
    /// step). Changes nothing in the physics. Links without shapes are accepted and never
    /// touch anything.
    ///
    /// # Errors
    ///
    /// [`ContactError::UnknownLink`] when the robot has no link of a given name (nothing is
    /// watched then).
    pub fn watch_robot_contacts<S: AsRef<str>>(&mut self, links: &[S]) -> Result<(), ContactError> {
        let (names, indices) = match &self.robot {
            Some(r) => (
                r.body.tree.links().collect::<Vec<_>>().join(", "),
                links
                    .iter()
                    .map(|l| r.body.tree.link_index(l.as_ref()).ok_or(l.as_ref()))
                    .collect::<Result<Vec<usize>, &str>>(),
            ),
            None => (
                String::new(),
                links.first().map_or(Ok(Vec::new()), |l| Err(l.as_ref())),
            ),
        };
        let mut indices = indices.map_err(|l| ContactError::UnknownLink {
            link: l.to_string(),
            known: names,
        })?;
        indices.sort_unstable();
        indices.dedup();
        self.watch = Some(Watch {
            links: indices,
            seen: BTreeMap::new(),
        });
        self.record_contacts();
        Ok(())
    }

    /// What the watch has recorded since it started or was last taken, and forget it (the
    /// watch goes on): one record per (link, body) pair that touched, ordered by the time
    /// they first touched, then link and scene order. Empty when nothing is watched.
    pub fn take_robot_contacts(&mut self) -> Vec<RobotContactRecord> {
        let Some(w) = self.watch.as_mut() else {
            return Vec::new();
        };
        let seen = std::mem::take(&mut w.seen);
        let mut out: Vec<(u64, RobotContactRecord)> = seen
            .into_iter()
            .map(|((l, b), s)| {
                (
                    s.first_us,
                    RobotContactRecord {
                        link: self.link_name(l),
                        body: self.ids.get(b).cloned().unwrap_or_default(),
                        first_us: s.first_us,
                        last_us: s.last_us,
                        steps: s.steps,
                        max_depth: s.max_depth,
                    },
                )
            })
            .collect();
        // Stable: pairs that first touched together stay in link, then scene order.
        out.sort_by_key(|(t, _)| *t);
        out.into_iter().map(|(_, r)| r).collect()
    }

    /// Stop watching; what was recorded and not yet taken (as
    /// [`World::take_robot_contacts`]).
    pub fn unwatch_robot_contacts(&mut self) -> Vec<RobotContactRecord> {
        let out = self.take_robot_contacts();
        self.watch = None;
        out
    }

    /// Name (URDF) of link `i` ([`ferrobot_kinematics::LinkTree::links`] index).
    fn link_name(&self, i: usize) -> String {
        self.robot
            .as_ref()
            .and_then(|r| r.body.tree.links().nth(i))
            .unwrap_or("?")
            .to_string()
    }

    /// Add the watched links' contacts now to the watch's record.
    fn record_contacts(&mut self) {
        let Some(mut w) = self.watch.take() else {
            return;
        };
        let now = self.time_us;
        for (l, b, depth) in self.contacts_of(&w.links) {
            w.seen
                .entry((l, b))
                .and_modify(|s| {
                    s.last_us = now;
                    s.steps += 1;
                    s.max_depth = s.max_depth.max(depth);
                })
                .or_insert(Seen {
                    first_us: now,
                    last_us: now,
                    steps: 1,
                    max_depth: depth,
                });
        }
        self.watch = Some(w);
    }

    /// The contacts of robot links `links` ([`ferrobot_kinematics::LinkTree::links`]
    /// indices, ascending) now: (link, scene index, penetration depth in m ≥ 0), in link then
    /// scene order. Poses from the bodies (a link put in place while the world rests has
    /// moved its body, not yet its colliders).
    fn contacts_of(&self, links: &[usize]) -> Vec<(usize, usize, f64)> {
        let Some(r) = &self.robot else {
            return Vec::new();
        };
        let placed = |rb: &RigidBody, c: &Collider| match c.position_wrt_parent() {
            Some(local) => *rb.position() * *local,
            None => *c.position(),
        };
        // The links' shapes where they are, and the box around them all.
        let mut shapes: Vec<(
            usize,
            Pose,
            &Collider,
            rapier3d::parry::bounding_volume::Aabb,
        )> = Vec::new();
        for &l in links {
            let Some(lb) = r
                .links
                .get(l)
                .copied()
                .flatten()
                .and_then(|h| self.pw.bodies.get(h))
            else {
                continue;
            };
            for ch in lb.colliders() {
                let Some(c) = self.pw.colliders.get(*ch) else {
                    continue;
                };
                let pose = placed(lb, c);
                let aabb = c.shape().compute_aabb(&pose).loosened(CONTACT as f32);
                shapes.push((l, pose, c, aabb));
            }
        }
        let Some(all) = shapes.iter().map(|s| s.3).reduce(|a, b| a.merged(&b)) else {
            return Vec::new();
        };
        let mut found: BTreeMap<(usize, usize), f64> = BTreeMap::new();
        for (i, h) in self.bodies.iter().enumerate() {
            let Some(rb) = self.pw.bodies.get(*h) else {
                continue;
            };
            for ch in rb.colliders() {
                let Some(c) = self.pw.colliders.get(*ch) else {
                    continue;
                };
                let pose = placed(rb, c);
                let aabb = c.shape().compute_aabb(&pose);
                if !aabb.intersects(&all) {
                    continue;
                }
                for (l, lpose, lc, laabb) in &shapes {
                    if !aabb.intersects(laabb) {
                        continue;
                    }
                    let hit = rapier3d::parry::query::contact(
                        lpose,
                        lc.shape(),
                        &pose,
                        c.shape(),
                        CONTACT as f32,
                    );
                    let Ok(Some(k)) = hit else { continue };
                    let dist = f64::from(k.dist);
                    if dist > CONTACT || !dist.is_finite() {
                        continue;
                    }
                    let depth = (-dist).max(0.0);
                    found
                        .entry((*l, i))
                        .and_modify(|d| *d = d.max(depth))
                        .or_insert(depth);
                }
            }
        }
        found.into_iter().map(|((l, b), d)| (l, b, d)).collect()
    }
}

impl Surroundings for World {
    fn touches(&self, x: f64, y: f64, radius: f64, gap: f64) -> Vec<Touch> {
        let (lo, hi) = BUMPER_BAND;
        let ring = rapier3d::parry::shape::Cylinder::new(((hi - lo) / 2.0) as f32, radius as f32);
        let at = Isometry3::from_parts(
            Translation3::new(x, y, (lo + hi) / 2.0),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2),
        );
        let pose = convert::pose(&at);
        let aabb = rapier3d::parry::shape::Shape::compute_aabb(&ring, &pose).loosened(gap as f32);
        let mut out = Vec::new();
        for (h, c) in self
            .pw
            .intersect_aabb_conservative(aabb, QueryFilter::exclude_kinematic())
        {
            let Ok(Some(k)) =
                rapier3d::parry::query::contact(&pose, &ring, c.position(), c.shape(), gap as f32)
            else {
                continue;
            };
            let n = convert::from_vector(k.normal1);
            let fixed = c
                .parent()
                .and_then(|b| self.pw.bodies.get(b))
                .is_none_or(|b| b.is_fixed());
            let (i, g) = h.into_raw_parts();
            out.push(Touch {
                id: (u64::from(g) << 32) | u64::from(i),
                bearing: n.y.atan2(n.x),
                depth: -f64::from(k.dist),
                fixed,
            });
        }
        out
    }
}
