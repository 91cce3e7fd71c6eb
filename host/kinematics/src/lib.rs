//! Kinematics of serial chains read from a URDF: forward kinematics to any frame of the chain,
//! the geometric Jacobian, FK velocity, and inverse kinematics ([`ik`]).
//!
//! Frames are right-handed; poses are `nalgebra::Isometry3<f64>` of the chain's tip in its base
//! frame; Jacobian rows are (vx, vy, vz, ωx, ωy, ωz) in the base frame, taken at the tip's
//! origin; quaternions are `[x, y, z, w]` wherever they appear as arrays.

#![warn(missing_docs)]

pub mod error;
pub mod ik;
pub mod locobot_ik;
pub mod tree;

pub use error::{Error, Result};
pub use tree::{check_urdf, LinkTree, TreeJoint};

use nalgebra::{Isometry3, Matrix6xX, Translation3, UnitQuaternion, Vector3, Vector6};

/// How a chain joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointType {
    /// Rotation about the axis, rad.
    Revolute,
    /// Translation along the axis, m.
    Prismatic,
}

/// A movable joint of a chain.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainJoint {
    /// URDF name.
    pub name: String,
    /// Type.
    pub kind: JointType,
    /// Unit axis in the joint frame.
    pub axis: Vector3<f64>,
    /// Transform from the previous movable joint's frame (or the base) to this joint's frame
    /// at zero, fixed joints in between folded in.
    pub origin: Isometry3<f64>,
    /// Lower limit, rad or m.
    pub lower: f64,
    /// Upper limit, rad or m.
    pub upper: f64,
    /// Speed limit, rad/s or m/s.
    pub velocity: f64,
}

/// A serial chain from a base link to a tip link.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    /// Base link.
    pub base: String,
    /// Tip link.
    pub tip: String,
    /// Movable joints, base to tip.
    pub joints: Vec<ChainJoint>,
    /// Transform from the last movable joint's frame to the tip.
    pub tip_offset: Isometry3<f64>,
}

/// A URDF origin as an isometry: translation, then fixed-axis roll-pitch-yaw.
pub fn pose_from_urdf(p: &urdf_rs::Pose) -> Isometry3<f64> {
    let r = UnitQuaternion::from_euler_angles(p.rpy[0], p.rpy[1], p.rpy[2]);
    Isometry3::from_parts(Translation3::new(p.xyz[0], p.xyz[1], p.xyz[2]), r)
}

/// The joints from `base` down to `tip` in `urdf`, base first: walked up from the tip.
fn path_between<'a>(
    urdf: &'a urdf_rs::Robot,
    base: &str,
    tip: &str,
) -> Result<Vec<&'a urdf_rs::Joint>> {
    let mut path = Vec::new();
    let mut link = tip.to_string();
    while link != base {
        let j = urdf
            .joints
            .iter()
            .find(|j| j.child.link == link)
            .ok_or_else(|| Error::Unreachable {
                why: format!("{base} is not an ancestor of {tip} in the URDF"),
            })?;
        path.push(j);
        link = j.parent.link.clone();
        if path.len() > urdf.joints.len() {
            return Err(Error::Unreachable {
                why: "the URDF has a cycle".into(),
            });
        }
    }
    path.reverse();
    Ok(path)
}

/// The chain joint of URDF joint `j` with `origin` from the previous chain joint's frame (or
/// the base's), or `None` for a fixed joint; an error for a joint a chain cannot hold.
fn chain_joint(
    j: &urdf_rs::Joint,
    origin: Isometry3<f64>,
    base: &str,
    tip: &str,
) -> Result<Option<ChainJoint>> {
    let kind = match j.joint_type {
        urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => JointType::Revolute,
        urdf_rs::JointType::Prismatic => JointType::Prismatic,
        urdf_rs::JointType::Fixed => return Ok(None),
        _ => {
            return Err(Error::Unreachable {
                why: format!(
                    "joint {} between {base} and {tip} is {:?}: a chain holds revolute, \
                         continuous, prismatic and fixed joints",
                    j.name, j.joint_type
                ),
            })
        }
    };
    if let Some(m) = &j.mimic {
        // A chain's joints are independent values (IK's unknowns); one that follows
        // another is not.
        return Err(Error::Unreachable {
            why: format!(
                "joint {} between {base} and {tip} mimics joint {}: a chain's joints \
                     move independently",
                j.name, m.joint
            ),
        });
    }
    let (lower, upper) = if j.joint_type == urdf_rs::JointType::Continuous {
        (-std::f64::consts::TAU, std::f64::consts::TAU)
    } else {
        (j.limit.lower, j.limit.upper)
    };
    let a = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
    Ok(Some(ChainJoint {
        name: j.name.clone(),
        kind,
        axis: a.try_normalize(1e-12).unwrap_or(Vector3::z()),
        origin,
        lower,
        upper,
        velocity: j.limit.velocity,
    }))
}

