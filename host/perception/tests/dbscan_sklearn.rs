//! DBSCAN against its real peer: scikit-learn's `DBSCAN(eps, min_samples)` on the same clouds
//! (`peer/dbscan_peer.py`).
//!
//! What is compared, exactly: for every point of every cloud, our label and scikit-learn's
//! are equal (the same integer: -1 for noise, cluster numbers in scikit-learn's order, border
//! points included), and so is whether the point is core. Not "up to a permutation": with
//! both sides comparing squared distances `dx² + dy² + dz² <= eps²` in double precision, the
//! labels are a function of the points (see `ferrobot_perception::cluster`), so any
//! difference is a bug on one side. Each cloud is written as a PLY file (float32
//! coordinates, as `write_ply` writes them) and read back, so both sides cluster exactly the
//! same float64 values.
//!
//! The peer needs a Python with scikit-learn: `FERROBOT_PYTHON` (scripts/test.sh installs it
//! with `scripts/python-env.sh cluster` and sets it; then it must be there), or else the
//! workspace's `target/py-venv`; without either the test is skipped, saying so.

use std::path::{Path, PathBuf};
use std::process::Command;

use ferrobot_perception::io::{read_ply, write_ply};
use ferrobot_perception::synthetic::{blobs, DepthCamera, Tabletop};
use ferrobot_perception::{
    above_table, fit_plane, Clusterer, Clustering, Dbscan, Intrinsics, PointCloud, RansacParams,
    SegmentParams,
};
use nalgebra::Point3;

#[path = "support/locobot_camera.rs"]
mod locobot_camera;
use locobot_camera::locobot_intrinsics;

/// The peer's Python, or `None` (skip): [`ferrobot_peers::for_test`]'s rule.
fn peer_python() -> Option<PathBuf> {
    ferrobot_peers::for_test(
        "sklearn.cluster, threadpoolctl",
        "scripts/python-env.sh cluster",
    )
}

/// A scratch directory, removed with the guard.
fn scratch() -> tempfile::TempDir {
    tempfile::tempdir().expect("temporary directory")
}

/// One scikit-learn run: labels, core flags, the neighbour search it chose.
struct Peer {
    labels: Vec<i32>,
    core: Vec<bool>,
    algorithm: String,
}

/// One cloud to compare: a name for messages, its points, and the (eps, min_samples) pairs.
struct Case {
    name: String,
    points: Vec<Point3<f64>>,
    params: Vec<(f64, usize)>,
}

impl Case {
    fn new(name: impl Into<String>, points: Vec<Point3<f64>>, params: &[(f64, usize)]) -> Self {
        Case {
            name: name.into(),
            points,
            params: params.to_vec(),
        }
    }
}

/// scikit-learn's runs on each case's cloud (the PLY file beside it in `plys`), one per
/// (eps, min_samples), all in one Python start-up (which takes longer than most fits).
fn sklearn(py: &Path, cases: &[Case], plys: &[PathBuf]) -> Vec<Vec<Peer>> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("peer/dbscan_peer.py");
    let spec: Vec<serde_json::Value> = cases
        .iter()
        .zip(plys)
        .map(|(case, ply)| {
            serde_json::json!({
                "cloud": ply,
                "eps": case.params.iter().map(|p| p.0).collect::<Vec<_>>(),
                "min_samples": case.params.iter().map(|p| p.1).collect::<Vec<_>>(),
            })
        })
        .collect();
    let spec_path = plys[0].with_extension("json");
    std::fs::write(&spec_path, serde_json::to_vec(&spec).unwrap()).expect("writes the cases");
    let out = Command::new(py)
        .arg(&script)
        .arg("--batch")
        .arg(&spec_path)
        .output()
        .expect("runs the peer");
    let _ = std::fs::remove_file(&spec_path);
    assert!(
        out.status.success(),
        "peer failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("peer's JSON");
    let batch = v["batch"].as_array().expect("batch");
    assert_eq!(batch.len(), cases.len());
    batch
        .iter()
        .zip(cases)
        .map(|(b, case)| {
            let runs = b["runs"].as_array().expect("runs");
            assert_eq!(runs.len(), case.params.len(), "{}", case.name);
            runs.iter()
                .map(|r| Peer {
                    labels: r["labels"]
                        .as_array()
                        .expect("labels")
                        .iter()
                        .map(|l| l.as_i64().expect("integer label") as i32)
                        .collect(),
                    core: r["core"]
                        .as_array()
                        .expect("core")
                        .iter()
                        .map(|c| c.as_i64() == Some(1))
                        .collect(),
                    algorithm: r["algorithm"].as_str().unwrap_or("?").to_string(),
                })
                .collect()
        })
        .collect()
}

