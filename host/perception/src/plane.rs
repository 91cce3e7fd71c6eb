//! Planes in a cloud: the table's (or the floor's) by RANSAC with a least-squares refit.

use nalgebra::{Matrix3, Point3, SymmetricEigen, Unit, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::cloud::check_points;
use crate::error::{PerceptionError, Result};

/// Largest inlier distance accepted, m.
pub const MAX_THRESHOLD: f64 = 10.0;

/// Most RANSAC hypotheses accepted.
pub const MAX_ITERATIONS: usize = 1_000_000;

/// A plane in the cloud's frame: the points `p` with `normal . p = offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// Unit normal (pointing up when the fit was told which way is up).
    pub normal: Unit<Vector3<f64>>,
    /// Signed distance of the plane from the frame's origin along the normal, m.
    pub offset: f64,
}

impl Plane {
    /// Signed distance of `p` from the plane, positive on the normal's side, m.
    pub fn signed_distance(&self, p: &Point3<f64>) -> f64 {
        self.normal.dot(&p.coords) - self.offset
    }

    /// The foot of `p` on the plane, m.
    pub fn project(&self, p: &Point3<f64>) -> Point3<f64> {
        p - self.normal.into_inner() * self.signed_distance(p)
    }

    /// The same plane with the opposite normal.
    pub fn flipped(&self) -> Plane {
        Plane {
            normal: -self.normal,
            offset: -self.offset,
        }
    }

    /// The plane through `points` closest to them in the least-squares sense (normal along
    /// the covariance's smallest eigenvector), or `None` for fewer than 3 points or when
    /// they are all on one line (within 1e-12 of their spread).
    pub fn least_squares(points: impl Iterator<Item = Point3<f64>> + Clone) -> Option<Plane> {
        let (n, sum) = points
            .clone()
            .fold((0usize, Vector3::zeros()), |(n, s), p| {
                (n + 1, s + p.coords)
            });
        if n < 3 {
            return None;
        }
        let c = sum / n as f64;
        let cov = points.fold(Matrix3::zeros(), |m, p| {
            let d = p.coords - c;
            m + d * d.transpose()
        }) / n as f64;
        let eig = SymmetricEigen::new(cov);
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        // The two larger eigenvalues must span a plane: a line's second one is ~0.
        // (NaN, from non-finite points, spans nothing either.)
        let spans =
            eig.eigenvalues[order[1]] > 1e-12 * eig.eigenvalues[order[2]].max(f64::MIN_POSITIVE);
        if !spans {
            return None;
        }
        let normal = Unit::try_new(eig.eigenvectors.column(order[0]).into_owned(), 1e-12)?;
        Some(Plane {
            normal,
            offset: normal.dot(&c),
        })
    }
}

/// RANSAC's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RansacParams {
    /// A point is an inlier when its distance to the plane is at most this, m: finite, in
    /// (0, [`MAX_THRESHOLD`]].
    pub threshold: f64,
    /// Most plane hypotheses (triples of points) tried: 1..=[`MAX_ITERATIONS`].
    pub iterations: usize,
    /// Stop early once a plane as good as the best so far would have been drawn with this
    /// probability (the usual adaptive count, `log(1 - p) / log(1 - w³)` for inlier fraction
    /// `w`): in (0, 1]; 1 tries all `iterations`.
    pub confidence: f64,
    /// Fewest inliers a plane must have, else [`PerceptionError::NoPlane`]: at least 3.
    pub min_inliers: usize,
    /// Seed of the sampler: the same seed and cloud give the same plane.
    pub seed: u64,
    /// Which way is up in the cloud's frame (need not be unit), if the caller knows: the
    /// normal is then turned to point along it (`normal . up >= 0`).
    pub up: Option<Vector3<f64>>,
    /// With `up`: hypotheses whose normal is more than this from `up` are not considered,
    /// rad, in [0, pi/2] (pi/2: any plane; e.g. 0.3 to find a table but not a wall).
    pub max_tilt: f64,
}

impl Default for RansacParams {
    /// 1 cm, 1000 hypotheses, confidence 0.999, 3 inliers, seed 0, +z up, any tilt.
    fn default() -> Self {
        RansacParams {
            threshold: 0.01,
            iterations: 1000,
            confidence: 0.999,
            min_inliers: 3,
            seed: 0,
            up: Some(Vector3::z()),
            max_tilt: std::f64::consts::FRAC_PI_2,
        }
    }
}

