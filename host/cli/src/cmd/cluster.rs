//! `ferrobot cluster`: DBSCAN on a PLY cloud, with scikit-learn's semantics and labels, so that
//! the clustering can be checked against other implementations.

use std::path::Path;

use ferrobot::perception::io::read_ply;
use ferrobot::perception::{Clusterer, Dbscan};
use serde::Serialize;

use super::common::print_json;

/// Clusters listed by size in the text summary; the rest are counted.
const LISTED: usize = 20;

/// `cluster --json`: one label per point, in the file's order (fields in alphabetical order,
/// see [`print_json`]).
#[derive(Serialize)]
struct LabelsJson {
    /// Cluster of each point (0, 1, ...), -1 for noise.
    labels: Vec<i32>,
}

/// Cluster the cloud in `input` (PLY; its points in metres) with DBSCAN (`eps` m,
/// `min_samples` points counting the point itself) and print the labels (`json`) or a summary.
/// The parameters are checked before the file is read.
pub fn run(input: &Path, eps: f64, min_samples: usize, json: bool) -> ferrobot::Result<()> {
    let dbscan = Dbscan::new(eps, min_samples)?;
    let cloud = read_ply(input)?;
    let c = dbscan.cluster(&cloud.points)?;
    if json {
        print_json(&LabelsJson { labels: c.labels });
        return Ok(());
    }
    let noise = c.noise();
    say!(
        "{}: {} points, DBSCAN eps {eps} m, min_samples {min_samples}: {} clusters, {} noise \
         points ({:.1} %)",
        input.display(),
        cloud.len(),
        c.clusters,
        noise,
        100.0 * noise as f64 / cloud.len() as f64
    );
    let mut sizes: Vec<(usize, usize)> = c.sizes().into_iter().enumerate().collect();
    sizes.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    for &(label, size) in sizes.iter().take(LISTED) {
        say!("  cluster {label}: {size} points");
    }
    if sizes.len() > LISTED {
        let rest: usize = sizes[LISTED..].iter().map(|s| s.1).sum();
        say!(
            "  ... and {} smaller clusters of {rest} points in all",
            sizes.len() - LISTED
        );
    }
    Ok(())
}
