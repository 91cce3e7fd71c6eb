//! The distance between two line segments (Ericson, Real-Time Collision Detection, 5.1.9),
//! for capsules and for the capsules that hold cylinders: two capsules are their axes'
//! distance less both radii apart, and a cylinder lies in the capsule of its axis and radius,
//! so that distance never exceeds the cylinders'.

use nalgebra::Point3;

/// The distance (m) between segments `p1`–`q1` and `p2`–`q2`.
pub(crate) fn distance(
    p1: &Point3<f64>,
    q1: &Point3<f64>,
    p2: &Point3<f64>,
    q2: &Point3<f64>,
) -> f64 {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    const EPS: f64 = 1e-18;
    let (s, t) = if a <= EPS && e <= EPS {
        (0.0, 0.0)
    } else if a <= EPS {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= EPS {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s = if denom > EPS {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    ((p1 + d1 * s) - (p2 + d2 * t)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Against a brute-force minimum over both segments' parameters.
    #[test]
    fn agrees_with_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let p = |rng: &mut rand_chacha::ChaCha8Rng| {
            Point3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
        };
        for k in 0..300 {
            let (p1, q1, p2) = (p(&mut rng), p(&mut rng), p(&mut rng));
            // Some parallel and some degenerate segments too.
            let q2 = match k % 3 {
                0 => p2 + (q1 - p1) * 0.7,
                1 => p2,
                _ => p(&mut rng),
            };
            let ours = distance(&p1, &q1, &p2, &q2);
            let n = 400;
            let mut best = f64::INFINITY;
            for i in 0..=n {
                let a = p1 + (q1 - p1) * (f64::from(i) / f64::from(n));
                for j in 0..=n {
                    let b = p2 + (q2 - p2) * (f64::from(j) / f64::from(n));
                    best = best.min((a - b).norm());
                }
            }
            assert!(ours <= best + 1e-12, "{ours} above {best}");
            assert!(best - ours < 0.01, "{ours} far below {best}");
        }
    }
}