impl RansacParams {
    /// Checks every setting's range (see each field).
    pub fn check(&self) -> Result<()> {
        let bad = |name, value, range| Err(PerceptionError::Parameter { name, value, range });
        if !(self.threshold.is_finite() && self.threshold > 0.0 && self.threshold <= MAX_THRESHOLD)
        {
            return bad(
                "threshold",
                self.threshold,
                "a finite distance in (0, 10] m",
            );
        }
        if !(1..=MAX_ITERATIONS).contains(&self.iterations) {
            return bad(
                "iterations",
                self.iterations as f64,
                "a count in 1..=1000000",
            );
        }
        if !(self.confidence > 0.0 && self.confidence <= 1.0) {
            return bad("confidence", self.confidence, "a probability in (0, 1]");
        }
        if self.min_inliers < 3 {
            return bad("min_inliers", self.min_inliers as f64, "at least 3");
        }
        if let Some(up) = self.up {
            let norm = up.norm();
            if !(norm.is_finite() && norm > 1e-12) {
                return bad(
                    "up",
                    norm,
                    "a finite, non-zero direction (its norm is shown)",
                );
            }
        }
        if !(self.max_tilt >= 0.0 && self.max_tilt <= std::f64::consts::FRAC_PI_2) {
            return bad("max_tilt", self.max_tilt, "an angle in [0, pi/2] rad");
        }
        Ok(())
    }
}

/// A plane found in a cloud, with its inliers.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneFit {
    /// The plane, refitted by least squares to its inliers.
    pub plane: Plane,
    /// Indices of the points within the threshold of `plane`, ascending.
    pub inliers: Vec<usize>,
    /// Root mean square of the inliers' distances to the plane, m.
    pub rms: f64,
    /// Hypotheses drawn before stopping.
    pub hypotheses: usize,
}

/// The dominant plane of `points` (m, any frame) by RANSAC: planes through three distinct
/// points drawn at random (seeded), the one with the most points within `threshold` kept
/// (the first drawn among equals); then refitted by least squares to its inliers and the
/// inliers taken again within the threshold of the refitted plane, until they stop changing
/// (at most 5 rounds). Errors: empty cloud, non-finite or out-of-range points, bad
/// parameters, fewer than 3 points, no plane with `min_inliers`.
pub fn fit_plane(points: &[Point3<f64>], params: &RansacParams) -> Result<PlaneFit> {
    params.check()?;
    if points.is_empty() {
        return Err(PerceptionError::EmptyCloud { what: "cloud" });
    }
    check_points(points)?;
    let n = points.len();
    if n < 3 {
        return Err(PerceptionError::TooFewPoints {
            what: "a plane fit",
            need: 3,
            got: n,
        });
    }
    let t = params.threshold;
    let (best, drawn, scored) = ransac(points, params);
    let no_plane = |best_inliers| PerceptionError::NoPlane {
        hypotheses: scored,
        best_inliers,
        threshold: t,
        min_inliers: params.min_inliers,
    };
    let Some((count, plane)) = best else {
        return Err(no_plane(0));
    };
    if count < params.min_inliers {
        return Err(no_plane(count));
    }
    let (plane, inliers) = refine(points, plane, t, params.min_inliers);
    let rms = (inliers
        .iter()
        .map(|&i| plane.signed_distance(&points[i]).powi(2))
        .sum::<f64>()
        / inliers.len() as f64)
        .sqrt();
    Ok(PlaneFit {
        plane,
        inliers,
        rms,
        hypotheses: drawn,
    })
}

/// RANSAC on `points` (at least 3): the plane with the most inliers and their count (`None`
/// when no hypothesis was scored), the hypotheses drawn, and those scored.
fn ransac(points: &[Point3<f64>], params: &RansacParams) -> (Option<(usize, Plane)>, usize, usize) {
    let n = points.len();
    let up = params.up.map(Unit::new_normalize);
    // Any tilt at pi/2 (a wall's normal is exactly perpendicular to up, and cos(pi/2) > 0).
    let min_cos = if params.max_tilt >= std::f64::consts::FRAC_PI_2 {
        f64::NEG_INFINITY
    } else {
        params.max_tilt.cos()
    };
    let t = params.threshold;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut best: Option<(usize, Plane)> = None;
    let mut needed = params.iterations;
    let mut drawn = 0;
    let mut scored = 0;
    while drawn < needed {
        drawn += 1;
        let (i, j, k) = draw_three(&mut rng, n);
        let Some(plane) = through(&points[i], &points[j], &points[k], up, min_cos) else {
            continue;
        };
        scored += 1;
        let count = points
            .iter()
            .filter(|p| plane.signed_distance(p).abs() <= t)
            .count();
        if best.is_none_or(|(c, _)| count > c) {
            best = Some((count, plane));
            if params.confidence < 1.0 {
                needed = still_needed(needed, drawn, count as f64 / n as f64, params.confidence);
            }
        }
    }
    (best, drawn, scored)
}

