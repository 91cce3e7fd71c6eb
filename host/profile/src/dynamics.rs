//! The arm's gravity model from its URDF: for each arm joint, the joint's origin and fixed
//! rotation in the previous arm joint's frame and the mass and centre of mass of everything it
//! carries up to the next arm joint (every other movable joint at zero, fixed joints folded
//! in). The firmware gets it as [`ArmLink`]s; the simulated arm's servos bear it.

use std::collections::HashMap;

use ferrobot_description::RobotConfig;
use ferrobot_protocol::gravity::{Link, MAX_LINKS};
use ferrobot_protocol::ArmLink;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// One arm joint's link of the gravity model (f64, in the description's units: m, kg, rad),
/// with the joint's URDF name.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelLink {
    /// The arm joint's URDF name.
    pub joint: String,
    /// The link.
    pub link: Link<f64>,
}

fn origin(j: &urdf_rs::Joint) -> Isometry3<f64> {
    let [r, p, y] = j.origin.rpy.0;
    Isometry3::from_parts(
        Translation3::from(Vector3::from(j.origin.xyz.0)),
        UnitQuaternion::from_euler_angles(r, p, y),
    )
}

/// The arm's gravity model from `cfg`'s URDF, base frame (the root link; gravity along its
/// −z) first; empty without an arm or when the URDF's tree does not hold its joints.
pub fn arm_links(cfg: &RobotConfig) -> Vec<ModelLink> {
    let Some(arm) = &cfg.arm else {
        return Vec::new();
    };
    let urdf = &cfg.urdf;
    let by_name: HashMap<&str, &urdf_rs::Joint> =
        urdf.joints.iter().map(|j| (j.name.as_str(), j)).collect();
    let parent_of: HashMap<&str, &urdf_rs::Joint> = urdf
        .joints
        .iter()
        .map(|j| (j.child.link.as_str(), j))
        .collect();
    // Each arm joint's origin in its parent link's frame, folded back through fixed (or
    // other, at zero) joints to the previous arm joint's child link (or the base frame).
    let mut links = Vec::new();
    let mut prev = arm.base_frame.as_str();
    for name in &arm.joints {
        let Some(j) = by_name.get(name.as_str()) else {
            return Vec::new();
        };
        let mut pose = origin(j);
        let mut parent = j.parent.link.as_str();
        while parent != prev {
            let Some(f) = parent_of.get(parent) else {
                return Vec::new();
            };
            pose = origin(f) * pose;
            parent = f.parent.link.as_str();
        }
        let (roll, pitch, yaw) = pose.rotation.euler_angles();
        let (mass, com) = carried(urdf, &parent_of, j, &arm.joints);
        links.push(ModelLink {
            joint: name.clone(),
            link: Link {
                origin: pose.translation.vector.into(),
                rpy: [roll, pitch, yaw],
                axis: Vector3::from(j.axis.xyz.0).normalize().into(),
                mass,
                com,
            },
        });
        prev = j.child.link.as_str();
    }
    links
}

/// The mass (kg) and centre of mass (m, in `joint`'s frame) of every link whose path to the
/// root passes through `joint` and through no later arm joint.
fn carried(
    urdf: &urdf_rs::Robot,
    parent_of: &HashMap<&str, &urdf_rs::Joint>,
    joint: &urdf_rs::Joint,
    arm: &[String],
) -> (f64, [f64; 3]) {
    let (mut m, mut mc) = (0.0, Vector3::zeros());
    for l in &urdf.links {
        // The link's pose in the joint's frame, walking up to it.
        let mut pose = Isometry3::identity();
        let mut at = l.name.as_str();
        let carried = loop {
            if at == joint.child.link {
                break true;
            }
            let Some(f) = parent_of.get(at) else {
                break false;
            };
            if arm.contains(&f.name) {
                break false;
            }
            pose = origin(f) * pose;
            at = f.parent.link.as_str();
        };
        if carried {
            let mass = l.inertial.mass.value;
            let c = pose * Point3::from(Vector3::from(l.inertial.origin.xyz.0));
            m += mass;
            mc += c.coords * mass;
        }
    }
    let com = if m > 0.0 { mc / m } else { mc };
    (m, com.into())
}

/// The arm's gravity model as the firmware takes it, each link naming its joint's row of
/// `cfg`'s joint table; `None` without an arm, with more than
/// [`MAX_LINKS`] joints, or with an arm joint that is not a row.
pub fn arm_model(cfg: &RobotConfig) -> Option<Vec<ArmLink>> {
    let links = arm_links(cfg);
    if links.is_empty() || links.len() > MAX_LINKS {
        return None;
    }
    let f = |v: [f64; 3]| v.map(|x| x as f32);
    links
        .iter()
        .map(|l| {
            let row = cfg.joints.iter().position(|j| j.name == l.joint)?;
            Some(ArmLink {
                joint: u8::try_from(row).ok()?,
                origin: f(l.link.origin),
                rpy: f(l.link.rpy),
                axis: f(l.link.axis),
                mass: l.link.mass as f32,
                com: f(l.link.com),
            })
        })
        .collect()
}
