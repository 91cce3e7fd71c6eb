//! The robot's collision model: each link's collision shapes from the URDF (primitives; meshes
//! as the convex hull of their vertices), a conservative sphere set per link, which links move
//! with the planned joints, and how far any of their points can move for a joint step.

use std::path::{Path, PathBuf};

use ferrobot_description::RobotConfig;
use ferrobot_kinematics::LinkTree;
use nalgebra::Isometry3;

use crate::acm::SelfCollisionMatrix;
use crate::convert::{self, Exact};
use crate::{Error, Result};

mod geometry;
mod reach;

pub(crate) use geometry::bounding_sphere;
use geometry::config_dir;
pub use geometry::{config_geometry, urdf_geometry, LinkGeometry, MAX_MESH_BYTES};

/// The robot's collision model for planning some of its joints.
#[derive(Debug, Clone)]
pub struct CollisionModel {
    name: String,
    tree: LinkTree,
    links: Vec<LinkGeometry>,
    /// [`LinkTree::joints`] index of each planned joint.
    planned: Vec<usize>,
    joint_names: Vec<String>,
    limits: Vec<(f64, f64)>,
    /// Every tree joint's range (URDF limits; ±π for continuous joints; planned joints' given
    /// limits).
    all_limits: Vec<(f64, f64)>,
    /// Every tree joint's value while planning (planned ones overwritten per state).
    values: Vec<f64>,
    moving: Vec<bool>,
    /// The links the planned joints move, parents first.
    moved: Vec<usize>,
    acm: SelfCollisionMatrix,
    urdf_file: Option<PathBuf>,
}

fn invalid(what: impl Into<String>, why: impl Into<String>) -> Error {
    Error::Invalid {
        what: what.into(),
        why: why.into(),
    }
}

/// The [`LinkTree::joints`] index of each of `joints` (URDF names), each movable, once, and
/// with a finite range of at most 4π in `limits`.
fn planned_joints(tree: &LinkTree, joints: &[String], limits: &[(f64, f64)]) -> Result<Vec<usize>> {
    let mut planned = Vec::with_capacity(joints.len());
    for (j, &(lo, hi)) in joints.iter().zip(limits) {
        let i = tree
            .joint_index(j)
            .ok_or_else(|| invalid("planned joints", format!("{j:?} is no movable joint")))?;
        if planned.contains(&i) {
            return Err(invalid("planned joints", format!("{j:?} twice")));
        }
        if !(lo.is_finite() && hi.is_finite() && lo < hi && hi - lo <= 4.0 * std::f64::consts::PI) {
            return Err(invalid(
                format!("limits of {j}"),
                format!("[{lo}, {hi}] is not a finite range of at most 4π"),
            ));
        }
        planned.push(i);
    }
    Ok(planned)
}

/// Every tree joint's range: `limits` for the `planned` ones, the URDF's for the others (±π
/// for continuous joints, nothing for joints without finite limits).
fn all_limits(
    tree: &LinkTree,
    urdf: &urdf_rs::Robot,
    planned: &[usize],
    limits: &[(f64, f64)],
) -> Vec<(f64, f64)> {
    tree.joints()
        .iter()
        .enumerate()
        .map(|(i, j)| {
            if let Some(k) = planned.iter().position(|&p| p == i) {
                return limits[k];
            }
            let u = urdf.joints.iter().find(|u| u.name == j.name);
            match u {
                Some(u) if matches!(u.joint_type, urdf_rs::JointType::Continuous) => {
                    (-std::f64::consts::PI, std::f64::consts::PI)
                }
                Some(u)
                    if u.limit.lower.is_finite()
                        && u.limit.upper.is_finite()
                        && u.limit.lower <= u.limit.upper =>
                {
                    (u.limit.lower, u.limit.upper)
                }
                _ => (0.0, 0.0),
            }
        })
        .collect()
}