/// Three distinct indices below `n` (at least 3), uniformly drawn from `rng`.
fn draw_three(rng: &mut ChaCha8Rng, n: usize) -> (usize, usize, usize) {
    let i = rng.random_range(0..n);
    let mut j = rng.random_range(0..n - 1);
    if j >= i {
        j += 1;
    }
    let mut k = rng.random_range(0..n - 2);
    for lower in [i.min(j), i.max(j)] {
        if k >= lower {
            k += 1;
        }
    }
    (i, j, k)
}

/// The plane through `a`, `b` and `c`, its normal turned along `up` when given; `None` when
/// they span no plane or its normal is farther from `up` than `min_cos` allows.
fn through(
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
    up: Option<Unit<Vector3<f64>>>,
    min_cos: f64,
) -> Option<Plane> {
    let (ab, ac) = (b - a, c - a);
    let cross = ab.cross(&ac);
    let scale = ab.norm() * ac.norm();
    let spans = cross.norm() > 1e-9 * scale;
    if !spans {
        return None; // collinear or coincident: no plane
    }
    let mut normal = Unit::new_normalize(cross);
    if let Some(up) = up {
        if normal.dot(&up) < 0.0 {
            normal = -normal;
        }
        if normal.dot(&up) < min_cos {
            return None;
        }
    }
    Some(Plane {
        normal,
        offset: normal.dot(&a.coords),
    })
}

/// The adaptive count of hypotheses, `needed` so far, once `drawn` have been drawn and the best
/// plane holds the fraction `w` of the points: enough to draw a plane as good with probability
/// `confidence`.
fn still_needed(needed: usize, drawn: usize, w: f64, confidence: f64) -> usize {
    let miss = 1.0 - w * w * w;
    if miss <= 0.0 {
        return drawn;
    }
    let k = ((1.0 - confidence).ln() / miss.ln()).ceil();
    if k.is_finite() && k >= 0.0 {
        needed.min((k as usize).max(drawn))
    } else {
        needed
    }
}

