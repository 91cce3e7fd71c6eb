//! The robot's URDF frames as its measured joints place them: PyRobot's `get_link_transform`,
//! and the camera's pose for each frame.

use ferrobot_description::{GripperSection, RobotConfig};
use ferrobot_kinematics::LinkTree;
use ferrobot_protocol::dxl::units;
use ferrobot_protocol::Telemetry;
use nalgebra::Isometry3;

use crate::error::Result;

/// The mobile base's frame: its centre on the floor, x ahead (the navigator's footprint is a
/// circle round it).
pub const BASE_FRAME: &str = "base_link";

/// The URDF's link tree and how the joint table's measured positions set its joints.
#[derive(Debug, Clone)]
pub struct Frames {
    tree: LinkTree,
    /// For each joint-table entry, the tree joint it sets.
    joints: Vec<Option<usize>>,
    /// The gripper's fingers, when the description names them.
    gripper: Option<Fingers>,
}

/// How the gripper's measured position sets the fingers.
#[derive(Debug, Clone)]
struct Fingers {
    /// The gripper's joint-table index.
    joint: usize,
    /// The gripper's description (finger travel).
    section: GripperSection,
    /// Each finger's tree joint and sign.
    fingers: Vec<(usize, f64)>,
}

impl Frames {
    /// The frames of `cfg`'s URDF.
    pub(crate) fn new(cfg: &RobotConfig) -> Result<Frames> {
        let tree = LinkTree::from_urdf(&cfg.urdf)?;
        let joints = cfg
            .joints
            .iter()
            .map(|j| tree.joint_index(j.name.as_str()))
            .collect();
        let gripper = cfg.gripper.as_ref().and_then(|g| {
            let idx = cfg.joint_index(&g.joint)?;
            let fingers = g
                .fingers
                .iter()
                .filter_map(|f| Some((tree.joint_index(&f.joint)?, f.sign)))
                .collect();
            Some(Fingers {
                joint: idx,
                section: g.clone(),
                fingers,
            })
        });
        Ok(Frames {
            tree,
            joints,
            gripper,
        })
    }

    /// The tree's joint values for the joint positions of `tel` (rad or m). The gripper's
    /// position (its servo's angle from the centre tick, rad) sets the fingers through the
    /// description's finger travel.
    pub fn joint_values(&self, tel: &Telemetry) -> Vec<f64> {
        let mut q = vec![0.0; self.tree.joints().len()];
        for (i, t) in self.joints.iter().enumerate() {
            if let (Some(t), Some(s)) = (t, tel.joints.get(i)) {
                q[*t] = s.position as f64;
            }
        }
        if let Some(g) = &self.gripper {
            if let Some(s) = tel.joints.get(g.joint) {
                let ticks = s.position as f64 / f64::from(units::RAD_PER_TICK)
                    + f64::from(units::CENTER_TICK);
                let off = g.section.finger_offset(ticks);
                for &(j, sign) in &g.fingers {
                    q[j] = sign * off;
                }
            }
        }
        q
    }

    /// Pose of frame `src` in frame `dst` (maps points of `src` into `dst`) for the joints of
    /// `tel`.
    pub fn transform_at(&self, tel: &Telemetry, src: &str, dst: &str) -> Result<Isometry3<f64>> {
        let poses = self.tree.poses(&self.joint_values(tel));
        Ok(self.tree.transform(&poses, src, dst)?)
    }

    /// The links (URDF tree indices) that the joints named `joints` move: each joint's child
    /// and everything beyond it. Unknown names move nothing.
    pub fn links_moved_by(&self, joints: &[String]) -> Vec<usize> {
        let idx: Vec<usize> = joints
            .iter()
            .filter_map(|j| self.tree.joint_index(j))
            .collect();
        self.tree.links_moved_by(&idx)
    }

    /// The URDF's link tree (its links, joints and their origins).
    pub fn tree(&self) -> &LinkTree {
        &self.tree
    }

    /// Index of link `name` in the URDF tree's order.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.tree.link_index(name)
    }

    /// Pose of every link (in the URDF tree's order) in frame `dst` for the joints of `tel`.
    pub fn poses_in(&self, tel: &Telemetry, dst: &str) -> Result<Vec<Isometry3<f64>>> {
        let poses = self.tree.poses(&self.joint_values(tel));
        let root = self.tree.root().to_string();
        let to_dst = self.tree.transform(&poses, &root, dst)?;
        Ok(poses.into_iter().map(|p| to_dst * p).collect())
    }
}
