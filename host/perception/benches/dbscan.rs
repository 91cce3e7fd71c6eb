//! DBSCAN on 100,000 points, single-threaded, beside scikit-learn's on the same clouds in the
//! same run. Run: `cargo bench -p ferrobot-perception --bench dbscan` (scikit-learn from
//! `FERROBOT_PYTHON` or `target/py-venv`, made by `scripts/python-env.sh cluster`; without it
//! only our times are printed).
//!
//! The clouds (seeded, the same on every machine), each written to a PLY file and read back
//! so that both sides cluster the same float32-rounded points:
//! * `view`: a table-top scene (a 0.6 x 1.0 m table, 10 objects of 2-8 cm, the floor) seen
//!   by the LoCoBot's D435 ray-cast at 640x480 with depth noise (2 mm at 1 m, growing with
//!   the square of depth), depths in (0.2, 1.5) m: 100,000 of its points drawn at random,
//!   kept in pixel order.
//! * `objects`: PyRobot's pushing pipeline on the same view (all its points): the table's
//!   plane by RANSAC, the points 1 cm to 0.5 m above it over the table; what one frame gives
//!   (about 20,000 points), not 100,000.
//! * `blobs`: 40 Gaussian blobs (15 mm, 2000 points each) and 20,000 uniform noise points
//!   in a 1 m cube, shuffled: 100,000 points.
//! * with `FERROBOT_BENCH_CLOUD=FILE.ply`, that cloud too (e.g. the simulator's own frame:
//!   `ferrobot snapshot locobot --scene tabletop --out DIR` writes `DIR/cloud.ply`).
//!
//! `FERROBOT_BENCH_ONLY=NAME` (`view`, `objects`, `blobs` or `file`) runs that cloud alone.
//!
//! Ours: median and best of 15 runs after one warm-up, on the calling thread (the grid of
//! cells built in every run). scikit-learn: `DBSCAN(eps, min_samples).fit(X)` (tree, neighbourhoods
//! and labels), median and best of 3, one thread. The labels of the two are compared point
//! by point.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use ferrobot_perception::io::{read_ply, write_ply};
use ferrobot_perception::synthetic::{blobs, DepthCamera, Tabletop};
use ferrobot_perception::{
    above_table, fit_plane, Clusterer, Dbscan, Intrinsics, PointCloud, RansacParams, SegmentParams,
};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const N: usize = 100_000;

#[path = "../tests/support/locobot_camera.rs"]
mod locobot_camera;
use locobot_camera::locobot_intrinsics;

/// `n` of `points` drawn at random (seeded), in their original order.
fn subset(points: &[Point3<f64>], n: usize, seed: u64) -> Vec<Point3<f64>> {
    assert!(points.len() >= n, "{} points, fewer than {n}", points.len());
    let mut idx: Vec<usize> = (0..points.len()).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for i in 0..n {
        let j = rng.random_range(i..idx.len());
        idx.swap(i, j);
    }
    let mut keep = idx[..n].to_vec();
    keep.sort_unstable();
    keep.iter().map(|&i| points[i]).collect()
}

fn clouds() -> Vec<(&'static str, Vec<Point3<f64>>, f64, usize)> {
    let scene = Tabletop::random(1, 10, 0.04);
    let view = DepthCamera::looking_down(locobot_intrinsics())
        .cloud(&scene, 1)
        .expect("renders");
    let fit = fit_plane(
        &view.points,
        &RansacParams {
            threshold: 0.008,
            max_tilt: 0.3,
            ..Default::default()
        },
    )
    .expect("a table");
    let above = above_table(&view.points, &fit, &SegmentParams::default()).expect("objects");
    let objects: Vec<Point3<f64>> = above.iter().map(|&i| view.points[i]).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let centres: Vec<[f64; 3]> = (0..40)
        .map(|_| [0; 3].map(|_| rng.random_range(0.0..1.0)))
        .collect();
    let b = blobs(3, &centres, 2000, 0.015, 20_000, [0.0; 3], [1.0; 3]);
    println!(
        "view: {} points rendered, {N} drawn; objects: {} points above the table of {}",
        view.len(),
        objects.len(),
        scene.objects.len()
    );
    let mut clouds = vec![
        ("view", subset(&view.points, N, 1), 0.02, 15),
        ("objects", objects, 0.02, 15),
        ("blobs", b, 0.02, 15),
    ];
    if let Some(path) = std::env::var_os("FERROBOT_BENCH_CLOUD") {
        let cloud = read_ply(&path).expect("FERROBOT_BENCH_CLOUD: a PLY cloud");
        clouds.push(("file", cloud.points, 0.02, 15));
    }
    clouds
}

