//! Two oriented boxes: whether they touch, and a lower bound of their distance, by the
//! separating-axis test (Gottschalk et al. 1996, OBBTree) instead of GJK.
//!
//! Why the separating axes: `docs/design/planning.md`.

use nalgebra::{Isometry3, Matrix3, Vector3};

/// Cross axes shorter than this (edges within about 1e-6 rad of parallel) are skipped: a
/// face axis then separates whenever they would.
const PARALLEL: f64 = 1e-6;

/// A lower bound (m) of the distance between box `a` (half-extents `ha`, m, centred at the
/// origin of the frame `pa` places) and box `b`; 0 when they touch or overlap.
pub(crate) fn gap(
    pa: &Isometry3<f64>,
    ha: &Vector3<f64>,
    pb: &Isometry3<f64>,
    hb: &Vector3<f64>,
) -> f64 {
    let ra = pa.rotation.to_rotation_matrix();
    let rb = pb.rotation.to_rotation_matrix();
    let (ra, rb): (&Matrix3<f64>, &Matrix3<f64>) = (ra.matrix(), rb.matrix());
    // b's axes and the centre offset in a's frame.
    let r = ra.transpose() * rb;
    let t = ra.transpose() * (pb.translation.vector - pa.translation.vector);
    let abs = r.map(f64::abs);
    let mut best = f64::NEG_INFINITY;
    // a's faces.
    for i in 0..3 {
        let rb_ = hb[0] * abs[(i, 0)] + hb[1] * abs[(i, 1)] + hb[2] * abs[(i, 2)];
        best = best.max(t[i].abs() - ha[i] - rb_);
    }
    // b's faces.
    for j in 0..3 {
        let ra_ = ha[0] * abs[(0, j)] + ha[1] * abs[(1, j)] + ha[2] * abs[(2, j)];
        let tj = t[0] * r[(0, j)] + t[1] * r[(1, j)] + t[2] * r[(2, j)];
        best = best.max(tj.abs() - ra_ - hb[j]);
    }
    // Edge crosses: a's axis i × b's axis j, in a's frame, normalised.
    for i in 0..3 {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        for j in 0..3 {
            let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
            // Length of e_i × b_j = sin of the angle between them.
            let len = (1.0 - r[(i, j)] * r[(i, j)]).max(0.0).sqrt();
            if len < PARALLEL {
                continue;
            }
            let ra_ = ha[i1] * abs[(i2, j)] + ha[i2] * abs[(i1, j)];
            let rb_ = hb[j1] * abs[(i, j2)] + hb[j2] * abs[(i, j1)];
            let tl = (t[i2] * r[(i1, j)] - t[i1] * r[(i2, j)]).abs();
            best = best.max((tl - ra_ - rb_) / len);
        }
    }
    best.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::convert;
    use crate::shape::Shape;
    use nalgebra::{Translation3, UnitQuaternion};
    use rand::{Rng, SeedableRng};

    /// Never more than GJK's distance (within f32 rounding), equal to it for boxes side by
    /// side, and the same contact verdict, over random poses near contact.
    #[test]
    fn a_lower_bound_of_gjk_with_the_same_contacts() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut touching, mut apart) = (0, 0);
        for _ in 0..20_000 {
            let ha = Vector3::from_fn(|_, _| rng.random_range(0.005..0.2));
            let hb = Vector3::from_fn(|_, _| rng.random_range(0.005..0.2));
            let rot = |rng: &mut rand_chacha::ChaCha8Rng| {
                UnitQuaternion::from_euler_angles(
                    rng.random_range(-3.2..3.2),
                    rng.random_range(-1.6..1.6),
                    rng.random_range(-3.2..3.2),
                )
            };
            let pa = Isometry3::from_parts(
                Translation3::new(
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                    0.0,
                ),
                rot(&mut rng),
            );
            let pb = Isometry3::from_parts(
                Translation3::new(
                    rng.random_range(-0.3..0.3),
                    0.0,
                    rng.random_range(-0.3..0.3),
                ),
                rot(&mut rng),
            );
            let ours = gap(&pa, &ha, &pb, &hb);
            let ea = convert::shape(&Shape::Box((ha * 2.0).into())).expect("box");
            let eb = convert::shape(&Shape::Box((hb * 2.0).into())).expect("box");
            let gjk = f64::from(parry3d::query::details::distance_support_map_support_map(
                &convert::pose(&pa).inv_mul(&convert::pose(&pb)),
                ea.shape.as_support_map().expect("support map"),
                eb.shape.as_support_map().expect("support map"),
            ));
            // Not parry's own cuboid distance, which may be too large (see the checker).
            let truth = gjk;
            assert!(ours <= truth + 1e-4, "{ours} m above GJK's {truth} m");
            let hit = parry3d::query::intersection_test(
                &convert::pose(&pa),
                ea.shape.as_ref(),
                &convert::pose(&pb),
                eb.shape.as_ref(),
            )
            .expect("test")
            .intersecting;
            if hit {
                touching += 1;
                assert!(ours < 1e-4, "touching boxes {ours} m apart");
            } else if truth > 1e-3 {
                apart += 1;
                assert!(ours > 0.0, "boxes {truth} m apart reported touching");
            }
        }
        assert!(
            touching > 2000 && apart > 2000,
            "{touching} touching, {apart} apart"
        );
    }

    #[test]
    fn exact_for_faces_side_by_side() {
        let h = Vector3::new(0.1, 0.2, 0.3);
        let a = Isometry3::identity();
        let b = Isometry3::translation(0.25, 0.05, 0.0)
            * UnitQuaternion::from_euler_angles(0.0, 0.0, 0.0);
        assert!((gap(&a, &h, &b, &h) - 0.05).abs() < 1e-12);
        let turned = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.9),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7),
        );
        assert!((gap(&a, &h, &turned, &h) - 0.3).abs() < 1e-12);
    }
}
