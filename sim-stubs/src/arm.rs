//! Gravity load on a serial arm from its link masses, for the simulated servos.
//!
//! Each link hangs off a revolute joint; the torque gravity exerts about joint `i` is
//! `τᵢ = aᵢ · Σₖ≥ᵢ (cₖ − oᵢ) × mₖ·g`, with `aᵢ` and `oᵢ` the joint's axis and origin and `cₖ`
//! the centre of mass of link `k`, all in the arm's base frame (z up). The chain comes from
//! the robot's description ([`crate::robots::from_description`]).

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};

/// One joint of the chain and the link it carries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmJoint {
    /// Joint origin in the parent link's frame, m.
    pub origin: [f64; 3],
    /// Fixed rotation of the joint frame, roll-pitch-yaw (URDF convention), rad.
    pub rpy: [f64; 3],
    /// Joint axis in the joint frame (unit vector).
    pub axis: [f64; 3],
    /// Mass of the child link (and everything rigidly attached), kg.
    pub mass: f64,
    /// Centre of mass of the child link in the joint frame, m.
    pub com: [f64; 3],
}

/// Gravity torque (N·m) about each joint at joint angles `q` (rad): `out[i]` for the first
/// `min(chain.len(), q.len(), out.len())` joints, in the arm's base frame with gravity along
/// −z at 9.81 m/s².
pub fn gravity_torques(chain: &[ArmJoint], q: &[f64], out: &mut [f64]) {
    let gravity = Vector3::new(0.0, 0.0, -9.81);
    let n = chain.len().min(q.len()).min(out.len());
    // Forward pass: each joint's origin and axis, and each link's centre of mass, in the base
    // frame.
    let mut pose = Isometry3::identity();
    let mut frames: Vec<(Vector3<f64>, Vector3<f64>, Vector3<f64>)> = Vec::with_capacity(n);
    for (j, &qi) in chain.iter().zip(q).take(n) {
        let [r, p, y] = j.rpy;
        pose *= Isometry3::from_parts(
            Translation3::from(Vector3::from(j.origin)),
            UnitQuaternion::from_euler_angles(r, p, y),
        );
        let axis = Vector3::from(j.axis);
        let origin = pose.translation.vector;
        let axis_world = pose.rotation * axis;
        if let Some(unit) = Unit::try_new(axis, 1e-12) {
            pose *= UnitQuaternion::from_axis_angle(&unit, qi);
        }
        let com = pose
            .transform_point(&Point3::from(Vector3::from(j.com)))
            .coords;
        frames.push((origin, axis_world, com));
    }
    // τᵢ = aᵢ · Σₖ≥ᵢ (cₖ − oᵢ) × mₖ·g.
    for (i, (o, a, _)) in frames.iter().enumerate() {
        out[i] = frames
            .iter()
            .zip(chain)
            .skip(i)
            .map(|((_, _, c), link)| a.dot(&(c - o).cross(&(gravity * link.mass))))
            .sum();
    }
}
