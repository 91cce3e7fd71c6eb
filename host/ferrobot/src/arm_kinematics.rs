//! The arm's kinematics as the API gives them: the end effector's pose now, forward
//! kinematics, Jacobians and velocities at given joint angles, and inverse kinematics (the
//! configured solver, and the LoCoBot's closed-form pitch-roll solver). Frames: the arm's base
//! frame unless said otherwise; m, rad.

use nalgebra::{Isometry3, Matrix6xX, Translation3, Vector3};

use crate::arm::{Arm, Orientation, Pose};
use crate::error::{Error, Result};
use crate::kinematics::ik::IkOptions;
use crate::validate;

impl Arm {
    /// Pose of the end effector from the measured joint angles.
    pub fn get_ee_pose(&self) -> Result<Pose> {
        let q = self.get_joint_angles()?;
        let ee = self.cfg().ee_frame.clone();
        self.compute_fk_position(&q, &ee)
    }
    pub(crate) fn chain_q(
        &self,
        q: &[f64],
        frame: &str,
    ) -> Result<(crate::kinematics::Chain, Vec<f64>)> {
        self.check_angles("joint positions", q)?;
        let names = self.cfg().joints.clone();
        let chain = (*self.chain_to(frame)?).clone();
        // The frame's chain moves a prefix of the arm's joints (or other joints: not ours).
        let mut sub = Vec::new();
        for j in &chain.joints {
            let k = names
                .iter()
                .position(|n| *n == j.name)
                .ok_or_else(|| Error::UnknownName {
                    what: "frame (its chain moves a joint that is not an arm joint)",
                    name: frame.to_string(),
                })?;
            sub.push(q[k]);
        }
        Ok((chain, sub))
    }
    /// Pose of `frame` (any link of the arm's chain) in the base frame at joint angles `q`.
    pub fn compute_fk_position(&self, q: &[f64], frame: &str) -> Result<Pose> {
        let (chain, sub) = self.chain_q(q, frame)?;
        Ok(chain.fk(&sub).into())
    }
    /// Geometric Jacobian at `q`: rows (vx, vy, vz, ωx, ωy, ωz) in the base frame at the
    /// end effector's origin, one column per arm joint.
    pub fn get_jacobian(&self, q: &[f64]) -> Result<Matrix6xX<f64>> {
        let ee = self.cfg().ee_frame.clone();
        let (chain, sub) = self.chain_q(q, &ee)?;
        Ok(chain.jacobian(&sub))
    }
    /// Twist `[vx, vy, vz, ωx, ωy, ωz]` of the end effector (base frame) at `q` moving at `qd`.
    pub fn compute_fk_velocity(&self, q: &[f64], qd: &[f64]) -> Result<[f64; 6]> {
        self.check_count("joint velocities", qd)?;
        validate::all_in_range(
            "joint velocities",
            qd,
            -(ferrobot_protocol::ranges::JOINT_SPEED_MAX as f64),
            ferrobot_protocol::ranges::JOINT_SPEED_MAX as f64,
        )?;
        let j = self.get_jacobian(q)?;
        let v = j * nalgebra::DVector::from_column_slice(qd);
        Ok([v[0], v[1], v[2], v[3], v[4], v[5]])
    }
    pub(crate) fn ik_options(&self) -> IkOptions {
        let c = self.cfg();
        IkOptions {
            position_tolerance: c.ik_position_tolerance,
            orientation_tolerance: c.ik_orientation_tolerance,
            ..IkOptions::default()
        }
    }
    /// Joint angles that put the end effector at `position` (m) with `orientation`, nearest to
    /// `seed` (default: the current joint angles).
    pub fn compute_ik(
        &self,
        position: [f64; 3],
        orientation: Orientation,
        seed: Option<&[f64]>,
    ) -> Result<Vec<f64>> {
        validate::arm_point("position", position)?;
        let rot = orientation.to_quaternion()?;
        let seed = match seed {
            Some(s) => {
                self.check_angles("IK seed", s)?;
                s.to_vec()
            }
            None => self.get_joint_angles()?,
        };
        let target = Isometry3::from_parts(
            Translation3::new(position[0], position[1], position[2]),
            rot,
        );
        let opts = self.ik_options();
        let chain = self.chain()?;
        let ik = &self.parts().ik;
        Ok(ik.solve(chain, &target, Some(&seed), &opts)?)
    }
    /// 5-DOF arms: joint angles that put the end effector at `position` (m) with gripper
    /// pitch `pitch` (rad below horizontal) and roll `roll` (rad; the seed's when `None`),
    /// nearest to `seed` (default: the current joint angles). The closed-form solver of
    /// [`Arm::set_ee_pose_pitch_roll`], without moving.
    pub fn compute_ik_pitch_roll(
        &self,
        position: [f64; 3],
        pitch: f64,
        roll: Option<f64>,
        seed: Option<&[f64]>,
    ) -> Result<Vec<f64>> {
        let seed = match seed {
            Some(s) => {
                self.check_angles("IK seed", s)?;
                Some(s.to_vec())
            }
            None => None,
        };
        self.ik_pitch_roll(position, pitch, roll, seed)
    }
    pub(crate) fn ik_pitch_roll(
        &self,
        position: [f64; 3],
        pitch: f64,
        roll: Option<f64>,
        seed: Option<Vec<f64>>,
    ) -> Result<Vec<f64>> {
        validate::arm_point("position", position)?;
        validate::angles("pitch", &[pitch])?;
        let solver = self.parts().locobot_ik.ok_or_else(|| Error::Unreachable {
            why: format!(
                "{} has no pitch-roll solver (a 5-DOF LoCoBot-type arm has)",
                self.robot.cfg().name
            ),
        })?;
        let seed = match seed {
            Some(s) => s,
            None => self.get_joint_angles()?,
        };
        // Roll is joint 5 up to its sign (its axis is −x on the LoCoBot).
        let chain = self.chain()?;
        let sign = if chain.joints[4].axis.x < 0.0 {
            -1.0
        } else {
            1.0
        };
        let roll = roll.unwrap_or(sign * seed[4]);
        validate::angles("roll", &[roll])?;
        Ok(solver.solve_pitch_roll(chain, &Vector3::from(position), pitch, roll, Some(&seed))?)
    }
}
