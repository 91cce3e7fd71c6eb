//! The robot's body in the world: its URDF link tree, each link's collision shapes, and how
//! the plants' true state (the base's ground-truth pose, the servos' output angles) sets
//! every joint of the tree, the gripper's fingers included. The renderer draws these shapes
//! and the physics engine collides with them.

use std::sync::Arc;

use ferrobot_description::{GripperSection, RobotConfig};
use ferrobot_kinematics::{pose_from_urdf, LinkTree};
use ferrobot_protocol::dxl::units;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

use crate::diff_drive::Pose;
use crate::scene::Shape;

/// One collision shape of a link.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkShape {
    /// Pose of the shape in the link's frame.
    pub origin: Isometry3<f64>,
    /// The shape (cylinders along z).
    pub shape: Shape,
    /// Colour for the camera, 0-1.
    pub colour: [f32; 3],
}

/// How one tree joint follows the plants.
#[derive(Debug, Clone, PartialEq)]
enum Drive {
    /// Joint value = (servo angle − offset) / sign.
    Servo {
        servo: usize,
        sign: f64,
        offset: f64,
    },
    /// A finger: `sign` × the gripper's finger offset at the servo's angle.
    Finger { servo: usize, sign: f64 },
}

/// The robot's body.
#[derive(Debug, Clone)]
pub struct RobotBody {
    /// The URDF's link tree.
    pub tree: LinkTree,
    /// Collision shapes of each link, in [`LinkTree::links`] order.
    pub shapes: Vec<Vec<LinkShape>>,
    /// Shapes the camera sees but nothing touches, on links ([`LinkTree::links`] index): the
    /// description's fiducial marker.
    pub decals: Vec<(usize, LinkShape)>,
    drives: Vec<Option<Drive>>,
    gripper: Option<GripperSection>,
    hand: Option<Hand>,
}

/// The gripper in the body: its servo, its fingers' links and the link they ride on, and the
/// servo angles of its mechanical stops.
#[derive(Debug, Clone, PartialEq)]
pub struct Hand {
    /// Index of the gripper's servo in the chain.
    pub servo: usize,
    /// The fingers' links ([`LinkTree::links`] indices).
    pub fingers: Vec<usize>,
    /// The link the fingers ride on (the palm, [`LinkTree::links`] index).
    pub palm: usize,
    /// Servo angle at the closed stop, rad.
    pub closed: f64,
    /// Servo angle at the open stop, rad.
    pub open: f64,
}

/// A servo that drives a joint of the description: its index in the chain, sign and offset.
#[derive(Debug, Clone, PartialEq)]
pub struct JointServo {
    /// Joint-table name (the URDF's joint name, or the gripper's motor).
    pub joint: String,
    /// Index of the joint's (primary) servo in the chain.
    pub servo: usize,
    /// Servo angle = sign · q + offset.
    pub sign: f64,
    /// Servo angle at q = 0, rad.
    pub offset: f64,
}

fn link_colour(name: &str) -> [f32; 3] {
    if name.contains("finger") || name.contains("gripper") {
        [0.18, 0.18, 0.2]
    } else if name.contains("wheel") {
        [0.08, 0.08, 0.08]
    } else if name.contains("base") || name.contains("plate") {
        [0.3, 0.3, 0.34]
    } else if name.contains("camera") {
        [0.12, 0.12, 0.14]
    } else if name.contains("tag") {
        [0.95, 0.95, 0.95]
    } else {
        [0.72, 0.72, 0.75]
    }
}

/// Thickness of the marker's black square, m (its top is the face the description places;
/// the description puts that face this far above the plate it is printed on, so that the two
/// never fight for a pixel's depth).
pub const MARKER_THICKNESS: f64 = 1e-4;

/// The fiducial `m` as a shape: a black square of its size and [`MARKER_THICKNESS`], its top
/// the face the description names.
fn marker_decal(m: &ferrobot_description::MarkerSection) -> LinkShape {
    let [x, y, z] = m.xyz;
    LinkShape {
        origin: Isometry3::translation(x, y, z - MARKER_THICKNESS / 2.0),
        shape: Shape::Box([m.size, m.size, MARKER_THICKNESS]),
        colour: [0.02, 0.02, 0.02],
    }
}

impl RobotBody {
    /// The body of `cfg`, its joints driven by `servos`. `None` when the URDF has no single
    /// root (a body cannot be placed in the world then).
    pub fn new(cfg: &RobotConfig, servos: &[JointServo]) -> Option<Arc<Self>> {
        let tree = LinkTree::from_urdf(&cfg.urdf).ok()?;
        let shapes = link_shapes(cfg, &tree);
        let gripper_servo = cfg
            .gripper
            .as_ref()
            .and_then(|g| servos.iter().find(|s| s.joint == g.joint).map(|s| s.servo));
        let drives = drives(&tree, cfg, servos, gripper_servo);
        let hand = hand(&tree, cfg, gripper_servo);
        let decals = cfg
            .camera
            .as_ref()
            .and_then(|c| c.marker.as_ref())
            .and_then(|m| Some((tree.link_index(&m.link)?, marker_decal(m))))
            .into_iter()
            .collect();
        Some(Arc::new(RobotBody {
            tree,
            shapes,
            decals,
            drives,
            gripper: cfg.gripper.clone(),
            hand,
        }))
    }

