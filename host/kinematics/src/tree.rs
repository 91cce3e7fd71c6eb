//! Forward kinematics of a whole URDF tree: the pose of every link in the root link's frame
//! for given joint values, and the transform between any two frames (PyRobot's
//! `get_link_transform`).

use std::collections::{HashMap, HashSet};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::{pose_from_urdf, Error, JointType, Result};

/// One link of the tree, with the joint that carries it.
#[derive(Debug, Clone, PartialEq)]
struct Node {
    name: String,
    parent: Option<usize>,
    /// Parent link frame to this link's joint frame.
    origin: Isometry3<f64>,
    /// The movable joint (index into `joints`), if the joint is not fixed.
    joint: Option<usize>,
}

/// A movable joint of the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct TreeJoint {
    /// URDF name.
    pub name: String,
    /// Type.
    pub kind: JointType,
    /// Unit axis in the joint frame.
    pub axis: Vector3<f64>,
    /// A URDF `<mimic>` joint follows another: its value is `multiplier · q[leader] + offset`
    /// (the leader's index in [`LinkTree::joints`]), whatever value it is given itself.
    pub mimic: Option<Mimic>,
}

/// How a mimic joint follows its leader ([`TreeJoint::mimic`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mimic {
    /// The leader's index in [`LinkTree::joints`].
    pub leader: usize,
    /// Its value per unit of the leader's (URDF default 1).
    pub multiplier: f64,
    /// Its value at the leader's zero, rad or m (URDF default 0).
    pub offset: f64,
}

/// A URDF's links in parent-before-child order.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkTree {
    nodes: Vec<Node>,
    joints: Vec<TreeJoint>,
    index: HashMap<String, usize>,
}

/// Checks what the tree and the planner rely on in `urdf` and its parser does not: link and
/// joint names each used once, every joint's parent and child among the links, finite joint
/// origins, finite non-zero axes of revolute, continuous and prismatic joints, and finite
/// collision origins.
pub fn check_urdf(urdf: &urdf_rs::Robot) -> Result<()> {
    let links = check_links(urdf)?;
    check_joints(urdf, &links)?;
    check_mimics(urdf)
}

/// [`check_urdf`]'s links: each name once, finite collision origins. Returns their names.
fn check_links(urdf: &urdf_rs::Robot) -> Result<HashSet<&str>> {
    let bad = |why: String| Error::Unreachable { why };
    let mut links = HashSet::new();
    for l in &urdf.links {
        if !links.insert(l.name.as_str()) {
            return Err(bad(format!("link {:?} is defined twice", l.name)));
        }
        if l.collision.iter().any(|c| !pose_finite(&c.origin)) {
            return Err(bad(format!(
                "link {:?} has a collision origin that is not finite",
                l.name
            )));
        }
    }
    Ok(links)
}

/// [`check_urdf`]'s joints: each name once, between `links`, finite origins, finite non-zero
/// axes where they move.
fn check_joints(urdf: &urdf_rs::Robot, links: &HashSet<&str>) -> Result<()> {
    let bad = |why: String| Error::Unreachable { why };
    let mut joints = HashSet::new();
    for j in &urdf.joints {
        if !joints.insert(j.name.as_str()) {
            return Err(bad(format!("joint {:?} is defined twice", j.name)));
        }
        for (end, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
            if !links.contains(link.as_str()) {
                return Err(bad(format!(
                    "joint {:?} names {end} link {link:?}, which the URDF does not define",
                    j.name
                )));
            }
        }
        if !pose_finite(&j.origin) {
            return Err(bad(format!(
                "joint {:?} has an origin that is not finite",
                j.name
            )));
        }
        let movable = matches!(
            j.joint_type,
            urdf_rs::JointType::Revolute
                | urdf_rs::JointType::Continuous
                | urdf_rs::JointType::Prismatic
        );
        let a = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
        if movable && !(a.iter().all(|v| v.is_finite()) && a.norm() > 1e-9) {
            return Err(bad(format!(
                "joint {:?} has axis {:?}: it needs a finite, non-zero one",
                j.name, j.axis.xyz
            )));
        }
    }
    Ok(())
}

