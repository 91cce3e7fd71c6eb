//! Joining DBSCAN's groups of core points (m): the pairs of leaders close enough to be joined,
//! whether two groups have core points within `eps` of each other, and the disjoint sets they
//! are joined in.

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::error::{PerceptionError, Result};
use crate::grid::{d2, CellGrid};

/// Below this many pairs, two leaders' groups are compared pair by pair; above, through a
/// k-d tree of one of them.
const BRUTE_PAIRS: usize = 1 << 14;

/// Most cells of a [`near_pairs`] grid per point.
const PAIR_CELLS_PER_POINT: usize = 8;

/// Calls `visit(a, b, d²)` for every pair `a < b` of `pts` whose squared distance
/// ([`d2`]) is at most `reach2` (positive), in no particular order.
///
/// On a [`CellGrid`] of cubes `sqrt(reach2)` wide, each point scanning the cubes around its
/// own: for the few thousand leaders DBSCAN joins, faster than a radius query per point on
/// kiddo's tree, whose per-query cost dominates at this size (the `blobs` benchmark cloud's
/// 7,551 leaders, visits included: 13 ms against 18-23 ms, same machine, same load; the
/// whole clustering 7 % fewer instructions). Where the grid would need more than
/// [`PAIR_CELLS_PER_POINT`] cells per point (points spread far apart), kiddo's tree.
pub(super) fn near_pairs(
    pts: &[[f64; 3]],
    reach2: f64,
    mut visit: impl FnMut(usize, usize, f64),
) -> Result<()> {
    let max_cells = PAIR_CELLS_PER_POINT.saturating_mul(pts.len());
    let Some(grid) = CellGrid::new(pts, reach2.sqrt(), max_cells) else {
        let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(pts)
            .map_err(|e| PerceptionError::KdTree(format!("{e:?}")))?;
        for (a, p) in pts.iter().enumerate() {
            tree.query(p)
                .within::<SquaredEuclidean<f64>>(reach2)
                .unsorted()
                .visit(|hit| {
                    let b = hit.item as usize;
                    if b > a {
                        visit(a, b, hit.distance);
                    }
                });
        }
        return Ok(());
    };
    // Each pair once: from the earlier of its two sorted positions.
    for sa in 0..grid.pts.len() {
        let a = grid.orig[sa] as usize;
        grid.within_after(sa, reach2, |sb, d| {
            let b = grid.orig[sb as usize] as usize;
            visit(a.min(b), a.max(b), d);
        });
    }
    Ok(())
}

/// Whether two groups of core points are within `eps` of each other somewhere, with reused
/// buffers (no allocation per pair once they have grown).
#[derive(Default)]
pub(super) struct Bridge {
    a: Vec<[f64; 3]>,
    b: Vec<[f64; 3]>,
}

impl Bridge {
    /// Whether some point of `a` (a group within `eps / 2` of leader `la`) lies within `eps`
    /// of some point of `b` (within `eps / 2` of `lb`).
    pub(super) fn connects(
        &mut self,
        a: &[[f64; 3]],
        la: &[f64; 3],
        b: &[[f64; 3]],
        lb: &[f64; 3],
        eps: f64,
    ) -> Result<bool> {
        let eps2 = eps * eps;
        // A point of `a` with a partner in `b` lies within eps + eps / 2 of `b`'s leader (and
        // the other way round); the margin of LEADER_SHRINK covers rounding.
        let reach2 = 2.25 * eps2;
        self.a.clear();
        self.a.extend(a.iter().filter(|p| d2(p, lb) <= reach2));
        self.b.clear();
        self.b.extend(b.iter().filter(|p| d2(p, la) <= reach2));
        if self.a.is_empty() || self.b.is_empty() {
            return Ok(false);
        }
        if self.a.len().saturating_mul(self.b.len()) <= BRUTE_PAIRS {
            return Ok(self
                .a
                .iter()
                .any(|p| self.b.iter().any(|q| d2(p, q) <= eps2)));
        }
        let (small, large) = if self.a.len() <= self.b.len() {
            (&self.a, &self.b)
        } else {
            (&self.b, &self.a)
        };
        let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(small)
            .map_err(|e| PerceptionError::KdTree(format!("{e:?}")))?;
        Ok(large.iter().any(|p| {
            let mut hit = false;
            tree.query(p)
                .within::<SquaredEuclidean<f64>>(eps2)
                .unsorted()
                .visit(|_| hit = true);
            hit
        }))
    }
}

/// Disjoint sets over `0..n` (union by size, path halving).
pub(super) struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    pub(super) fn new(n: usize) -> Self {
        UnionFind {
            parent: (0..n as u32).collect(),
            size: vec![1; n],
        }
    }

    pub(super) fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] as usize != x {
            let up = self.parent[self.parent[x] as usize];
            self.parent[x] = up;
            x = up as usize;
        }
        x
    }

    pub(super) fn union(&mut self, a: usize, b: usize) {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return;
        }
        if self.size[a] < self.size[b] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b] = a as u32;
        self.size[a] += self.size[b];
    }
}
