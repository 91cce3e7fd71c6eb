//! Closed-form IK of the LoCoBot arm family: joint 1 yaws about z, joints 2-4 pitch about y,
//! joint 5 rolls about the gripper's x axis. The geometry (link offsets, the 0.1 mm lateral
//! offset of the wrist) is read from the chain, so the same solver serves every arm of the
//! family on any mount.
//!
//! Conventions: `pitch` is the angle of the gripper's x axis below the horizontal plane of the
//! arm (π/2 points straight down); `roll` is the rotation about the gripper's own x axis,
//! right-handed. The end-effector orientation is `Rz(yaw)·Ry(pitch)·Rx(roll)` in the frame of
//! joint 1, with yaw set by where the target is.

use ferrobot_geometry::wrap;
use nalgebra::{Isometry3, Rotation3, Vector3};

use super::ik::{pose_error, IkOptions, IkSolver};
use super::{Chain, JointType};
use crate::error::{Error, Result};

/// The arm's geometry in the plane of joints 2-4.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocobotIk {
    /// Base frame to joint 1's frame.
    base_to_j1: Isometry3<f64>,
    /// Joint 2's origin in joint 1's frame (x, z).
    o2: (f64, f64),
    /// Joint 2 to joint 3: length and direction angle (from +z towards +x) at zero.
    la: f64,
    ba: f64,
    /// Joint 3 to joint 4.
    lb: f64,
    bb: f64,
    /// Joint 4 to the tip (x, z) in joint 4's frame.
    last: (f64, f64),
    /// Lateral (y) offset of the tip from the arm plane, m.
    d: f64,
}

fn same_dir(a: &Vector3<f64>, b: Vector3<f64>) -> bool {
    (a - b).norm() < 1e-9
}

impl LocobotIk {
    /// Read the geometry from a 5-joint chain of the family; an error names what does not fit.
    pub fn from_chain(chain: &Chain) -> Result<Self> {
        let bad = |why: &str| Error::Unreachable {
            why: format!("the closed-form LoCoBot solver does not fit this chain: {why}"),
        };
        if chain.dof() != 5 || chain.joints.iter().any(|j| j.kind != JointType::Revolute) {
            return Err(bad("needs 5 revolute joints"));
        }
        let j = &chain.joints;
        let axes_ok = same_dir(&j[0].axis, Vector3::z())
            && (1..4).all(|k| same_dir(&j[k].axis, Vector3::y()))
            && (same_dir(&j[4].axis, -Vector3::x()) || same_dir(&j[4].axis, Vector3::x()));
        if !axes_ok {
            return Err(bad("axes must be z, y, y, y, x"));
        }
        if (1..5).any(|k| j[k].origin.rotation.angle() > 1e-12)
            || chain.tip_offset.rotation.angle() > 1e-12
        {
            return Err(bad("joints 2-5 and the tip must not be rotated at zero"));
        }
        let t = |k: usize| j[k].origin.translation.vector;
        let tip = chain.tip_offset.translation.vector;
        if tip.y.abs() > 1e-12 || tip.z.abs() > 1e-12 {
            return Err(bad("the tip must lie on joint 5's axis"));
        }
        let (o3, o4, o5) = (t(2), t(3), t(4));
        Ok(LocobotIk {
            base_to_j1: j[0].origin,
            o2: (t(1).x, t(1).z),
            la: o3.x.hypot(o3.z),
            ba: o3.x.atan2(o3.z),
            lb: o4.x.hypot(o4.z),
            bb: o4.x.atan2(o4.z),
            last: (o5.x + tip.x, o5.z),
            d: t(1).y + o3.y + o4.y + o5.y,
        })
    }

