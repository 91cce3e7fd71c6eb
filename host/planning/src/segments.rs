//! Distances from line segments, for capsules and for the capsules that hold cylinders: two
//! capsules are their axes' distance less both radii apart, a capsule and a box the distance
//! of its axis from the box less its radius, and a cylinder lies in the capsule of its axis
//! and radius, so those distances never exceed the cylinder's.

use nalgebra::{Isometry3, Point3, Vector3};

/// The closest points of segments `p1`–`q1` and `p2`–`q2`, one on each: their distance is
/// the segments' (m).
pub(crate) fn closest(
    p1: &Point3<f64>,
    q1: &Point3<f64>,
    p2: &Point3<f64>,
    q2: &Point3<f64>,
) -> (Point3<f64>, Point3<f64>) {
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
    (p1 + d1 * s, p2 + d2 * t)
}

/// A lower bound (m, within a nanometre of the exact value) of the distance between segment
/// `p`–`q` and the box of half-extents `half` centred at the origin of the frame `pose`
/// places; 0 when they meet. Along the segment (`x(s) = a + d·s`, `s` in [0, 1], box frame)
/// the squared distance is a sum over axes of `(|x_k| − h_k)²` where `|x_k| > h_k` and 0
/// elsewhere: one quadratic between consecutive parameters where some coordinate crosses a
/// face's plane (at most six), whose minimum over its piece is found in closed form.
pub(crate) fn box_distance(
    p: &Point3<f64>,
    q: &Point3<f64>,
    pose: &Isometry3<f64>,
    half: &Vector3<f64>,
) -> f64 {
    let (a, b) = (
        pose.inverse_transform_point(p),
        pose.inverse_transform_point(q),
    );
    let d = b - a;
    // The pieces' ends: 0, 1 and every crossing of a face's plane within.
    let mut cuts = [0.0f64; 8];
    let mut n = 0;
    for k in 0..3 {
        if d[k] != 0.0 {
            for plane in [-half[k], half[k]] {
                let s = (plane - a[k]) / d[k];
                if s > 0.0 && s < 1.0 {
                    cuts[n] = s;
                    n += 1;
                }
            }
        }
    }
    cuts[n] = 0.0;
    cuts[n + 1] = 1.0;
    let cuts = &mut cuts[..n + 2];
    cuts.sort_unstable_by(f64::total_cmp);
    let mut best = f64::INFINITY;
    for w in cuts.windows(2) {
        let (s0, s1) = (w[0], w[1]);
        // Which side of each face the piece lies on (read at its middle): the squared distance
        // over it is Σ (c_k + d_k·s)² over the axes outside the box.
        let mid = 0.5 * (s0 + s1);
        let (mut qa, mut qb, mut qc) = (0.0, 0.0, 0.0);
        for k in 0..3 {
            let x = a[k] + d[k] * mid;
            let c = if x > half[k] {
                a[k] - half[k]
            } else if x < -half[k] {
                a[k] + half[k]
            } else {
                continue;
            };
            qa += d[k] * d[k];
            qb += c * d[k];
            qc += c * c;
        }
        let s = if qa > 0.0 {
            (-qb / qa).clamp(s0, s1)
        } else {
            s0
        };
        best = best.min(qa * s * s + 2.0 * qb * s + qc);
    }
    (best.max(0.0).sqrt() - 1e-9).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Against a brute-force minimum over the segment, for segments outside, grazing and
    /// crossing a turned box.
    #[test]
    fn box_distance_agrees_with_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let pose = Isometry3::new(Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.3, -0.5, 0.8));
        let half = Vector3::new(0.2, 0.1, 0.05);
        let (mut touching, mut apart) = (0, 0);
        for _ in 0..500 {
            let mut p = || {
                pose * Point3::new(
                    rng.random_range(-0.6..0.6),
                    rng.random_range(-0.4..0.4),
                    rng.random_range(-0.3..0.3),
                )
            };
            let (a, b) = (p(), p());
            let ours = box_distance(&a, &b, &pose, &half);
            let n = 20_000;
            let brute = (0..=n)
                .map(|i| {
                    let x = pose
                        .inverse_transform_point(&(a + (b - a) * (f64::from(i) / f64::from(n))));
                    Vector3::new(
                        (x.x.abs() - half.x).max(0.0),
                        (x.y.abs() - half.y).max(0.0),
                        (x.z.abs() - half.z).max(0.0),
                    )
                    .norm()
                })
                .fold(f64::INFINITY, f64::min);
            assert!(ours <= brute + 1e-12, "{ours} above {brute}");
            // The brute force samples 1/20000 of the segment: within that of the minimum.
            assert!(
                brute - ours < (b - a).norm() / 20_000.0 + 2e-9,
                "{ours} far below {brute}"
            );
            if brute == 0.0 {
                touching += 1;
            } else {
                apart += 1;
            }
        }
        assert!(
            touching > 50 && apart > 50,
            "{touching} touching, {apart} apart"
        );
    }

    /// Segments along a face, degenerate ones and ones parallel to an axis: exact values.
    #[test]
    fn box_distance_of_special_segments() {
        let pose = Isometry3::translation(1.0, 2.0, 3.0);
        let half = Vector3::new(0.2, 0.1, 0.05);
        let at = |x: f64, y: f64, z: f64| Point3::new(1.0 + x, 2.0 + y, 3.0 + z);
        let cases = [
            // Along x, 0.1 above the top face: 0.1.
            (at(-1.0, 0.0, 0.15), at(1.0, 0.0, 0.15), 0.1),
            // A point, off a corner by (0.1, 0.1, 0.1).
            (at(0.3, 0.2, 0.15), at(0.3, 0.2, 0.15), 0.03f64.sqrt()),
            // Through the box.
            (at(-1.0, 0.0, 0.0), at(1.0, 0.0, 0.0), 0.0),
            // Parallel to z beside the +x face, 0.3 out.
            (at(0.5, 0.0, -2.0), at(0.5, 0.0, 2.0), 0.3),
            // Diagonal x + y = 0.4 past the edge at (0.2, 0.1): distance 0.1/√2.
            (
                at(0.4, 0.0, 0.0),
                at(0.0, 0.4, 0.0),
                (0.1f64 / 2.0f64.sqrt()),
            ),
        ];
        for (p, q, want) in cases {
            let got = box_distance(&p, &q, &pose, &half);
            assert!(
                got <= want + 1e-12 && want - got < 1e-8,
                "{p} {q}: {got} {want}"
            );
        }
    }

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
            let (x, y) = closest(&p1, &q1, &p2, &q2);
            let ours = (x - y).norm();
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
