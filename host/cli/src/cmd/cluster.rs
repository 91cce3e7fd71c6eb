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

/// `ferrobot cluster`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The cloud: a PLY file (ASCII or binary little-endian, vertices with x y z).
    #[arg(long = "in", value_name = "CLOUD.ply")]
    pub input: std::path::PathBuf,
    /// Neighbourhood radius, m (finite, in (0, 100]).
    #[arg(long, allow_negative_numbers = true)]
    pub eps: f64,
    /// Neighbours (the point itself included) that make a point core (1 to 1,000,000).
    #[arg(long)]
    pub min_samples: usize,
    /// Print one JSON object: `{"labels": [...]}`, one label per point, -1 for noise.
    #[arg(long)]
    pub json: bool,
}

/// Cluster the cloud in `--in` (PLY; its points in metres) with DBSCAN (`--eps` m,
/// `--min-samples` points counting the point itself) and print the labels (`--json`) or a
/// summary. The parameters are checked before the file is read.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let (input, eps, min_samples, json): (&Path, f64, usize, bool) =
        (&a.input, a.eps, a.min_samples, a.json);
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