/// Border points whose core neighbours lie in two or more clusters (where the rule for
/// border points decides), by exhaustive search; `None` for clouds too large for that.
fn contested(pts: &[Point3<f64>], c: &Clustering, eps: f64) -> Option<usize> {
    if pts.len() > 5000 {
        return None;
    }
    let eps2 = eps * eps;
    let mut count = 0;
    for (i, p) in pts.iter().enumerate() {
        if c.core[i] || c.labels[i] < 0 {
            continue;
        }
        let mut seen: Vec<i32> = pts
            .iter()
            .enumerate()
            .filter(|(j, q)| c.core[*j] && (p - *q).norm_squared() <= eps2)
            .map(|(j, _)| c.labels[j])
            .collect();
        seen.sort_unstable();
        seen.dedup();
        count += usize::from(seen.len() > 1);
    }
    Some(count)
}

/// What one comparison saw: clusters, noise, contested border points (when counted).
struct Seen {
    clusters: usize,
    noise: usize,
    contested: Option<usize>,
}

/// Writes each case's points as a PLY, reads them back (float32 coordinates), clusters them
/// with ours and scikit-learn's for each (eps, min_samples), and checks every label and core
/// flag; what each run saw, case by case.
fn compare(py: &Path, cases: &[Case]) -> Vec<Vec<Seen>> {
    let scratch = scratch();
    let dir = scratch.path();
    let plys: Vec<PathBuf> = cases
        .iter()
        .map(|case| {
            let path = dir.join(format!("{}.ply", case.name));
            let cloud = PointCloud {
                points: case.points.clone(),
                colours: vec![[128; 3]; case.points.len()],
            };
            write_ply(&path, &cloud).expect("writes");
            path
        })
        .collect();
    let peers = sklearn(py, cases, &plys);
    cases
        .iter()
        .zip(&plys)
        .zip(peers)
        .map(|((case, ply), peers)| {
            let pts = read_ply(ply).expect("reads").points;
            let _ = std::fs::remove_file(ply);
            compare_one(&case.name, &pts, &case.params, peers)
        })
        .collect()
}

/// Ours against scikit-learn's `peers` on the points read back, one run per pair.
fn compare_one(
    name: &str,
    pts: &[Point3<f64>],
    params: &[(f64, usize)],
    peers: Vec<Peer>,
) -> Vec<Seen> {
    params
        .iter()
        .zip(peers)
        .map(|(&(eps, min_samples), peer)| {
            let ours = Dbscan::new(eps, min_samples).unwrap().cluster(pts).unwrap();
            assert_eq!(peer.labels.len(), pts.len(), "{name}");
            let differ: Vec<usize> = (0..pts.len())
                .filter(|&i| peer.labels[i] != ours.labels[i] || peer.core[i] != ours.core[i])
                .collect();
            let seen = Seen {
                clusters: ours.clusters,
                noise: ours.noise(),
                contested: contested(pts, &ours, eps),
            };
            eprintln!(
                "{name}: {} points, eps {eps} m, min_samples {min_samples}: {} clusters, {} \
                 noise, {} core, contested border points {:?}; scikit-learn's neighbours by {}; \
                 {} points differ",
                pts.len(),
                seen.clusters,
                seen.noise,
                ours.core.iter().filter(|&&c| c).count(),
                seen.contested,
                peer.algorithm,
                differ.len()
            );
            if let Some(&i) = differ.first() {
                panic!(
                    "{name}, eps {eps}, min_samples {min_samples}: {} of {} points differ, e.g. \
                     point {i}: ours label {} core {}, scikit-learn's label {} core {}",
                    differ.len(),
                    pts.len(),
                    ours.labels[i],
                    ours.core[i],
                    peer.labels[i],
                    peer.core[i]
                );
            }
            seen
        })
        .collect()
}

#[test]
fn labels_equal_scikit_learns_on_blobs_with_noise() {
    let Some(py) = peer_python() else { return };
    let centres = [
        [0.0, 0.0, 0.0],
        [0.06, 0.0, 0.01],
        [0.0, 0.1, 0.0],
        [0.2, 0.15, 0.05],
    ];
    let params = [(0.02, 15), (0.01, 5), (0.03, 30), (0.005, 3)];
    let cases: Vec<Case> = (1..=3u64)
        .map(|seed| {
            let pts = blobs(seed, &centres, 600, 0.01, 400, [-0.1; 3], [0.3, 0.3, 0.15]);
            Case::new(format!("blobs{seed}"), pts, &params)
        })
        .collect();
    for seen in compare(&py, &cases) {
        // Non-trivial cases: several clusters and noise with PyRobot's parameters, and
        // border points that the rule for them decides.
        assert!(seen[0].clusters >= 2 && seen[0].noise > 50);
    }
}

