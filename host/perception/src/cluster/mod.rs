//! Clustering of point clouds (m, any one frame): DBSCAN with scikit-learn's semantics behind
//! the [`Clusterer`] trait, on a grid of cells or a k-d tree ([`Dbscan`], the fast one) and by
//! exhaustive search ([`ExhaustiveDbscan`], the literal algorithm, a reference for checking).
//!
//! # Semantics (scikit-learn's `DBSCAN(eps, min_samples)`, metric euclidean)
//! * Point `j` is a neighbour of `i` when their Euclidean distance is at most `eps`
//!   (compared as squared distances, `dx² + dy² + dz² <= eps²`, as scikit-learn's k-d tree
//!   compares them); every point is its own neighbour.
//! * A point is *core* when it has at least `min_samples` neighbours (itself included).
//! * Core points within `eps` of each other are in the same cluster (the connected components
//!   of that graph); clusters are numbered 0, 1, ... in the order of their lowest-index core
//!   point, which is the order scikit-learn discovers them scanning points by index.
//! * A non-core point within `eps` of a core point (a *border* point) takes the cluster of
//!   the first cluster that reaches it in scikit-learn's order: that is the lowest-numbered
//!   cluster among its core neighbours' (scikit-learn labels every unlabelled neighbour of
//!   each core point while it grows one cluster, and grows the clusters one after another).
//! * Every other point is noise, [`NOISE`] (-1).
//!
//! So the labels are a function of the points and the two parameters alone, and are
//! scikit-learn's label for label, not only up to a permutation (`tests/dbscan_sklearn.rs`
//! checks that against scikit-learn itself).

use nalgebra::Point3;

use crate::cloud::check_points;
use crate::error::{PerceptionError, Result};

mod dbscan;
mod exhaustive;
mod join;
mod neighbours;

pub use dbscan::Dbscan;
pub use exhaustive::ExhaustiveDbscan;

/// The label of a noise point.
pub const NOISE: i32 = -1;

/// Largest neighbourhood radius accepted, m (a table-top object is centimetres; 100 m is
/// beyond any room).
pub const MAX_EPS: f64 = 100.0;

/// Largest `min_samples` accepted (far beyond any cloud a camera frame gives: a 640x480 frame
/// has 307,200 pixels).
pub const MAX_MIN_SAMPLES: usize = 1_000_000;

/// Most points one clustering takes (labels are `i32`).
pub const MAX_POINTS: usize = i32::MAX as usize;

/// What a clustering found: one label per point, in the points' order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Clustering {
    /// Cluster of each point, 0, 1, ..., or [`NOISE`] (-1).
    pub labels: Vec<i32>,
    /// Whether each point is a core point (DBSCAN's notion; an implementation without it
    /// marks every clustered point core).
    pub core: Vec<bool>,
    /// Number of clusters (labels run from 0 to `clusters - 1`).
    pub clusters: usize,
}

impl Clustering {
    /// Number of points in each cluster, by label.
    pub fn sizes(&self) -> Vec<usize> {
        let mut sizes = vec![0; self.clusters];
        for &l in &self.labels {
            if let Ok(k) = usize::try_from(l) {
                sizes[k] += 1;
            }
        }
        sizes
    }

    /// Number of noise points.
    pub fn noise(&self) -> usize {
        self.labels.iter().filter(|&&l| l == NOISE).count()
    }

    /// The indices of each cluster's points (ascending), by label.
    pub fn members(&self) -> Vec<Vec<usize>> {
        let mut members = vec![Vec::new(); self.clusters];
        for (i, &l) in self.labels.iter().enumerate() {
            if let Ok(k) = usize::try_from(l) {
                members[k].push(i);
            }
        }
        members
    }
}

/// A clustering algorithm over 3-D points (m, any one frame): the labels of [`Clustering`].
/// Implementations refuse empty clouds, non-finite points and points beyond
/// [`MAX_COORDINATE`](crate::cloud::MAX_COORDINATE) with typed errors.
pub trait Clusterer: Send + Sync {
    /// Cluster `points`.
    fn cluster(&self, points: &[Point3<f64>]) -> Result<Clustering>;
}

/// DBSCAN's two parameters, checked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DbscanParams {
    /// Neighbourhood radius, m: finite, `0 < eps <= MAX_EPS`.
    pub eps: f64,
    /// Neighbours (the point itself included) that make a point core: `1..=MAX_MIN_SAMPLES`.
    pub min_samples: usize,
}

impl DbscanParams {
    /// PyRobot's pushing example: eps 0.02 m, min_samples 15.
    pub const PYROBOT_PUSHING: DbscanParams = DbscanParams {
        eps: 0.02,
        min_samples: 15,
    };