impl Chain {
    /// The chain from `base` to `tip` in `urdf`.
    pub fn from_urdf(urdf: &urdf_rs::Robot, base: &str, tip: &str) -> Result<Self> {
        let unknown = |n: &str| Error::UnknownName {
            what: "frame",
            name: n.to_string(),
        };
        if !urdf.links.iter().any(|l| l.name == base) {
            return Err(unknown(base));
        }
        if !urdf.links.iter().any(|l| l.name == tip) {
            return Err(unknown(tip));
        }
        let path = path_between(urdf, base, tip)?;
        let mut joints = Vec::new();
        let mut acc = Isometry3::identity();
        for j in path {
            acc *= pose_from_urdf(&j.origin);
            let Some(joint) = chain_joint(j, acc, base, tip)? else {
                continue;
            };
            joints.push(joint);
            acc = Isometry3::identity();
        }
        Ok(Chain {
            base: base.to_string(),
            tip: tip.to_string(),
            joints,
            tip_offset: acc,
        })
    }

    /// Number of movable joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    fn motion(j: &ChainJoint, q: f64) -> Isometry3<f64> {
        match j.kind {
            JointType::Revolute => Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_scaled_axis(j.axis * q),
            ),
            JointType::Prismatic => {
                Isometry3::from_parts(Translation3::from(j.axis * q), UnitQuaternion::identity())
            }
        }
    }

    /// Pose of the tip in the base frame at joint values `q` (`q.len() == dof()`).
    pub fn fk(&self, q: &[f64]) -> Isometry3<f64> {
        let mut t = Isometry3::identity();
        for (j, &qi) in self.joints.iter().zip(q) {
            t *= j.origin * Self::motion(j, qi);
        }
        t * self.tip_offset
    }

    /// Tip pose and, for each joint, its axis and origin in the base frame.
    pub fn fk_with_axes(
        &self,
        q: &[f64],
        axes: &mut [(Vector3<f64>, Vector3<f64>)],
    ) -> Isometry3<f64> {
        let mut t = Isometry3::identity();
        for ((j, &qi), slot) in self.joints.iter().zip(q).zip(axes.iter_mut()) {
            t *= j.origin;
            *slot = (t.rotation * j.axis, t.translation.vector);
            t *= Self::motion(j, qi);
        }
        t * self.tip_offset
    }

    /// Geometric Jacobian at `q`: rows (vx, vy, vz, ωx, ωy, ωz) in the base frame at the tip's
    /// origin, one column per joint.
    pub fn jacobian(&self, q: &[f64]) -> Matrix6xX<f64> {
        let n = self.dof();
        let mut axes = vec![(Vector3::zeros(), Vector3::zeros()); n];
        let tip = self.fk_with_axes(q, &mut axes);
        let p = tip.translation.vector;
        let mut jac = Matrix6xX::zeros(n);
        for (c, (j, (z, o))) in self.joints.iter().zip(&axes).enumerate() {
            let col: Vector6<f64> = match j.kind {
                JointType::Revolute => {
                    let v = z.cross(&(p - o));
                    Vector6::new(v.x, v.y, v.z, z.x, z.y, z.z)
                }
                JointType::Prismatic => Vector6::new(z.x, z.y, z.z, 0.0, 0.0, 0.0),
            };
            jac.set_column(c, &col);
        }
        jac
    }

    /// Twist of the tip (vx, vy, vz, ωx, ωy, ωz) in the base frame at joint speeds `qd`.
    pub fn fk_velocity(&self, q: &[f64], qd: &[f64]) -> Vector6<f64> {
        let jac = self.jacobian(q);
        let mut out = Vector6::zeros();
        for (c, &v) in qd.iter().enumerate().take(self.dof()) {
            out += jac.column(c) * v;
        }
        out
    }

    /// Whether `q` is within the joint limits (with slack `eps`).
    pub fn within_limits(&self, q: &[f64], eps: f64) -> bool {
        self.joints
            .iter()
            .zip(q)
            .all(|(j, &v)| v >= j.lower - eps && v <= j.upper + eps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bundled Sawyer's URDF and its arm chain, base to hand.
    fn sawyer() -> (urdf_rs::Robot, Chain) {
        let text = include_str!("../../description/robots/sawyer.urdf");
        let urdf = urdf_rs::read_from_string(text).expect("urdf");
        let chain = Chain::from_urdf(&urdf, "base", "right_hand").expect("chain");
        (urdf, chain)
    }

    /// A chain built straight from a URDF whose limits are absent (infinite) or inverted is
    /// refused by the numerical IK with a typed error (the restarts' draw once panicked); a
    /// floating joint between base and tip is refused when the chain is built.
    #[test]
    fn chains_with_unusable_joints_are_errors_not_panics() {
        use crate::ik::{IkOptions, IkSolver, NumericalIk};
        let (urdf, good) = sawyer();
        // Out of reach: the solver restarts until its budget runs out.
        let far = Isometry3::translation(5.0, 0.0, 0.0);
        let opts = IkOptions::default();
        for (lo, hi) in [
            (f64::NEG_INFINITY, f64::INFINITY),
            (1.0, -1.0),
            (f64::NAN, 1.0),
        ] {
            let mut chain = good.clone();
            chain.joints[2].lower = lo;
            chain.joints[2].upper = hi;
            let err = NumericalIk
                .solve(&chain, &far, None, &opts)
                .expect_err("refused");
            assert!(err.to_string().contains("limits"), "{err}");
        }
        let mut floating = urdf.clone();
        let j = floating
            .joints
            .iter_mut()
            .find(|j| j.name == "right_j3")
            .expect("right_j3");
        j.joint_type = urdf_rs::JointType::Floating;
        let err = Chain::from_urdf(&floating, "base", "right_hand").expect_err("refused");
        assert!(err.to_string().contains("right_j3"), "{err}");
    }

    /// The default budget is a count of descents, not a time: an unreachable target ends
    /// after exactly that many however fast the machine is (a 5 ms budget made 163 here, and
    /// fewer on a busy machine), and no attempt at all is refused.
    #[test]
    fn the_default_budget_is_a_count_of_attempts() {
        use crate::ik::{IkOptions, IkSolver, NumericalIk, DEFAULT_ATTEMPTS};
        let (_, chain) = sawyer();
        let far = Isometry3::translation(5.0, 0.0, 0.0);
        let err = NumericalIk
            .solve(&chain, &far, None, &IkOptions::default())
            .expect_err("out of reach");
        assert!(
            err.to_string()
                .contains(&format!("({DEFAULT_ATTEMPTS} made)")),
            "{err}"
        );
        let none = IkOptions {
            attempts: 0,
            ..IkOptions::default()
        };
        let err = NumericalIk
            .solve(&chain, &far, None, &none)
            .expect_err("refused");
        assert!(err.to_string().contains("IK attempts"), "{err}");
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let (_, chain) = sawyer();
        let q = [0.3, -0.7, 0.4, 1.2, -0.5, 0.8, 2.0];
        let j = chain.jacobian(&q);
        let h = 1e-7;
        for c in 0..7 {
            let mut qp = q;
            qp[c] += h;
            let a = chain.fk(&q);
            let b = chain.fk(&qp);
            let dv = (b.translation.vector - a.translation.vector) / h;
            let dw = (b.rotation * a.rotation.inverse()).scaled_axis() / h;
            for r in 0..3 {
                assert!((j[(r, c)] - dv[r]).abs() < 1e-5, "v col {c}");
                assert!((j[(r + 3, c)] - dw[r]).abs() < 1e-5, "w col {c}");
            }
        }
    }
}