/// A chain of tight blobs (20 points within 8 mm) 48 mm apart, so that with eps 0.02 m and
/// min_samples 15 their core points stay apart, and a point at each midpoint that reaches a
/// few points of both neighbours (the 4 mm deep caps of their balls): a border point contested by two clusters. Shuffled, so
/// that the clusters' numbers do not follow the chain.
fn contested_chain(seed: u64) -> Vec<Point3<f64>> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut pts = Vec::new();
    for k in 0..40 {
        let c = Point3::new(0.048 * k as f64, 0.0, 0.0);
        for _ in 0..20 {
            loop {
                let d = nalgebra::Vector3::new(
                    rng.random_range(-0.008..0.008),
                    rng.random_range(-0.008..0.008),
                    rng.random_range(-0.008..0.008),
                );
                if d.norm() <= 0.008 {
                    pts.push(c + d);
                    break;
                }
            }
        }
        pts.push(c + nalgebra::Vector3::new(0.024, rng.random_range(-0.001..0.001), 0.0));
    }
    for i in (1..pts.len()).rev() {
        pts.swap(i, rng.random_range(0..=i));
    }
    pts
}

#[test]
fn labels_equal_scikit_learns_where_border_points_are_contested() {
    let Some(py) = peer_python() else { return };
    let params = [(0.02, 15), (0.02, 12), (0.021, 15)];
    let cases: Vec<Case> = [1u64, 2, 3]
        .iter()
        .map(|&seed| Case::new(format!("chain{seed}"), contested_chain(seed), &params))
        .collect();
    for seen in compare(&py, &cases) {
        let contested = seen[0].contested.unwrap_or(0);
        assert!(contested >= 10, "only {contested} contested border points");
    }
}

#[test]
fn labels_equal_scikit_learns_on_a_table_top_camera_cloud() {
    let Some(py) = peer_python() else { return };
    let mut cases = Vec::new();
    for seed in [1u64, 2] {
        let scene = Tabletop::random(seed, 8, 0.04);
        // The whole view at 160x120 (floor, table and objects, D435-like noise).
        let cloud = DepthCamera::looking_down(locobot_intrinsics())
            .scaled(0.25)
            .cloud(&scene, seed)
            .unwrap();
        cases.push(Case::new(
            format!("view{seed}"),
            cloud.points,
            &[(0.02, 15), (0.01, 4), (0.05, 40)],
        ));
        // PyRobot's pushing pipeline: the full 640x480 view, the table's plane, the points
        // 1 cm to 0.5 m above it over the table, DBSCAN (0.02, 15).
        let full = DepthCamera::looking_down(locobot_intrinsics())
            .cloud(&scene, seed)
            .unwrap();
        let fit = fit_plane(
            &full.points,
            &RansacParams {
                threshold: 0.008,
                max_tilt: 0.3,
                seed,
                ..Default::default()
            },
        )
        .unwrap();
        let above = above_table(&full.points, &fit, &SegmentParams::default()).unwrap();
        let objects: Vec<Point3<f64>> = above.iter().map(|&i| full.points[i]).collect();
        cases.push(Case::new(format!("objects{seed}"), objects, &[(0.02, 15)]));
    }
    let seen = compare(&py, &cases);
    for objects in [&seen[1], &seen[3]] {
        assert!(
            objects[0].clusters >= 6,
            "{} objects of 8",
            objects[0].clusters
        );
    }
}

#[test]
fn labels_equal_scikit_learns_on_a_lattice_with_ties_at_eps() {
    // A 1 cm lattice with stacked duplicates: many pairs lie exactly (or within a rounding
    // of) eps apart, where the comparison's form decides.
    let Some(py) = peer_python() else { return };
    let mut pts = Vec::new();
    for i in 0..30 {
        for j in 0..20 {
            for k in 0..3 {
                let p = Point3::new(i as f64 * 0.01, j as f64 * 0.01, k as f64 * 0.01);
                pts.push(p);
                if (i * 7 + j * 3 + k) % 11 == 0 {
                    pts.push(p);
                }
            }
        }
    }
    let params = [(0.01, 7), (0.01, 8), (0.02, 20), (0.015, 12), (0.03, 90)];
    compare(&py, &[Case::new("lattice", pts, &params)]);
}