    /// Every tree joint's value (rad or m, [`LinkTree::joints`] order) for the servos'
    /// output angles `theta` (rad, chain order); joints no servo drives stay at 0.
    pub fn joint_values(&self, theta: &[f64]) -> Vec<f64> {
        self.drives
            .iter()
            .map(|d| match d {
                Some(Drive::Servo {
                    servo,
                    sign,
                    offset,
                }) => theta.get(*servo).map_or(0.0, |t| (t - offset) / sign),
                Some(Drive::Finger { servo, sign }) => match (&self.gripper, theta.get(*servo)) {
                    (Some(g), Some(t)) => {
                        let ticks =
                            t / f64::from(units::RAD_PER_TICK) + f64::from(units::CENTER_TICK);
                        sign * g.finger_offset(ticks)
                    }
                    _ => 0.0,
                },
                None => 0.0,
            })
            .collect()
    }

    /// The gripper's servo, finger links and palm, when the robot has a gripper with fingers.
    pub fn hand(&self) -> Option<&Hand> {
        self.hand.as_ref()
    }

    /// Pose of the tree's root in the world for a base pose on the floor and a pedestal
    /// height, m.
    pub fn root_pose(base: Pose, height: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(base[0], base[1], height),
            UnitQuaternion::from_euler_angles(0.0, 0.0, base[2]),
        )
    }

    /// Pose of every link in the world ([`LinkTree::links`] order).
    pub fn link_poses(&self, root: &Isometry3<f64>, q: &[f64]) -> Vec<Isometry3<f64>> {
        self.tree.poses(q).into_iter().map(|p| root * p).collect()
    }
}

/// The collision shapes of each link of `tree` ([`LinkTree::links`] order) from `cfg`'s URDF;
/// links with mesh geometry get none (mesh files are not read).
fn link_shapes(cfg: &RobotConfig, tree: &LinkTree) -> Vec<Vec<LinkShape>> {
    tree.links()
        .map(|name| {
            let link = cfg.urdf.links.iter().find(|l| l.name == name);
            link.map(|l| {
                l.collision
                    .iter()
                    .filter_map(|c| {
                        let shape = match &c.geometry {
                            urdf_rs::Geometry::Box { size } => {
                                Shape::Box([size[0], size[1], size[2]])
                            }
                            urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
                                radius: *radius,
                                length: *length,
                            },
                            urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
                                radius: *radius,
                                length: *length,
                            },
                            urdf_rs::Geometry::Sphere { radius } => Shape::Sphere(*radius),
                            // Mesh files of a URDF are not read (the bundled robots have
                            // none): such links are invisible and do not collide.
                            urdf_rs::Geometry::Mesh { .. } => return None,
                        };
                        Some(LinkShape {
                            origin: pose_from_urdf(&c.origin),
                            shape,
                            colour: link_colour(name),
                        })
                    })
                    .collect()
            })
            .unwrap_or_default()
        })
        .collect()
}

/// What drives each joint of `tree` ([`LinkTree::joints`] order): its servo, a finger of the
/// gripper servo `gripper_servo`, or nothing.
fn drives(
    tree: &LinkTree,
    cfg: &RobotConfig,
    servos: &[JointServo],
    gripper_servo: Option<usize>,
) -> Vec<Option<Drive>> {
    tree.joints()
        .iter()
        .map(|j| {
            if let Some(s) = servos.iter().find(|s| s.joint == j.name) {
                return Some(Drive::Servo {
                    servo: s.servo,
                    sign: s.sign,
                    offset: s.offset,
                });
            }
            let g = cfg.gripper.as_ref()?;
            let f = g.fingers.iter().find(|f| f.joint == j.name)?;
            Some(Drive::Finger {
                servo: gripper_servo?,
                sign: f.sign,
            })
        })
        .collect()
}

/// The gripper's hand: its servo, palm and finger links and stops, when `cfg` has a gripper
/// whose links are all in `tree`.
fn hand(tree: &LinkTree, cfg: &RobotConfig, gripper_servo: Option<usize>) -> Option<Hand> {
    cfg.gripper.as_ref().and_then(|g| {
        let joint = |name: &str| cfg.urdf.joints.iter().find(|j| j.name == name);
        let fingers: Vec<usize> = g
            .fingers
            .iter()
            .filter_map(|f| tree.link_index(&joint(&f.joint)?.child.link))
            .collect();
        let first = joint(&g.fingers.first()?.joint)?;
        let tick = |t: i32| f64::from(units::tick_to_rad(t));
        (fingers.len() == g.fingers.len()).then_some(Hand {
            servo: gripper_servo?,
            palm: tree.link_index(&first.parent.link)?,
            fingers,
            closed: tick(g.stops[0]),
            open: tick(g.stops[1]),
        })
    })
}
