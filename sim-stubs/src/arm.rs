//! Gravity load on a serial arm from its link masses, for the simulated servos.
//!
//! Each link hangs off a revolute joint; the torque gravity exerts about joint `i` is
//! `τᵢ = aᵢ · Σₖ≥ᵢ (cₖ − oᵢ) × mₖ·g`, with `aᵢ` and `oᵢ` the joint's axis and origin and `cₖ`
//! the centre of mass of link `k`, all in the arm's base frame (z up).

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

/// The LoCoBot arm (joint_1 … joint_5): the firmware's gravity model
/// ([`ferrobot_firmware::config::LOCOBOT_GRAVITY`], checked against the bundled description),
/// so the simulated arm has the description's masses. The hostile checker may perturb them.
pub fn locobot_arm() -> Vec<ArmJoint> {
    ferrobot_firmware::config::LOCOBOT_GRAVITY
        .links
        .iter()
        .map(|l| {
            let l = l.to_f64();
            ArmJoint {
                origin: l.origin,
                rpy: [0.0; 3],
                axis: l.axis,
                mass: l.mass,
                com: l.com,
            }
        })
        .collect()
}

type M3 = [[f64; 3]; 3];

fn mul(a: &M3, b: &M3) -> M3 {
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}

fn apply(a: &M3, v: &[f64; 3]) -> [f64; 3] {
    [
        a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2],
        a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
        a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2],
    ]
}

fn axis_angle(axis: &[f64; 3], q: f64) -> M3 {
    let [x, y, z] = *axis;
    let (s, c) = q.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Gravity torque (N·m) about each joint at joint angles `q` (rad); `out.len() == chain.len()`.
pub fn gravity_torques(chain: &[ArmJoint], q: &[f64], out: &mut [f64]) {
    const G: [f64; 3] = [0.0, 0.0, -9.81];
    let n = chain.len().min(q.len()).min(out.len());
    let mut rot: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut pos = [0.0; 3];
    let mut origins = [[0.0; 3]; 8];
    let mut axes = [[0.0; 3]; 8];
    let mut coms = [[0.0; 3]; 8];
    for i in 0..n.min(8) {
        let j = &chain[i];
        pos = add(pos, apply(&rot, &j.origin));
        if j.rpy != [0.0; 3] {
            let [r, p, y] = j.rpy;
            let fixed = mul(
                &axis_angle(&[0.0, 0.0, 1.0], y),
                &mul(
                    &axis_angle(&[0.0, 1.0, 0.0], p),
                    &axis_angle(&[1.0, 0.0, 0.0], r),
                ),
            );
            rot = mul(&rot, &fixed);
        }
        origins[i] = pos;
        axes[i] = apply(&rot, &j.axis);
        rot = mul(&rot, &axis_angle(&j.axis, q[i]));
        coms[i] = add(pos, apply(&rot, &j.com));
    }
    for i in 0..n.min(8) {
        let mut tau = 0.0;
        for k in i..n.min(8) {
            let f = [
                G[0] * chain[k].mass,
                G[1] * chain[k].mass,
                G[2] * chain[k].mass,
            ];
            tau += dot(axes[i], cross(sub(coms[k], origins[i]), f));
        }
        out[i] = tau;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shoulder_load_matches_a_hand_calculation() {
        // At zero angles the upper arm stands vertical and the forearm points along +x. About
        // joint_2 (axis +y), gravity's torque is g · Σ m·x over the links it carries:
        // 0.21248·0.009598 + 0.18746·(0.05+0.11783) + 0.06059·(0.05+0.2002+0.04294)
        // + 0.12421·(0.05+0.2002+0.063+0.040623) = 0.09522 kg·m.
        let mut t = [0.0; 5];
        gravity_torques(&locobot_arm(), &[0.0; 5], &mut t);
        assert!((t[1] - 0.09522 * 9.81).abs() < 1e-3, "{}", t[1]);
        // Yaw never carries gravity load; folding the forearm up (joint_3 = −π/2) shortens the
        // lever of joint_2.
        assert!(t[0].abs() < 1e-12);
        let mut folded = [0.0; 5];
        gravity_torques(
            &locobot_arm(),
            &[0.0, 0.0, -std::f64::consts::FRAC_PI_2, 0.0, 0.0],
            &mut folded,
        );
        assert!(folded[1] < 0.3 * t[1], "{}", folded[1]);
    }
}