/// The peer's Python: `FERROBOT_PYTHON`, else the workspace's venv, if it has scikit-learn.
fn peer_python() -> Option<PathBuf> {
    ferrobot_peers::for_bench("sklearn.cluster, threadpoolctl")
}

/// scikit-learn's labels and fit times (s) on the cloud in `ply`.
fn sklearn(py: &Path, ply: &Path, eps: f64, m: usize) -> (Vec<i32>, Vec<f64>, String) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("peer/dbscan_peer.py");
    let out = Command::new(py)
        .arg(script)
        .arg(ply)
        .args(["--eps", &eps.to_string(), "--min-samples", &m.to_string()])
        .args(["--repeat", "3"])
        .output()
        .expect("runs the peer");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let labels = v["labels"]
        .as_array()
        .expect("labels")
        .iter()
        .map(|l| l.as_i64().unwrap_or(i64::MIN) as i32)
        .collect();
    let secs = v["seconds"]
        .as_array()
        .expect("seconds")
        .iter()
        .filter_map(|s| s.as_f64())
        .collect();
    (labels, secs, v["sklearn"].as_str().unwrap_or("?").into())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Mean number of neighbours within `eps` (the point itself included).
fn mean_neighbours(points: &[Point3<f64>], eps: f64) -> f64 {
    let pts: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(&pts).expect("tree");
    let mut total = 0usize;
    for p in &pts {
        tree.query(p)
            .within::<SquaredEuclidean<f64>>(eps * eps)
            .unsorted()
            .visit(|_| total += 1);
    }
    total as f64 / pts.len() as f64
}

fn main() {
    let dir: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/bench-dbscan");
    std::fs::create_dir_all(&dir).expect("output directory");
    let py = peer_python();
    let mut rows = Vec::new();
    let mut version = String::from("not run");
    let only = std::env::var("FERROBOT_BENCH_ONLY").ok();
    for (name, points, eps, m) in clouds() {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let path = dir.join(format!("{name}.ply"));
        let cloud = PointCloud {
            colours: vec![[128; 3]; points.len()],
            points,
        };
        write_ply(&path, &cloud).expect("writes");
        let pts = read_ply(&path).expect("reads").points;
        let dbscan = Dbscan::new(eps, m).expect("parameters");
        let ours = dbscan.cluster(&pts).expect("clusters");
        let mut times = Vec::new();
        for _ in 0..15 {
            let t = Instant::now();
            let r = dbscan
                .cluster(std::hint::black_box(&pts))
                .expect("clusters");
            times.push(t.elapsed());
            std::hint::black_box(r);
        }
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        let ours_med = median(times.iter().map(|&d| ms(d)).collect());
        let ours_best = times.iter().map(|&d| ms(d)).fold(f64::INFINITY, f64::min);
        let (sk, equal) = match &py {
            Some(py) => {
                let (labels, secs, v) = sklearn(py, &path, eps, m);
                version = v;
                let best = secs.iter().copied().fold(f64::INFINITY, f64::min) * 1e3;
                let differ = labels
                    .iter()
                    .zip(&ours.labels)
                    .filter(|(a, b)| a != b)
                    .count();
                (
                    Some((median(secs) * 1e3, best)),
                    if differ == 0 {
                        "all".to_string()
                    } else {
                        format!("{differ} differ")
                    },
                )
            }
            None => (None, "-".to_string()),
        };
        rows.push((
            name,
            pts.len(),
            mean_neighbours(&pts, eps),
            ours.clusters,
            ours.noise(),
            ours_med,
            ours_best,
            sk,
            equal,
        ));
    }
    println!(
        "\nDBSCAN, single thread, ferrobot (grid of cells eps wide) vs scikit-learn {version}"
    );
    println!(
        "| cloud | points | eps, min_samples | mean neighbours | clusters | noise | ours: median (best) | scikit-learn: median (best) | ratio (medians) | labels equal |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (name, n, nb, c, noise, med, best, sk, equal) in rows {
        let (skt, ratio) = match sk {
            Some((m, b)) => (format!("{m:.0} ms ({b:.0} ms)"), format!("{:.0}x", m / med)),
            None => ("not run".into(), "-".into()),
        };
        println!(
            "| {name} | {n} | 0.02 m, 15 | {nb:.0} | {c} | {noise} | {med:.1} ms ({best:.1} ms) | {skt} | {ratio} | {equal} |"
        );
    }
    if py.is_none() {
        println!("\n(scikit-learn not found: run scripts/python-env.sh cluster)");
    }
}