impl CollisionModel {
    /// The model of `urdf` for planning `joints` (URDF names, in path order) within `limits`
    /// (rad or m, one `(min, max)` per joint); meshes are read relative to `dir`. The
    /// self-collision matrix is `acm`, or computed by sampling when `None`.
    pub fn new(
        name: &str,
        urdf: &urdf_rs::Robot,
        joints: &[String],
        limits: &[(f64, f64)],
        dir: Option<&Path>,
        acm: Option<SelfCollisionMatrix>,
    ) -> Result<Self> {
        let tree = LinkTree::from_urdf(urdf).map_err(|e| invalid("URDF", e.to_string()))?;
        if joints.is_empty() || joints.len() != limits.len() {
            return Err(invalid(
                "planned joints",
                format!("{} joints and {} limits", joints.len(), limits.len()),
            ));
        }
        let planned = planned_joints(&tree, joints, limits)?;
        let links = urdf_geometry(urdf, dir)?;
        let n = links.len();
        let moved = tree.links_moved_by(&planned);
        let mut moving = vec![false; n];
        for &l in &moved {
            moving[l] = true;
        }
        let all_limits = all_limits(&tree, urdf, &planned, limits);
        let mut model = CollisionModel {
            all_limits,
            name: name.to_string(),
            values: vec![0.0; tree.joints().len()],
            tree,
            links,
            planned,
            joint_names: joints.to_vec(),
            limits: limits.to_vec(),
            moving,
            moved,
            acm: SelfCollisionMatrix::default(),
            urdf_file: None,
        };
        model.acm = match acm {
            Some(a) => a,
            None => SelfCollisionMatrix::compute(&model, crate::acm::DEFAULT_SAMPLES, 1),
        };
        Ok(model)
    }

    /// The model of a robot's arm: its arm joints within their limits, the fingers and other
    /// joints at 0 until [`CollisionModel::set_value`], the stored self-collision matrix
    /// (`[collision]` of its configuration) or one computed by sampling.
    pub fn from_config(cfg: &RobotConfig) -> Result<Self> {
        let arm = cfg
            .arm
            .as_ref()
            .ok_or_else(|| invalid("robot", format!("{} has no arm", cfg.name)))?;
        let limits = arm
            .joints
            .iter()
            .map(|n| {
                cfg.joint_index(n)
                    .map(|i| {
                        let l = cfg.joints[i].limits;
                        (f64::from(l.min), f64::from(l.max))
                    })
                    .ok_or_else(|| invalid("arm joints", format!("{n:?} not in the joint table")))
            })
            .collect::<Result<Vec<_>>>()?;
        let dir = config_dir(cfg);
        let acm = cfg
            .collision
            .as_ref()
            .map(|c| SelfCollisionMatrix::from_entries(&c.disabled));
        let mut m = CollisionModel::new(&cfg.name, &cfg.urdf, &arm.joints, &limits, dir, acm)?;
        m.urdf_file = dir.map(|d| d.join(&cfg.urdf_file));
        Ok(m)
    }

    /// Robot name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The URDF file the model came from, when it came from a file (not a bundled robot).
    pub fn urdf_file(&self) -> Option<&Path> {
        self.urdf_file.as_deref()
    }

    /// The link tree.
    pub fn tree(&self) -> &LinkTree {
        &self.tree
    }

    /// Every link's geometry, in [`LinkTree::links`] order.
    pub fn links(&self) -> &[LinkGeometry] {
        &self.links
    }