/// Whether a URDF joint moves (revolute, continuous or prismatic): the joints a tree and a
/// chain give values.
fn moves(j: &urdf_rs::Joint) -> bool {
    matches!(
        j.joint_type,
        urdf_rs::JointType::Revolute
            | urdf_rs::JointType::Continuous
            | urdf_rs::JointType::Prismatic
    )
}

/// [`check_urdf`]'s mimic joints: each joint that moves and mimics follows a joint that moves
/// and mimics none, with a finite multiplier and offset. A `<mimic>` on a joint that does not
/// move is meaningless and ignored, as urdfdom, pinocchio and MoveIt ignore it (VAMP's
/// `panda_spherized.urdf` fixes both finger joints and keeps the follower's tag).
fn check_mimics(urdf: &urdf_rs::Robot) -> Result<()> {
    let bad = |why: String| Error::Unreachable { why };
    for j in urdf.joints.iter().filter(|j| moves(j)) {
        let Some(m) = &j.mimic else { continue };
        let leader = urdf.joints.iter().find(|l| l.name == m.joint);
        let why = match leader {
            None => Some("which the URDF does not define".to_string()),
            Some(l) if !moves(l) => Some("which does not move".into()),
            Some(l) if l.mimic.is_some() => Some("which mimics another joint itself".into()),
            _ => None,
        };
        if let Some(why) = why {
            return Err(bad(format!(
                "joint {:?} mimics joint {:?}, {why}",
                j.name, m.joint
            )));
        }
        let (mult, off) = (m.multiplier.unwrap_or(1.0), m.offset.unwrap_or(0.0));
        if !(mult.is_finite() && off.is_finite()) {
            return Err(bad(format!(
                "joint {:?} mimics with multiplier {mult} and offset {off}: they must be finite",
                j.name
            )));
        }
    }
    Ok(())
}

fn pose_finite(p: &urdf_rs::Pose) -> bool {
    p.xyz.iter().chain(p.rpy.iter()).all(|v| v.is_finite())
}

/// The one link of `urdf` without a parent joint; an error when a link has two parents or
/// there is not one such link.
fn root_of(urdf: &urdf_rs::Robot) -> Result<&str> {
    let unreachable = |why: String| Error::Unreachable { why };
    let mut parent_joint: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
    for j in &urdf.joints {
        if parent_joint.insert(j.child.link.as_str(), j).is_some() {
            return Err(unreachable(format!(
                "link {} has two parents",
                j.child.link
            )));
        }
    }
    let roots: Vec<&str> = urdf
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|n| !parent_joint.contains_key(n))
        .collect();
    if roots.len() != 1 {
        return Err(unreachable(format!(
            "the URDF has {} root links ({roots:?}), not one",
            roots.len()
        )));
    }
    Ok(roots[0])
}

impl LinkTree {
    /// The tree of `urdf`, rooted at its one link without a parent joint; `urdf` must pass
    /// [`check_urdf`].
    pub fn from_urdf(urdf: &urdf_rs::Robot) -> Result<Self> {
        check_urdf(urdf)?;
        let root = root_of(urdf)?;
        let mut tree = LinkTree {
            nodes: Vec::new(),
            joints: Vec::new(),
            index: HashMap::new(),
        };
        tree.index.insert(root.to_string(), 0);
        tree.nodes.push(Node {
            name: root.to_string(),
            parent: None,
            origin: Isometry3::identity(),
            joint: None,
        });
        tree.add_descendants(urdf)?;
        if tree.nodes.len() != urdf.links.len() {
            return Err(Error::Unreachable {
                why: format!(
                    "{} of the URDF's {} links hang from no joint path to the root",
                    urdf.links.len().saturating_sub(tree.nodes.len()),
                    urdf.links.len()
                ),
            });
        }
        tree.link_mimics(urdf);
        Ok(tree)
    }

