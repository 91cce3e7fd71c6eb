//! DBSCAN by exhaustive search ([`ExhaustiveDbscan`]): the literal algorithm, a reference to
//! check the fast one against.

use nalgebra::Point3;

use super::{check_cloud, Clusterer, Clustering, DbscanParams, NOISE};
use crate::error::Result;
use crate::grid::d2;

/// DBSCAN by exhaustive search: scikit-learn's algorithm line for line (neighbourhoods by
/// comparing every pair, core flags, then a depth-first search from each unlabelled core
/// point in index order that labels every unlabelled neighbour of each core point it
/// reaches). O(n²) time and O(n) memory: a reference to check [`Dbscan`](super::Dbscan) against, and enough
/// for a few thousand points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExhaustiveDbscan {
    /// The parameters.
    pub params: DbscanParams,
}

impl ExhaustiveDbscan {
    /// Exhaustive DBSCAN with checked parameters ([`DbscanParams::new`]).
    pub fn new(eps: f64, min_samples: usize) -> Result<Self> {
        Ok(ExhaustiveDbscan {
            params: DbscanParams::new(eps, min_samples)?,
        })
    }
}

impl Clusterer for ExhaustiveDbscan {
    fn cluster(&self, points: &[Point3<f64>]) -> Result<Clustering> {
        self.params.check()?;
        check_cloud(points)?;
        let n = points.len();
        let eps2 = self.params.eps * self.params.eps;
        let pts: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let neighbours = |i: usize| {
            let p = pts[i];
            pts.iter()
                .enumerate()
                .filter(move |(_, q)| d2(&p, q) <= eps2)
                .map(|(j, _)| j)
        };
        let core: Vec<bool> = (0..n)
            .map(|i| neighbours(i).count() >= self.params.min_samples)
            .collect();
        let mut labels = vec![NOISE; n];
        let mut clusters = 0usize;
        let mut stack = Vec::new();
        for start in 0..n {
            if labels[start] != NOISE || !core[start] {
                continue;
            }
            let label = clusters as i32;
            let mut i = start;
            loop {
                if labels[i] == NOISE {
                    labels[i] = label;
                    if core[i] {
                        stack.extend(neighbours(i).filter(|&v| labels[v] == NOISE));
                    }
                }
                match stack.pop() {
                    Some(v) => i = v,
                    None => break,
                }
            }
            clusters += 1;
        }
        Ok(Clustering {
            labels,
            core,
            clusters,
        })
    }
}
