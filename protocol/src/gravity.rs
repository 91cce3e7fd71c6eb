//! Gravity torques on a serial chain of revolute joints, for the firmware (`f32`, its gravity
//! feed-forward), the simulated arm and the host (`f64`).
//!
//! Each [`Link`] is one revolute joint and the rigid body it carries: the joint's origin and
//! fixed rotation (roll-pitch-yaw, as a URDF joint's `<origin>`) in the previous joint's frame
//! (the chain's base frame for the first), its axis in its own frame, and the carried body's
//! mass and centre of mass in the joint's frame. Gravity points along −z of the base frame. The torque
//! gravity exerts about joint `i` is `τᵢ = aᵢ · ((Σₖ≥ᵢ mₖ·cₖ − Mᵢ·oᵢ) × g)` with `aᵢ` and `oᵢ`
//! the joint's axis and origin, `cₖ` the centres of mass and `Mᵢ = Σₖ≥ᵢ mₖ`, all in the base
//! frame. `no_std`, no allocation, no panics: two passes down the chain, nothing stored.

// The arithmetic here is on `Real` (f32, f64) only: floating point neither overflows nor
// panics, so the crate's denial of integer arithmetic side effects does not apply; clippy
// cannot tell a generic float apart.
#![allow(clippy::arithmetic_side_effects)]

use crate::geometry::Real;

/// One joint of the chain and the body it carries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Link<R> {
    /// Joint origin in the parent joint's frame, m.
    pub origin: [R; 3],
    /// Fixed rotation of the joint's frame from its parent's at zero angle: roll, pitch, yaw
    /// about the parent's fixed x, y, z axes (URDF convention), rad.
    pub rpy: [R; 3],
    /// Joint axis in the joint's frame (unit vector).
    pub axis: [R; 3],
    /// Mass of the carried body (everything rigidly attached up to the next joint), kg.
    pub mass: R,
    /// Centre of mass of the carried body in the joint's frame, m.
    pub com: [R; 3],
}

impl Link<f32> {
    /// The same link in `f64` (the tables are written once, in `f32`, for the firmware).
    pub fn to_f64(&self) -> Link<f64> {
        let v = |a: [f32; 3]| [a[0] as f64, a[1] as f64, a[2] as f64];
        Link {
            origin: v(self.origin),
            rpy: v(self.rpy),
            axis: v(self.axis),
            mass: self.mass as f64,
            com: v(self.com),
        }
    }
}

/// Most links an arm's gravity model may have (Sawyer has 7).
pub const MAX_LINKS: usize = 8;

/// Gravity, m/s² (the value the simulated arm uses too).
pub const G: f32 = 9.81;

type V3<R> = [R; 3];
type M3<R> = [[R; 3]; 3];

fn add<R: Real>(a: V3<R>, b: V3<R>) -> V3<R> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale<R: Real>(a: V3<R>, s: R) -> V3<R> {
    [a[0] * s, a[1] * s, a[2] * s]
}

fn apply<R: Real>(m: &M3<R>, v: V3<R>) -> V3<R> {
    let row = |r: [R; 3]| r[0] * v[0] + r[1] * v[1] + r[2] * v[2];
    [row(m[0]), row(m[1]), row(m[2])]
}

fn mul<R: Real>(a: &M3<R>, b: &M3<R>) -> M3<R> {
    let [[b00, b01, b02], [b10, b11, b12], [b20, b21, b22]] = *b;
    let (c0, c1, c2) = (
        apply(a, [b00, b10, b20]),
        apply(a, [b01, b11, b21]),
        apply(a, [b02, b12, b22]),
    );
    [
        [c0[0], c1[0], c2[0]],
        [c0[1], c1[1], c2[1]],
        [c0[2], c1[2], c2[2]],
    ]
}