    /// All joint solutions (within limits) for a tip position (base frame), pitch and roll.
    pub fn solutions(
        &self,
        chain: &Chain,
        position: &Vector3<f64>,
        pitch: f64,
        roll: f64,
    ) -> Vec<[f64; 5]> {
        let p = self.base_to_j1.inverse_transform_point(&(*position).into());
        let r2 = p.x * p.x + p.y * p.y - self.d * self.d;
        if r2 < 0.0 {
            return Vec::new();
        }
        let mut out = Vec::new();
        let roll_joint = if same_dir(&chain.joints[4].axis, -Vector3::x()) {
            -roll
        } else {
            roll
        };
        for rho in [r2.sqrt(), -r2.sqrt()] {
            let yaw = p.y.atan2(p.x) - self.d.atan2(rho);
            // Wrist point in the arm plane, relative to joint 2.
            let (lx, lz) = self.last;
            let (s, c) = pitch.sin_cos();
            let wx = rho - (lx * c + lz * s) - self.o2.0;
            let wz = p.z - (-lx * s + lz * c) - self.o2.1;
            let dist2 = wx * wx + wz * wz;
            let cg = (dist2 - self.la * self.la - self.lb * self.lb) / (2.0 * self.la * self.lb);
            if !(-1.0..=1.0).contains(&cg) {
                continue;
            }
            for g in [cg.acos(), -cg.acos()] {
                let bw = wx.atan2(wz);
                let q2 = bw - self.ba - (self.lb * g.sin()).atan2(self.la + self.lb * g.cos());
                let q3 = g - self.bb + self.ba;
                let q4 = pitch - q2 - q3;
                let q = [wrap(yaw), wrap(q2), wrap(q3), wrap(q4), wrap(roll_joint)];
                if chain.within_limits(&q, 1e-9) {
                    out.push(q);
                }
            }
        }
        out
    }

    /// The solution nearest to `seed` (or to zero) for position, pitch and roll.
    pub fn solve_pitch_roll(
        &self,
        chain: &Chain,
        position: &Vector3<f64>,
        pitch: f64,
        roll: f64,
        seed: Option<&[f64]>,
    ) -> Result<Vec<f64>> {
        ferrobot_geometry::validate::arm_point(
            "IK target position",
            [position.x, position.y, position.z],
        )?;
        ferrobot_geometry::validate::angles("pitch and roll", &[pitch, roll])?;
        super::ik::check_seed(chain, seed)?;
        let sols = self.solutions(chain, position, pitch, roll);
        let zero = [0.0; 5];
        let s = seed.unwrap_or(&zero);
        sols.iter()
            .min_by(|a, b| dist(&a[..], s).total_cmp(&dist(&b[..], s)))
            .map(|q| q.to_vec())
            .ok_or_else(|| Error::Unreachable {
                why: format!(
                    "no joint solution within limits reaches ({:.4}, {:.4}, {:.4}) m at pitch {pitch:.4} rad",
                    position.x, position.y, position.z
                ),
            })
    }
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

impl IkSolver for LocobotIk {
    fn solve_valid(
        &self,
        chain: &Chain,
        target: &Isometry3<f64>,
        seed: Option<&[f64]>,
        opts: &IkOptions,
    ) -> Result<Vec<f64>> {
        let pos = target.translation.vector;
        let p = self.base_to_j1.inverse_transform_point(&pos.into());
        let r_j1: Rotation3<f64> =
            (self.base_to_j1.rotation.inverse() * target.rotation).to_rotation_matrix();
        let mut candidates = Vec::new();
        let r2 = (p.x * p.x + p.y * p.y - self.d * self.d).max(0.0);
        for rho in [r2.sqrt(), -r2.sqrt()] {
            let yaw = p.y.atan2(p.x) - self.d.atan2(rho);
            // The orientation must be Rz(yaw)·Ry(pitch)·Rx(roll).
            let m = Rotation3::from_axis_angle(&Vector3::z_axis(), -yaw) * r_j1;
            let m = m.matrix();
            if m[(1, 0)].abs() > opts.orientation_tolerance.max(1e-9) {
                continue;
            }
            let pitch = (-m[(2, 0)]).atan2(m[(0, 0)]);
            let rest = Rotation3::from_axis_angle(&Vector3::y_axis(), -pitch).matrix() * m;
            let roll = rest[(2, 1)].atan2(rest[(1, 1)]);
            for q in self.solutions(chain, &pos, pitch, roll) {
                let e = pose_error(target, &chain.fk(&q));
                if e.fixed_rows::<3>(0).norm() <= opts.position_tolerance
                    && e.fixed_rows::<3>(3).norm() <= opts.orientation_tolerance
                {
                    candidates.push(q);
                }
            }
        }
        let zero = [0.0; 5];
        let s = seed.unwrap_or(&zero);
        candidates
            .iter()
            .min_by(|a, b| dist(&a[..], s).total_cmp(&dist(&b[..], s)))
            .map(|q| q.to_vec())
            .ok_or_else(|| Error::Unreachable {
                why: "a 5-joint LoCoBot arm reaches only orientations whose x axis lies in the vertical plane \
                      through joint 1 and the target, and only within reach and joint limits"
                    .into(),
            })
    }
}