/// `plane` refitted by least squares to its inliers (within `t` of it) and the inliers taken
/// again, until they stop changing (at most 5 rounds; a refit with fewer than `min_inliers`
/// is not taken). Returns the plane and its inliers, ascending.
fn refine(
    points: &[Point3<f64>],
    mut plane: Plane,
    t: f64,
    min_inliers: usize,
) -> (Plane, Vec<usize>) {
    let n = points.len();
    let within = |plane: &Plane| -> Vec<usize> {
        (0..n)
            .filter(|&i| plane.signed_distance(&points[i]).abs() <= t)
            .collect()
    };
    let mut inliers = within(&plane);
    for _ in 0..5 {
        let Some(mut refit) = Plane::least_squares(inliers.iter().map(|&i| points[i])) else {
            break;
        };
        if refit.normal.dot(&plane.normal) < 0.0 {
            refit = refit.flipped();
        }
        let again = within(&refit);
        if again.len() < min_inliers {
            break;
        }
        plane = refit;
        if again == inliers {
            break;
        }
        inliers = again;
    }
    (plane, inliers)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::sample_rectangle;

    /// A tilted plane with 2 mm noise, 30 % outliers in a cube around it.
    fn noisy_plane(seed: u64) -> (Vec<Point3<f64>>, Vector3<f64>, f64) {
        let normal = Vector3::new(0.1, -0.2, 1.0).normalize();
        let u = normal.cross(&Vector3::x()).normalize();
        let v = normal.cross(&u);
        let centre = Point3::new(0.6, 0.1, 0.4);
        let mut pts = sample_rectangle(seed, centre, u, v, [0.8, 0.6], 20_000.0, 0.002, &[], 0.0);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 100);
        let outliers = pts.len() * 3 / 7;
        for _ in 0..outliers {
            pts.push(Point3::new(
                rng.random_range(0.1..1.1),
                rng.random_range(-0.4..0.6),
                rng.random_range(0.0..0.8),
            ));
        }
        (pts, normal, normal.dot(&centre.coords))
    }

    #[test]
    fn a_noisy_plane_with_outliers_is_found_within_half_a_degree_and_a_millimetre() {
        for seed in 0..5 {
            let (pts, normal, offset) = noisy_plane(seed);
            let params = RansacParams {
                threshold: 0.006,
                seed,
                ..Default::default()
            };
            let fit = fit_plane(&pts, &params).unwrap();
            let angle = fit.plane.normal.dot(&normal).clamp(-1.0, 1.0).acos();
            assert!(angle < 0.5f64.to_radians(), "seed {seed}: {angle} rad");
            assert!(
                (fit.plane.offset - offset).abs() < 0.001,
                "seed {seed}: {} vs {offset}",
                fit.plane.offset
            );
            assert!(fit.plane.normal.z > 0.0, "up is +z");
            // Nearly all of the 9600 plane points (noise 2 mm, threshold 6 mm = 3 sigma)
            // and a few of the outliers that happen to lie near it.
            assert!(
                (9400..9900).contains(&fit.inliers.len()),
                "{}",
                fit.inliers.len()
            );
            assert!((fit.rms - 0.002).abs() < 0.0003, "rms {}", fit.rms);
            // Seeded: the same again.
            let again = fit_plane(&pts, &params).unwrap();
            assert_eq!(fit, again);
        }
    }

    #[test]
    fn up_orients_the_normal_and_max_tilt_skips_walls() {
        // A floor (z = 0, 1 x 1 m) and a larger wall (x = 1, 1 x 2 m).
        let floor = sample_rectangle(
            1,
            Point3::new(0.5, 0.0, 0.0),
            Vector3::x(),
            Vector3::y(),
            [1.0, 1.0],
            2000.0,
            0.0,
            &[],
            0.0,
        );
        let wall = sample_rectangle(
            2,
            Point3::new(1.0, 0.0, 1.0),
            Vector3::y(),
            Vector3::z(),
            [1.0, 2.0],
            2000.0,
            0.0,
            &[],
            0.0,
        );
        let pts: Vec<_> = floor.iter().chain(&wall).copied().collect();
        let any = fit_plane(&pts, &RansacParams::default()).unwrap();
        assert!(any.plane.normal.x.abs() > 0.999, "the wall is larger");
        let table = fit_plane(
            &pts,
            &RansacParams {
                max_tilt: 0.3,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(
            table.plane.normal.z > 0.999 && table.plane.offset.abs() < 0.003,
            "{:?}",
            table.plane
        );
        let down = fit_plane(
            &pts,
            &RansacParams {
                up: Some(-Vector3::z()),
                max_tilt: 0.3,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(down.plane.normal.z < -0.999);
    }

    #[test]
    fn bad_input_is_a_typed_error() {
        let ok = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        let p = RansacParams::default();
        assert!(matches!(
            fit_plane(&[], &p),
            Err(PerceptionError::EmptyCloud { .. })
        ));
        assert!(matches!(
            fit_plane(&ok[..2], &p),
            Err(PerceptionError::TooFewPoints {
                need: 3,
                got: 2,
                ..
            })
        ));
        let mut nan = ok.clone();
        nan[2].y = f64::NAN;
        assert!(matches!(
            fit_plane(&nan, &p),
            Err(PerceptionError::NonFinitePoint { index: 2, .. })
        ));
        // Collinear points hold no plane.
        let line: Vec<_> = (0..50).map(|i| Point3::new(i as f64, 0.0, 0.0)).collect();
        assert!(matches!(
            fit_plane(&line, &p),
            Err(PerceptionError::NoPlane {
                best_inliers: 0,
                ..
            })
        ));
        assert!(matches!(
            fit_plane(
                &ok,
                &RansacParams {
                    min_inliers: 4,
                    ..p
                }
            ),
            Err(PerceptionError::NoPlane {
                best_inliers: 3,
                ..
            })
        ));
        for bad in [
            RansacParams {
                threshold: 0.0,
                ..p
            },
            RansacParams {
                threshold: f64::NAN,
                ..p
            },
            RansacParams {
                threshold: 11.0,
                ..p
            },
            RansacParams { iterations: 0, ..p },
            RansacParams {
                confidence: 0.0,
                ..p
            },
            RansacParams {
                confidence: f64::NAN,
                ..p
            },
            RansacParams {
                min_inliers: 2,
                ..p
            },
            RansacParams {
                up: Some(Vector3::zeros()),
                ..p
            },
            RansacParams {
                up: Some(Vector3::new(f64::INFINITY, 0.0, 0.0)),
                ..p
            },
            RansacParams {
                max_tilt: -0.1,
                ..p
            },
            RansacParams {
                max_tilt: f64::NAN,
                ..p
            },
        ] {
            assert!(
                matches!(fit_plane(&ok, &bad), Err(PerceptionError::Parameter { .. })),
                "{bad:?}"
            );
        }
    }
}