/// Rotation by `q` about the unit `axis` (Rodrigues).
fn axis_angle<R: Real>(axis: V3<R>, q: R) -> M3<R> {
    let [x, y, z] = axis;
    let (s, c) = (q.sin(), q.cos());
    let t = R::ONE - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

/// The rotation of URDF's roll-pitch-yaw: `Rz(yaw)·Ry(pitch)·Rx(roll)`.
fn rpy_matrix<R: Real>([r, p, y]: V3<R>) -> M3<R> {
    let (o, i) = (R::ZERO, R::ONE);
    let x = axis_angle([i, o, o], r);
    let y_ = axis_angle([o, i, o], p);
    let z = axis_angle([o, o, i], y);
    mul(&z, &mul(&y_, &x))
}

/// Walk the chain at angles `q`, calling `f(i, origin, axis, mass, com)` for each joint with
/// its origin, axis and carried centre of mass in the base frame.
fn walk<R: Real>(links: &[Link<R>], q: &[R], mut f: impl FnMut(usize, V3<R>, V3<R>, R, V3<R>)) {
    let (o, i) = (R::ZERO, R::ONE);
    let mut rot: M3<R> = [[i, o, o], [o, i, o], [o, o, i]];
    let mut pos = [o; 3];
    for (k, (l, &qk)) in links.iter().zip(q).enumerate() {
        pos = add(pos, apply(&rot, l.origin));
        // Most arms (the LoCoBot's) have no fixed rotations: no trigonometry for them.
        if l.rpy.iter().any(|&a| a != R::ZERO) {
            rot = mul(&rot, &rpy_matrix(l.rpy));
        }
        let axis = apply(&rot, l.axis);
        rot = mul(&rot, &axis_angle(l.axis, qk));
        f(k, pos, axis, l.mass, add(pos, apply(&rot, l.com)));
    }
}

/// Gravity torques (N·m) about each joint of `links` at angles `q` (rad) under gravity `g`
/// (m/s², pointing along −z), written to `out`; returns how many were written (the shortest of
/// the three slices). The torque is what gravity exerts on the joint, positive about its axis:
/// a servo holding the joint still gives the opposite.
pub fn torques<R: Real>(links: &[Link<R>], q: &[R], g: R, out: &mut [R]) -> usize {
    // First pass: the whole chain's mass and first moment.
    let (mut total_m, mut total_mc) = (R::ZERO, [R::ZERO; 3]);
    walk(links, q, |_, _, _, m, c| {
        total_m = total_m + m;
        total_mc = add(total_mc, scale(c, m));
    });
    // Second pass: what lies beyond each joint is the total less what lies before it.
    let (mut before_m, mut before_mc) = (R::ZERO, [R::ZERO; 3]);
    let mut n = 0;
    walk(links, q, |k, origin, axis, m, c| {
        let beyond_m = total_m - before_m;
        let r = add(
            [
                total_mc[0] - before_mc[0],
                total_mc[1] - before_mc[1],
                total_mc[2] - before_mc[2],
            ],
            scale(origin, -beyond_m),
        );
        // r × (0, 0, −g) = (−g·r_y, g·r_x, 0).
        let tau = axis[0] * (-g * r[1]) + axis[1] * (g * r[0]);
        if let Some(t) = out.get_mut(k) {
            *t = tau;
            n = k + 1;
        }
        before_m = before_m + m;
        before_mc = add(before_mc, scale(c, m));
    });
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A two-link planar arm, both joints about +y, along +x at zero: the textbook result.
    #[test]
    fn a_planar_two_link_arm_matches_the_textbook() {
        let links = [
            Link {
                origin: [0.0, 0.0, 0.1],
                rpy: [0.0; 3],
                axis: [0.0, 1.0, 0.0],
                mass: 1.0,
                com: [0.2, 0.0, 0.0],
            },
            Link {
                origin: [0.4, 0.0, 0.0],
                rpy: [0.0; 3],
                axis: [0.0, 1.0, 0.0],
                mass: 0.5,
                com: [0.1, 0.0, 0.0],
            },
        ];
        for &(q1, q2) in &[(0.0f64, 0.0f64), (0.3, -0.7), (-1.2, 2.0)] {
            let mut t = [0.0; 2];
            assert_eq!(torques(&links, &[q1, q2], 9.81, &mut t), 2);
            // About +y a point at (x, z) under gravity −z feels g·m·x; a rotation by q about
            // +y takes x along the link to x·cos q.
            let t2 = 9.81 * 0.5 * 0.1 * (q1 + q2).cos();
            let t1 = 9.81 * (1.0 * 0.2 * q1.cos() + 0.5 * (0.4 * q1.cos() + 0.1 * (q1 + q2).cos()));
            assert!(
                (t[0] - t1).abs() < 1e-12 && (t[1] - t2).abs() < 1e-12,
                "{t:?}"
            );
        }
        // In f32 too, and short slices are not a panic.
        let l32 = [Link {
            origin: [0.0f32, 0.0, 0.1],
            rpy: [0.0; 3],
            axis: [0.0, 1.0, 0.0],
            mass: 1.0,
            com: [0.2, 0.0, 0.0],
        }];
        let mut t = [0.0f32; 1];
        assert_eq!(torques(&l32, &[0.0, 1.0], 9.81, &mut t), 1);
        assert!((t[0] - 1.962).abs() < 1e-5);
        assert_eq!(torques(&l32, &[], 9.81, &mut t), 0);
        assert_eq!(torques(&l32, &[0.0], 9.81, &mut []), 0);
    }

    /// A vertical axis carries no gravity load.
    #[test]
    fn a_vertical_axis_carries_nothing() {
        let links = [Link {
            origin: [0.0, 0.0, 0.0],
            rpy: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
            mass: 2.0,
            com: [0.3, 0.1, 0.0],
        }];
        let mut t = [1.0f64];
        torques(&links, &[0.7], 9.81, &mut t);
        assert!(t[0].abs() < 1e-15);
    }
}