    /// Index of a link by name.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.tree.link_index(name)
    }

    /// Number of planned joints.
    pub fn dof(&self) -> usize {
        self.planned.len()
    }

    /// Planned joint names, in path order.
    pub fn joint_names(&self) -> &[String] {
        &self.joint_names
    }

    /// Limits of the planned joints, rad or m.
    pub fn limits(&self) -> &[(f64, f64)] {
        &self.limits
    }

    /// Every movable joint's range ([`LinkTree::joints`] order): planned joints' limits, the
    /// URDF's for the others (±π for continuous joints).
    pub fn all_limits(&self) -> Vec<(f64, f64)> {
        self.all_limits.clone()
    }

    /// Whether link `i` moves with the planned joints.
    pub fn is_moving(&self, i: usize) -> bool {
        self.moving.get(i).copied().unwrap_or(false)
    }

    /// Lets links `a` and `b` touch (adds the pair to the self-collision matrix as touching by
    /// default).
    pub fn allow_pair(&mut self, a: &str, b: &str) {
        self.acm.allow(a, b);
    }

    /// The self-collision matrix.
    pub fn acm(&self) -> &SelfCollisionMatrix {
        &self.acm
    }

    /// Sets the value (rad or m) a joint that is not planned keeps while planning (a finger,
    /// the head): within the joint's limits (a joint whose range is a whole turn, as a
    /// continuous joint's, takes any angle, wrapped into it). Unknown names, planned joints,
    /// non-finite values and values beyond the limits are errors that change nothing.
    pub fn set_value(&mut self, joint: &str, value: f64) -> Result<()> {
        let i = self.unplanned(joint)?;
        let (lo, hi) = self.all_limits[i];
        let v = if Self::whole_turn((lo, hi)) && value.is_finite() && value.abs() <= 1e6 {
            ferrobot_geometry::wrap(value)
        } else {
            value
        };
        if !(v.is_finite() && lo - 1e-9 <= v && v <= hi + 1e-9) {
            return Err(invalid(
                format!("value of {joint}"),
                format!("{value} is not within its limits [{lo}, {hi}]"),
            ));
        }
        self.values[i] = v.clamp(lo, hi);
        Ok(())
    }

    /// [`CollisionModel::set_value`] for a measured value, which may sit a little past a
    /// limit (a servo's overshoot, a finger's encoder): held to the limits rather than
    /// refused. Only a non-finite value is an error.
    pub fn set_measured_value(&mut self, joint: &str, value: f64) -> Result<()> {
        let i = self.unplanned(joint)?;
        if !value.is_finite() {
            return Err(invalid(format!("value of {joint}"), format!("{value}")));
        }
        let (lo, hi) = self.all_limits[i];
        let held = if Self::whole_turn((lo, hi)) {
            ferrobot_geometry::wrap(value.clamp(-1e6, 1e6))
        } else {
            value.clamp(lo, hi)
        };
        self.set_value(joint, held)
    }

    /// The tree index of `joint`, a movable joint that is not planned.
    fn unplanned(&self, joint: &str) -> Result<usize> {
        let i = self
            .tree
            .joint_index(joint)
            .ok_or_else(|| invalid("joint", format!("{joint:?} is no movable joint")))?;
        if self.planned.contains(&i) {
            return Err(invalid("joint", format!("{joint:?} is planned")));
        }
        Ok(i)
    }

    /// Whether a range is a whole turn, [−π, π] (a continuous joint's here).
    fn whole_turn((lo, hi): (f64, f64)) -> bool {
        lo == -std::f64::consts::PI && hi == std::f64::consts::PI
    }

    /// The values of the joints that are not planned, by name.
    pub fn fixed_values(&self) -> Vec<(String, f64)> {
        self.tree
            .joints()
            .iter()
            .enumerate()
            .filter(|(i, _)| !self.planned.contains(i))
            .map(|(i, j)| (j.name.clone(), self.values[i]))
            .collect()
    }

    /// Every tree joint's value for planned joint values `q`.
    pub fn tree_values(&self, q: &[f64]) -> Vec<f64> {
        let mut v = self.values.clone();
        for (&i, &x) in self.planned.iter().zip(q) {
            v[i] = x;
        }
        v
    }

    /// Every tree joint's value for planned values `q`, into `out`.
    pub(crate) fn tree_values_into(&self, q: &[f64], out: &mut Vec<f64>) {
        out.clear();
        out.extend_from_slice(&self.values);
        for (&i, &x) in self.planned.iter().zip(q) {
            out[i] = x;
        }
    }

    /// Pose of every link in the root frame for planned joint values `q`, into `poses`:
    /// only the links the planned joints move are computed when `poses` already holds every
    /// link's pose from an earlier call (the other links never move), and none when that call
    /// was for the same `q` (an edge's start is measured right after the edge is begun there).
    /// `values` holds the tree's joint values of the last call.
    pub(crate) fn link_poses_into(
        &self,
        q: &[f64],
        values: &mut Vec<f64>,
        poses: &mut Vec<Isometry3<f64>>,
    ) {
        let complete = poses.len() == self.links.len() && values.len() == self.values.len();
        if complete
            && q.len() == self.planned.len()
            && self.planned.iter().zip(q).all(|(&i, &x)| values[i] == x)
        {
            return;
        }
        self.tree_values_into(q, values);
        if complete {
            self.tree.update_poses(values, &self.moved, poses);
        } else {
            self.tree.poses_into(values, poses);
        }
    }

    /// Pose of every link in the root frame for planned joint values `q`.
    pub fn link_poses(&self, q: &[f64]) -> Vec<Isometry3<f64>> {
        self.tree.poses(&self.tree_values(q))
    }

    /// The exact shapes of link `l` placed at `pose`: parry pose and shape.
    pub(crate) fn exact_at<'a>(
        &'a self,
        l: usize,
        pose: &'a Isometry3<f64>,
    ) -> impl Iterator<Item = (parry3d::math::Pose, &'a Exact)> + 'a {
        self.links[l]
            .exact
            .iter()
            .map(move |(o, e)| (convert::pose(&(pose * o)), e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrobot_description::RobotConfig;

    /// A joint that is not planned takes values within its limits only, as the problems
    /// files' `fixed_joints` give them (a LoCoBot finger at 12 m was accepted); a whole-turn
    /// joint any angle, wrapped; measured values are held to the limits. Refusals change
    /// nothing. Every bundled robot's unplanned joints start within their limits, so an
    /// export's `fixed_joints` read back.
    #[test]
    fn unplanned_joints_keep_values_within_their_limits() {
        for robot in ["locobot", "locobot_lite", "sawyer"] {
            let cfg = RobotConfig::bundled(robot).expect(robot);
            let mut model = CollisionModel::from_config(&cfg).expect("model");
            let fixed = model.fixed_values();
            assert!(!fixed.is_empty(), "{robot}");
            for (name, v) in &fixed {
                let i = model.tree.joint_index(name).expect("joint");
                let (lo, hi) = model.all_limits[i];
                assert!(
                    lo <= *v && *v <= hi,
                    "{robot} {name}: {v} not in [{lo}, {hi}]"
                );
                model.set_value(name, *v).expect("its own value");
            }
        }
        let cfg = RobotConfig::bundled("locobot").expect("locobot");
        let mut model = CollisionModel::from_config(&cfg).expect("model");
        // A finger (prismatic, its URDF's range [0, 1] m).
        let finger = "joint_7".to_string();
        let i = model.tree.joint_index(&finger).expect("joint");
        let (lo, hi) = model.all_limits[i];
        assert_eq!((lo, hi), (0.0, 1.0));
        model.set_value(&finger, hi).expect("its limit");
        for bad in [12.0, hi + 1e-3, lo - 1e-3, f64::NAN, f64::INFINITY] {
            let err = model.set_value(&finger, bad).expect_err("refused");
            assert!(err.to_string().contains(&finger), "{err}");
            assert_eq!(model.values[i], hi, "{bad}");
        }
        model.set_measured_value(&finger, hi + 1e-3).expect("held");
        assert_eq!(model.values[i], hi);
        model.set_measured_value(&finger, -5.0).expect("held");
        assert_eq!(model.values[i], lo);
        assert!(model.set_measured_value(&finger, f64::NAN).is_err());
        assert!(model.set_value("joint_1", 0.0).is_err(), "planned");
        assert!(model.set_value("no_such_joint", 0.0).is_err());
        // A whole-turn range (the wheels are continuous) takes any angle, wrapped into it.
        model.set_value("wheel_left_joint", 7.0).expect("any angle");
        let w = model.tree.joint_index("wheel_left_joint").expect("wheel");
        assert!((model.values[w] - (7.0 - 2.0 * std::f64::consts::PI)).abs() < 1e-12);
    }

    /// Poses into reused buffers equal poses computed afresh, whether the joint values change,
    /// repeat (nothing recomputed) or come back.
    #[test]
    fn poses_into_reused_buffers_follow_every_change() {
        let cfg = RobotConfig::bundled("sawyer").expect("sawyer");
        let model = CollisionModel::from_config(&cfg).expect("model");
        let dof = model.dof();
        let q1: Vec<f64> = (0..dof).map(|i| 0.1 * i as f64 - 0.2).collect();
        let mut q2 = q1.clone();
        q2[dof - 1] += 0.3;
        q2[0] -= 0.5;
        let (mut values, mut poses) = (Vec::new(), Vec::new());
        for q in [&q1, &q2, &q2, &q1, &q1, &q2] {
            model.link_poses_into(q, &mut values, &mut poses);
            let fresh = model.link_poses(q);
            assert_eq!(poses.len(), fresh.len());
            for (a, b) in poses.iter().zip(&fresh) {
                assert!((a.translation.vector - b.translation.vector).norm() < 1e-12);
                assert!(a.rotation.angle_to(&b.rotation) < 1e-9);
            }
        }
        // Not vacuous: the two settings put some link elsewhere.
        let (p1, p2) = (model.link_poses(&q1), model.link_poses(&q2));
        assert!(p1
            .iter()
            .zip(&p2)
            .any(|(a, b)| (a.translation.vector - b.translation.vector).norm() > 0.05));
    }
}
