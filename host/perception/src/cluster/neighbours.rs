//! Where DBSCAN looks for a point's neighbours (m): a grid of cells `eps` wide, or kiddo's k-d
//! tree for a cloud spread too far for a grid.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;

use crate::error::{PerceptionError, Result};
use crate::grid::CellGrid;

/// Most cells of DBSCAN's grid per point; a cloud spread wider for its `eps` is searched
/// through kiddo's k-d tree instead.
const GRID_CELLS_PER_POINT: usize = 16;

/// Where one cell of DBSCAN's grid holds more points than this, exact duplicates in cells of
/// more than [`MERGE_IN_CELLS_ABOVE`] points are merged ([`CellGrid::merge_duplicates`]): a
/// crowd of copies just beyond many points' reach would otherwise cost each of them the whole
/// crowd. (A depth camera's surface seen face-on at 0.2 m puts about 3,600 points in a 2 cm
/// cell, none of them equal.)
const CROWDED_CELL: usize = 2048;

/// See [`CROWDED_CELL`].
const MERGE_IN_CELLS_ABOVE: usize = 64;

/// Where DBSCAN looks for a point's neighbours: a grid of cells `eps` wide with the points
/// sorted by cell (compact clouds), or kiddo's k-d tree over the points in the caller's order.
/// Both name points by their *position* in [`Neighbours::pts`].
pub(super) enum Neighbours {
    Grid(CellGrid),
    Tree {
        pts: Vec<[f64; 3]>,
        tree: ImmutableKdTree<f64, 3>,
    },
}

impl Neighbours {
    /// The grid of cells `eps` wide over `points` where it needs at most
    /// [`GRID_CELLS_PER_POINT`] cells per point, else the tree.
    pub(super) fn new(points: &[Point3<f64>], eps: f64) -> Result<Self> {
        let pts: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let max_cells = GRID_CELLS_PER_POINT.saturating_mul(pts.len());
        match CellGrid::new(&pts, eps, max_cells) {
            Some(mut grid) => {
                if grid.most() > CROWDED_CELL {
                    grid.merge_duplicates(MERGE_IN_CELLS_ABOVE);
                }
                Ok(Neighbours::Grid(grid))
            }
            None => Self::tree(pts),
        }
    }

    /// How many of the caller's points the point at position `s` stands for.
    #[inline]
    pub(super) fn weight(&self, s: usize) -> usize {
        match self {
            Neighbours::Grid(g) => g.weight(s),
            Neighbours::Tree { .. } => 1,
        }
    }

    /// Values by position, `v`, given to every point of the caller's (in its order).
    pub(super) fn to_caller<T: Copy + Default>(&self, v: &[T]) -> Vec<T> {
        match self {
            Neighbours::Grid(g) => {
                let mut out = vec![T::default(); g.caller_len()];
                if g.merged() {
                    for (s, &x) in v.iter().enumerate() {
                        for &o in g.copies(s) {
                            out[o as usize] = x;
                        }
                    }
                } else {
                    for (&o, &x) in g.orig.iter().zip(v) {
                        out[o as usize] = x;
                    }
                }
                out
            }
            Neighbours::Tree { .. } => v.to_vec(),
        }
    }

    /// Kiddo's k-d tree over `pts`.
    pub(super) fn tree(pts: Vec<[f64; 3]>) -> Result<Self> {
        let tree = ImmutableKdTree::new_from_slice(&pts)
            .map_err(|e| PerceptionError::KdTree(format!("{e:?}")))?;
        Ok(Neighbours::Tree { pts, tree })
    }

    /// The points, by position.
    pub(super) fn pts(&self) -> &[[f64; 3]] {
        match self {
            Neighbours::Grid(g) => &g.pts,
            Neighbours::Tree { pts, .. } => pts,
        }
    }

    /// The caller's index of the point at position `s`.
    pub(super) fn orig(&self, s: usize) -> usize {
        match self {
            Neighbours::Grid(g) => g.orig[s] as usize,
            Neighbours::Tree { .. } => s,
        }
    }

    /// Calls `visit(position, d²)` for every point within squared distance `r2` of `p`.
    #[inline]
    pub(super) fn within(&self, p: &[f64; 3], r2: f64, mut visit: impl FnMut(u32, f64)) {
        match self {
            Neighbours::Grid(g) => g.within(p, r2, visit),
            Neighbours::Tree { tree, .. } => tree
                .query(p)
                .within::<SquaredEuclidean<f64>>(r2)
                .unsorted()
                .visit(|hit| visit(hit.item, hit.distance)),
        }
    }

    /// At least the number of points within `eps` of `p`, where that is cheap to bound (the
    /// grid's cells around it); else `usize::MAX`.
    #[inline]
    pub(super) fn at_most(&self, p: &[f64; 3], eps: f64) -> usize {
        match self {
            Neighbours::Grid(g) => g.count_around(p, eps),
            Neighbours::Tree { .. } => usize::MAX,
        }
    }
}