    /// Adds the links below the root, breadth first from it, so parents come before children.
    fn add_descendants(&mut self, urdf: &urdf_rs::Robot) -> Result<()> {
        let mut k = 0;
        while k < self.nodes.len() {
            let parent = self.nodes[k].name.clone();
            for j in urdf.joints.iter().filter(|j| j.parent.link == parent) {
                if self.index.contains_key(&j.child.link) {
                    return Err(Error::Unreachable {
                        why: "the URDF has a cycle".into(),
                    });
                }
                let kind = match j.joint_type {
                    urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                        Some(JointType::Revolute)
                    }
                    urdf_rs::JointType::Prismatic => Some(JointType::Prismatic),
                    _ => None,
                };
                let joint = kind.map(|kind| {
                    let a = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
                    self.joints.push(TreeJoint {
                        name: j.name.clone(),
                        kind,
                        axis: a.try_normalize(1e-12).unwrap_or(Vector3::z()),
                        // Its leader's index is known once every joint is in: `link_mimics`.
                        mimic: None,
                    });
                    self.joints.len() - 1
                });
                self.index.insert(j.child.link.clone(), self.nodes.len());
                self.nodes.push(Node {
                    name: j.child.link.clone(),
                    parent: Some(k),
                    origin: pose_from_urdf(&j.origin),
                    joint,
                });
            }
            k += 1;
        }
        Ok(())
    }

    /// Sets each mimic joint's leader, once every joint is in.
    fn link_mimics(&mut self, urdf: &urdf_rs::Robot) {
        for j in &urdf.joints {
            let (Some(m), Some(k)) = (&j.mimic, self.joint_index(&j.name)) else {
                continue;
            };
            // check_urdf: the leader exists and moves.
            if let Some(leader) = self.joint_index(&m.joint) {
                self.joints[k].mimic = Some(Mimic {
                    leader,
                    multiplier: m.multiplier.unwrap_or(1.0),
                    offset: m.offset.unwrap_or(0.0),
                });
            }
        }
    }

    /// The root link.
    pub fn root(&self) -> &str {
        &self.nodes[0].name
    }

    /// Link names, parents before children (the order of [`LinkTree::poses`]).
    pub fn links(&self) -> impl Iterator<Item = &str> {
        self.nodes.iter().map(|n| n.name.as_str())
    }

    /// Index of a link in [`LinkTree::links`].
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.index.get(name).copied()
    }

    /// The movable joints (the order of the values [`LinkTree::poses`] takes).
    pub fn joints(&self) -> &[TreeJoint] {
        &self.joints
    }

    /// Index of a movable joint in [`LinkTree::joints`].
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Pose of every link in the root frame, in [`LinkTree::links`] order, for joint values
    /// `q` (rad or m, in [`LinkTree::joints`] order; missing values count as 0; a mimic
    /// joint's follows its leader's).
    pub fn poses(&self, q: &[f64]) -> Vec<Isometry3<f64>> {
        let mut out = Vec::with_capacity(self.nodes.len());
        self.poses_into(q, &mut out);
        out
    }

    /// [`LinkTree::poses`] into `out` (cleared first), without allocating once `out` has room.
    pub fn poses_into(&self, q: &[f64], out: &mut Vec<Isometry3<f64>>) {
        out.clear();
        for i in 0..self.nodes.len() {
            let pose = self.pose_of(i, q, out);
            out.push(pose);
        }
    }

    /// The links (indices of [`LinkTree::links`]) whose poses depend on any of the movable
    /// `joints` (indices of [`LinkTree::joints`]), parents before children.
    pub fn links_moved_by(&self, joints: &[usize]) -> Vec<usize> {
        let mut moved = vec![false; self.nodes.len()];
        let moves = |j: usize| {
            joints.contains(&j)
                || self.joints[j]
                    .mimic
                    .is_some_and(|m| joints.contains(&m.leader))
        };
        for (i, n) in self.nodes.iter().enumerate() {
            moved[i] = n.joint.is_some_and(moves) || n.parent.is_some_and(|p| moved[p]);
        }
        (0..self.nodes.len()).filter(|&i| moved[i]).collect()
    }

    /// Recomputes in `poses` (from [`LinkTree::poses_into`] with the same values of every
    /// other joint) the poses of `links` ([`LinkTree::links_moved_by`] of the joints whose
    /// values in `q` changed); the other links keep theirs.
    ///
    /// # Panics
    /// If `poses` holds fewer poses than the tree has links.
    pub fn update_poses(&self, q: &[f64], links: &[usize], poses: &mut [Isometry3<f64>]) {
        for &i in links {
            poses[i] = self.pose_of(i, q, poses);
        }
    }

    /// Pose of link `i` for joint values `q`, its parent's pose read from `poses`.
    ///
    /// A revolute joint's rotation is built from one sine and cosine of the half angle about
    /// the stored unit axis (no axis normalisation), and identities are not composed: this is
    /// the planner's innermost forward kinematics.
    #[inline]
    fn pose_of(&self, i: usize, q: &[f64], poses: &[Isometry3<f64>]) -> Isometry3<f64> {
        let n = &self.nodes[i];
        let joint_frame = match n.parent {
            Some(p) => poses[p] * n.origin,
            None => n.origin,
        };
        let Some(j) = n.joint else {
            return joint_frame;
        };
        let joint = &self.joints[j];
        let v = match joint.mimic {
            Some(m) => m.multiplier * q.get(m.leader).copied().unwrap_or(0.0) + m.offset,
            None => q.get(j).copied().unwrap_or(0.0),
        };
        match joint.kind {
            JointType::Revolute => {
                let (s, c) = ferrobot_geometry::trig::sin_cos(0.5 * v);
                let a = joint.axis * s;
                let motion =
                    UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(c, a.x, a.y, a.z));
                Isometry3::from_parts(joint_frame.translation, joint_frame.rotation * motion)
            }
            JointType::Prismatic => joint_frame * Translation3::from(joint.axis * v),
        }
    }

    /// The parent of link `link` ([`LinkTree::links`] indices); `None` for the root.
    pub fn parent(&self, link: usize) -> Option<usize> {
        self.nodes.get(link).and_then(|n| n.parent)
    }

    /// The movable joint ([`LinkTree::joints`] index) between link `link` and its parent;
    /// `None` for the root and for links on fixed joints.
    pub fn link_joint(&self, link: usize) -> Option<usize> {
        self.nodes.get(link).and_then(|n| n.joint)
    }

    /// Pose of link `link`'s joint frame in its parent link's frame (the URDF joint origin).
    pub fn link_origin(&self, link: usize) -> Option<Isometry3<f64>> {
        self.nodes.get(link).map(|n| n.origin)
    }

    /// Pose of frame `src` in frame `dst` (`T_dst_src`) given the link poses of
    /// [`LinkTree::poses`]: PyRobot's `get_link_transform(src, dst)`.
    pub fn transform(
        &self,
        poses: &[Isometry3<f64>],
        src: &str,
        dst: &str,
    ) -> Result<Isometry3<f64>> {
        let find = |n: &str| {
            self.link_index(n)
                .and_then(|i| poses.get(i))
                .ok_or_else(|| Error::UnknownName {
                    what: "frame",
                    name: n.to_string(),
                })
        };
        let (s, d) = (find(src)?, find(dst)?);
        Ok(d.inverse() * s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Chain;

    const URDF: &str = include_str!("../../description/robots/locobot.urdf");

    #[test]
    fn the_tree_agrees_with_the_arm_chain() {
        let urdf = urdf_rs::read_from_string(URDF).unwrap();
        let tree = LinkTree::from_urdf(&urdf).unwrap();
        assert_eq!(tree.root(), "base_footprint");
        let chain = Chain::from_urdf(&urdf, "base_link", "gripper_link").unwrap();
        let qa = [0.3, -0.4, 0.5, 0.2, -0.7];
        let mut q = vec![0.0; tree.joints().len()];
        for (j, v) in chain.joints.iter().zip(qa) {
            q[tree.joint_index(&j.name).unwrap()] = v;
        }
        let poses = tree.poses(&q);
        let t = tree.transform(&poses, "gripper_link", "base_link").unwrap();
        let f = chain.fk(&qa);
        assert!((t.translation.vector - f.translation.vector).norm() < 1e-12);
        assert!(t.rotation.angle_to(&f.rotation) < 1e-12);
        assert!(tree.transform(&poses, "nope", "base_link").is_err());
    }

    #[test]
    fn updating_the_moved_links_equals_computing_all() {
        let urdf = urdf_rs::read_from_string(URDF).unwrap();
        let tree = LinkTree::from_urdf(&urdf).unwrap();
        let arm: Vec<usize> = ["joint_1", "joint_2", "joint_3"]
            .iter()
            .map(|j| tree.joint_index(j).unwrap())
            .collect();
        let moved = tree.links_moved_by(&arm);
        // The arm's links move, the base and the camera do not.
        let link = |n: &str| tree.links().position(|l| l == n).unwrap();
        assert!(moved.contains(&link("gripper_link")));
        assert!(!moved.contains(&link("base_link")) && !moved.contains(&link("camera_link")));
        let mut q = vec![0.1; tree.joints().len()];
        let mut poses = tree.poses(&q);
        for (k, &j) in arm.iter().enumerate() {
            q[j] = 0.4 - 0.3 * k as f64;
        }
        tree.update_poses(&q, &moved, &mut poses);
        for (a, b) in poses.iter().zip(tree.poses(&q)) {
            assert!((a.translation.vector - b.translation.vector).norm() < 1e-15);
            assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
        }
    }

    /// A two-finger gripper whose right finger mimics the left (multiplier −1, offset 1 cm),
    /// on a wrist joint; `mimic` replaces the right finger's `<mimic>` element.
    fn gripper(mimic: &str) -> String {
        format!(
            r#"<robot name="g">
  <link name="base"/><link name="palm"/><link name="left"/><link name="right"/>
  <joint name="wrist" type="revolute"><parent link="base"/><child link="palm"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="finger_l" type="prismatic"><parent link="palm"/><child link="left"/>
    <origin xyz="0.1 0 0"/><axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="1" velocity="1"/></joint>
  <joint name="finger_r" type="prismatic"><parent link="palm"/><child link="right"/>
    <origin xyz="0.1 0 0"/><axis xyz="0 1 0"/><limit lower="-0.04" upper="0.04" effort="1" velocity="1"/>
    {mimic}</joint>
</robot>"#
        )
    }

    /// A `<mimic>` joint follows its leader, whatever value it is given, in the poses and in
    /// the links a leader's change moves (the planner's incremental update); a mimic naming
    /// no joint, mimicking a mimic or with a NaN multiplier is refused, and an arm chain
    /// through one is an error.
    #[test]
    fn a_mimic_joint_follows_its_leader() {
        let urdf = urdf_rs::read_from_string(&gripper(
            r#"<mimic joint="finger_l" multiplier="-1" offset="0.01"/>"#,
        ))
        .unwrap();
        let tree = LinkTree::from_urdf(&urdf).unwrap();
        let (wrist, left, right) = (
            tree.joint_index("wrist").unwrap(),
            tree.joint_index("finger_l").unwrap(),
            tree.joint_index("finger_r").unwrap(),
        );
        let mut q = vec![0.0; 3];
        q[wrist] = 0.0;
        q[left] = 0.03;
        // Its own value is ignored.
        q[right] = 0.5;
        let poses = tree.poses(&q);
        let at = |n: &str| poses[tree.link_index(n).unwrap()].translation.vector;
        assert!((at("left").y - 0.03).abs() < 1e-12, "{}", at("left"));
        assert!(
            (at("right").y - (-0.03 + 0.01)).abs() < 1e-12,
            "{}",
            at("right")
        );
        let moved = tree.links_moved_by(&[left]);
        assert!(moved.contains(&tree.link_index("right").unwrap()));
        let mut updated = poses.clone();
        q[left] = 0.01;
        tree.update_poses(&q, &moved, &mut updated);
        assert_eq!(updated, tree.poses(&q));
        assert!(Chain::from_urdf(&urdf, "base", "left").is_ok());
        let err = Chain::from_urdf(&urdf, "base", "right").unwrap_err();
        assert!(err.to_string().contains("mimics"), "{err}");
        for (bad, why) in [
            (r#"<mimic joint="thumb"/>"#, "does not define"),
            (r#"<mimic joint="finger_l" multiplier="nan"/>"#, "finite"),
            (r#"<mimic joint="wrist"/>"#, ""),
        ] {
            let urdf = urdf_rs::read_from_string(&gripper(bad)).unwrap();
            match LinkTree::from_urdf(&urdf) {
                Err(e) => assert!(!why.is_empty() && e.to_string().contains(why), "{bad}: {e}"),
                Ok(_) => assert!(why.is_empty(), "{bad} was accepted"),
            }
        }
        // A mimic of a mimic.
        let chained = gripper(r#"<mimic joint="finger_l"/>"#).replace(
            r#"<joint name="finger_l" type="prismatic">"#,
            r#"<joint name="finger_l" type="prismatic"><mimic joint="finger_r"/>"#,
        );
        let urdf = urdf_rs::read_from_string(&chained).unwrap();
        let err = LinkTree::from_urdf(&urdf).unwrap_err();
        assert!(err.to_string().contains("mimics another"), "{err}");
        // A moving joint that mimics a fixed one would mislead: refused.
        let fixed_leader = gripper(r#"<mimic joint="finger_l"/>"#).replace(
            r#"<joint name="finger_l" type="prismatic">"#,
            r#"<joint name="finger_l" type="fixed">"#,
        );
        let urdf = urdf_rs::read_from_string(&fixed_leader).unwrap();
        let err = LinkTree::from_urdf(&urdf).unwrap_err();
        assert!(err.to_string().contains("does not move"), "{err}");
    }

    /// A `<mimic>` on a joint that does not move is ignored, as urdfdom ignores it: VAMP's
    /// Panda fixes both finger joints and keeps the follower's tag. The tree and a chain
    /// through the fixed joint build, and the fixed finger sits where its origin puts it.
    #[test]
    fn a_mimic_on_a_fixed_joint_is_ignored() {
        let both_fixed = gripper(r#"<mimic joint="finger_l" multiplier="-1"/>"#)
            .replace(
                r#"<joint name="finger_l" type="prismatic">"#,
                r#"<joint name="finger_l" type="fixed">"#,
            )
            .replace(
                r#"<joint name="finger_r" type="prismatic">"#,
                r#"<joint name="finger_r" type="fixed">"#,
            );
        let urdf = urdf_rs::read_from_string(&both_fixed).unwrap();
        let tree = LinkTree::from_urdf(&urdf).expect("a fixed joint's mimic is ignored");
        assert_eq!(tree.joints().len(), 1, "only the wrist moves");
        let poses = tree.poses(&[0.0]);
        let right = poses[tree.link_index("right").unwrap()].translation.vector;
        assert!((right - nalgebra::Vector3::new(0.1, 0.0, 0.0)).norm() < 1e-12);
        assert!(Chain::from_urdf(&urdf, "base", "right").is_ok());
        // Its leader need not exist either: the tag says nothing.
        let dangling = both_fixed.replace(r#"joint="finger_l""#, r#"joint="thumb""#);
        let urdf = urdf_rs::read_from_string(&dangling).unwrap();
        assert!(LinkTree::from_urdf(&urdf).is_ok());
    }
}