    /// Checked parameters: `eps` finite in (0, [`MAX_EPS`]] m, `min_samples` in
    /// 1..=[`MAX_MIN_SAMPLES`].
    pub fn new(eps: f64, min_samples: usize) -> Result<Self> {
        let p = DbscanParams { eps, min_samples };
        p.check()?;
        Ok(p)
    }

    /// The checks of [`DbscanParams::new`], for parameters built as a literal.
    pub fn check(&self) -> Result<()> {
        if !(self.eps.is_finite() && self.eps > 0.0 && self.eps <= MAX_EPS) {
            return Err(PerceptionError::Parameter {
                name: "eps",
                value: self.eps,
                range: "a finite radius in (0, 100] m",
            });
        }
        if !(1..=MAX_MIN_SAMPLES).contains(&self.min_samples) {
            return Err(PerceptionError::Parameter {
                name: "min_samples",
                value: self.min_samples as f64,
                range: "a count in 1..=1000000",
            });
        }
        Ok(())
    }
}

/// Checks a cloud for clustering: not empty, not too large, every point finite and in range.
fn check_cloud(points: &[Point3<f64>]) -> Result<()> {
    if points.is_empty() {
        return Err(PerceptionError::EmptyCloud { what: "cloud" });
    }
    if points.len() > MAX_POINTS {
        return Err(PerceptionError::Parameter {
            name: "number of points",
            value: points.len() as f64,
            range: "at most 2147483647",
        });
    }
    check_points(points)
}

#[cfg(test)]
mod tests {
    use super::join::near_pairs;
    use super::neighbours::Neighbours;
    use super::*;
    use crate::grid::{d2, CellGrid};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
        Point3::new(x, y, z)
    }

    /// The fast clustering of `pts`, checked equal to the exhaustive reference's (`what`
    /// names the case in the failure).
    /// The fast clustering is checked both on the index it chooses and on the tree.
    fn agreed(pts: &[Point3<f64>], eps: f64, min_samples: usize, what: &str) -> Clustering {
        let dbscan = Dbscan::new(eps, min_samples).unwrap();
        let d = dbscan.cluster(pts).unwrap();
        let e = ExhaustiveDbscan::new(eps, min_samples)
            .unwrap()
            .cluster(pts)
            .unwrap();
        assert_eq!(d, e, "{what}");
        let raw: Vec<[f64; 3]> = pts.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree = Neighbours::tree(raw.clone()).unwrap();
        assert_eq!(dbscan.cluster_on(&tree).unwrap(), e, "{what}, on the tree");
        // And with every cell's duplicates merged, where there is a grid.
        if let Some(mut grid) = CellGrid::new(&raw, eps, usize::MAX) {
            grid.merge_duplicates(0);
            let merged = Neighbours::Grid(grid);
            assert_eq!(dbscan.cluster_on(&merged).unwrap(), e, "{what}, merged");
        }
        d
    }

    /// Whether the clustering of `pts` with `eps` searches a grid (not the tree).
    fn on_grid(pts: &[Point3<f64>], eps: f64) -> bool {
        matches!(Neighbours::new(pts, eps).unwrap(), Neighbours::Grid(_))
    }

    #[test]
    fn a_small_case_by_hand() {
        // Two tight groups of 4 on a line, a border point, and an isolated point.
        let pts = vec![
            p(0.0, 0.0, 0.0),
            p(0.01, 0.0, 0.0),
            p(0.02, 0.0, 0.0),
            p(0.03, 0.0, 0.0),
            p(1.0, 0.0, 0.0),
            p(1.01, 0.0, 0.0),
            p(1.02, 0.0, 0.0),
            p(1.03, 0.0, 0.0),
            p(0.045, 0.0, 0.0), // 0.015 from point 3 only: border of cluster 0
            p(5.0, 0.0, 0.0),   // noise
        ];
        for c in [
            &Dbscan::new(0.0151, 3).unwrap() as &dyn Clusterer,
            &ExhaustiveDbscan::new(0.0151, 3).unwrap(),
        ] {
            let r = c.cluster(&pts).unwrap();
            assert_eq!(r.labels, vec![0, 0, 0, 0, 1, 1, 1, 1, 0, -1]);
            assert_eq!(r.clusters, 2);
            assert_eq!(r.sizes(), vec![5, 4]);
            assert_eq!(r.noise(), 1);
            assert!(!r.core[0] && r.core[1] && r.core[3] && !r.core[8] && !r.core[9]);
        }
    }

    #[test]
    fn a_border_point_takes_the_lowest_cluster_among_its_core_neighbours() {
        // Clusters A (around x = 0) and B (around x = 1) are found in the order of their
        // lowest core index: B's points come first, so B is 0. The border point in between
        // touches a core point of each: it takes 0 (B), whatever its own index.
        let mut pts = vec![];
        for k in 0..4 {
            pts.push(p(1.0 + 0.01 * k as f64, 0.0, 0.0)); // B: 0..4
        }
        for k in 0..4 {
            pts.push(p(-0.01 * k as f64, 0.0, 0.0)); // A: 4..8, reaching x = 0
        }
        pts.push(p(0.5, 0.0, 0.0)); // border, 0.5 from both ends with eps 0.5
        let d = agreed(&pts, 0.5, 5, "");
        assert_eq!(d.labels[8], 0, "{:?}", d.labels);
        assert_eq!(&d.labels[..8], &[0, 0, 0, 0, 1, 1, 1, 1]);
    }

    #[test]
    fn min_samples_one_makes_every_point_a_cluster_or_a_member() {
        let pts = vec![p(0.0, 0.0, 0.0), p(3.0, 0.0, 0.0), p(0.05, 0.0, 0.0)];
        let r = Dbscan::new(0.1, 1).unwrap().cluster(&pts).unwrap();
        assert_eq!(r.labels, vec![0, 1, 0]);
        assert!(r.core.iter().all(|&c| c));
    }

    #[test]
    fn duplicates_and_ties_at_eps_agree_with_the_reference() {
        // A lattice at 1 cm with eps exactly 1 cm and 2 cm: many distances equal eps (the
        // comparison is inclusive), and stacked duplicates.
        let mut pts = vec![];
        for i in 0..12 {
            for j in 0..7 {
                pts.push(p(i as f64 * 0.01, j as f64 * 0.01, 0.0));
                if (i + j) % 5 == 0 {
                    pts.push(p(i as f64 * 0.01, j as f64 * 0.01, 0.0));
                }
            }
        }
        for (eps, m) in [(0.01, 5), (0.01, 6), (0.02, 13), (0.0141, 9), (0.03, 40)] {
            agreed(&pts, eps, m, &format!("eps {eps}, min_samples {m}"));
        }
    }

    #[test]
    fn near_pairs_finds_every_close_pair_on_the_grid_and_on_the_tree() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        // Clumped (the grid: few cells per point) and spread over a kilometre (more cells
        // than PAIR_CELLS_PER_POINT per point: the tree), with duplicates and points on
        // cell boundaries.
        let clumped: Vec<[f64; 3]> = (0..600)
            .map(|k| match k % 10 {
                0 => [0.04 * (k / 10) as f64, 0.0, 0.08],
                1 => [0.04 * (k / 10) as f64, 0.0, 0.08],
                _ => [0; 3].map(|_| rng.random_range(0.0..0.3)),
            })
            .collect();
        let spread: Vec<[f64; 3]> = (0..300)
            .map(|k| {
                let far = [0; 3].map(|_| rng.random_range(-500.0..500.0));
                if k % 3 == 0 {
                    far
                } else {
                    [far[0] * 1e-4, far[1] * 1e-4, far[2] * 1e-4]
                }
            })
            .collect();
        for (pts, reach) in [(&clumped, 0.04), (&spread, 0.04), (&clumped, 2.0)] {
            let reach2 = reach * reach;
            let mut found = Vec::new();
            near_pairs(pts, reach2, |a, b, d| found.push((a, b, d))).unwrap();
            found.sort_by_key(|x| (x.0, x.1));
            let mut want = Vec::new();
            for a in 0..pts.len() {
                for b in a + 1..pts.len() {
                    let d = d2(&pts[a], &pts[b]);
                    if d <= reach2 {
                        want.push((a, b, d));
                    }
                }
            }
            assert!(!want.is_empty());
            assert_eq!(found, want, "{} points, reach {reach}", pts.len());
        }
    }

    #[test]
    fn random_clouds_agree_with_the_reference() {
        let mut rng = ChaCha8Rng::seed_from_u64(14);
        let mut grids = 0;
        for case in 0..40 {
            let n = rng.random_range(1..600);
            let spread = [0.05, 0.2, 1.0][case % 3];
            let centres: Vec<[f64; 3]> = (0..rng.random_range(1..6))
                .map(|_| [0; 3].map(|_| rng.random_range(-spread..spread)))
                .collect();
            let pts: Vec<Point3<f64>> = (0..n)
                .map(|_| {
                    let c = centres[rng.random_range(0..centres.len())];
                    let s = rng.random_range(0.001..0.05);
                    p(
                        c[0] + rng.random_range(-s..s),
                        c[1] + rng.random_range(-s..s),
                        c[2] + rng.random_range(-s..s),
                    )
                })
                .collect();
            let eps = rng.random_range(0.002..0.08);
            let m = rng.random_range(1..30);
            grids += on_grid(&pts, eps) as usize;
            agreed(
                &pts,
                eps,
                m,
                &format!("case {case}: n {n}, eps {eps}, min_samples {m}"),
            );
        }
        // Both indexes are chosen by some of the clouds (and every cloud is also clustered
        // on the tree).
        assert!((5..35).contains(&grids), "{grids} of 40 on a grid");
    }

    #[test]
    fn large_stacks_of_duplicates_take_the_tree_path() {
        // Two stacks of 300 identical points 1.5 eps apart, and a bridge point between them
        // that is core: the groups' comparison goes through a k-d tree (300 x 300 pairs).
        let mut pts = vec![p(0.0, 0.0, 0.0); 300];
        pts.extend(vec![p(0.03, 0.0, 0.0); 300]);
        for eps in [0.02, 0.0151, 0.0149] {
            let d = agreed(&pts, eps, 10, &format!("eps {eps}"));
            assert_eq!(d.clusters, 2);
        }
        pts.push(p(0.015, 0.0, 0.0));
        let d = agreed(&pts, 0.0151, 10, "with the bridge");
        assert_eq!(d.clusters, 1);
    }

    #[test]
    fn a_crowd_just_out_of_reach_is_counted_exactly() {
        // 5000 duplicates at the origin and 1500 points on a sphere 1.2 eps around them,
        // with min_samples beyond what a sphere point has: the sphere's leaders are mixed
        // groups with the crowd around them, which their members count past by the tree.
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let eps = 0.02;
        let mut pts = vec![p(0.0, 0.0, 0.0); 5000];
        for _ in 0..1500 {
            let v = nalgebra::Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0f64),
            );
            if v.norm() > 0.1 {
                pts.push(Point3::from(v.normalize() * 1.2 * eps));
            }
        }
        assert!(on_grid(&pts, eps));
        for m in [20, 60, 4000] {
            agreed(&pts, eps, m, &format!("min_samples {m}"));
        }
        // The crowd, 5000 copies, is merged on its own (CROWDED_CELL): its cell is one point.
        match Neighbours::new(&pts, eps).unwrap() {
            Neighbours::Grid(g) => {
                assert!(g.pts.len() <= pts.len() - 4999, "{} points", g.pts.len());
                assert_eq!(g.caller_len(), pts.len());
            }
            Neighbours::Tree { .. } => panic!("a tree"),
        }
    }

    #[test]
    fn everything_within_eps_and_min_samples_beyond_the_count_is_quick_noise() {
        // 100,000 points within 100 m of each other, min_samples 1,000,000: every point's
        // neighbourhood is the whole cloud, and none is core. Quadratic work would be 1e10
        // distances; the sparse groups' check finds no core point at once.
        let pts: Vec<Point3<f64>> = (0..100_000)
            .map(|i| {
                p(
                    (i % 100) as f64 * 0.1,
                    (i / 100 % 100) as f64 * 0.1,
                    (i / 10_000) as f64,
                )
            })
            .collect();
        let t = std::time::Instant::now();
        let r = Dbscan::new(100.0, MAX_MIN_SAMPLES)
            .unwrap()
            .cluster(&pts)
            .unwrap();
        assert_eq!(r.noise(), pts.len());
        assert!(t.elapsed().as_secs_f64() < 5.0, "{:?}", t.elapsed());
    }

    #[test]
    fn bad_parameters_and_clouds_are_typed_errors() {
        let pts = vec![p(0.0, 0.0, 0.0)];
        for (eps, m) in [
            (0.0, 5),
            (-0.1, 5),
            (f64::NAN, 5),
            (f64::INFINITY, 5),
            (100.5, 5),
            (0.02, 0),
            (0.02, MAX_MIN_SAMPLES + 1),
        ] {
            assert!(
                matches!(Dbscan::new(eps, m), Err(PerceptionError::Parameter { .. })),
                "{eps} {m}"
            );
            let literal = Dbscan {
                params: DbscanParams {
                    eps,
                    min_samples: m,
                },
            };
            assert!(matches!(
                literal.cluster(&pts),
                Err(PerceptionError::Parameter { .. })
            ));
        }
        let d = Dbscan::new(0.02, 15).unwrap();
        assert!(matches!(
            d.cluster(&[]),
            Err(PerceptionError::EmptyCloud { .. })
        ));
        assert!(matches!(
            d.cluster(&[p(0.0, 0.0, 0.0), p(f64::NAN, 0.0, 0.0)]),
            Err(PerceptionError::NonFinitePoint { index: 1, .. })
        ));
        assert!(matches!(
            d.cluster(&[p(0.0, 1e300, 0.0)]),
            Err(PerceptionError::PointOutOfRange { index: 0, .. })
        ));
    }
}
