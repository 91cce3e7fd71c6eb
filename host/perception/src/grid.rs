//! A uniform grid of cubic cells over a cloud, its points sorted by cell: the neighbour index
//! of DBSCAN ([`crate::cluster`]) where the cloud is compact enough for one.
//!
//! Why a hand-written grid beside kiddo's k-d tree: at DBSCAN's radius the grid is a counting
//! sort (a few milliseconds for 100,000 points, where the tree takes 15-20 ms on the same
//! machine), a radius query is a handful of contiguous runs of points instead of a tree
//! descent, and the count of points in the cells around a point bounds its neighbourhood
//! without a query at all. Where the cloud is spread too far for a grid of bounded size, the
//! callers fall back on kiddo.

/// Margin, in cells, added to every cell range: far beyond the rounding of a cell coordinate
/// (at most a few 1e-10 cell for the at most [`MAX_DIM`] cells per axis allowed), so a range
/// holds every point it must whatever the rounding.
const MARGIN: f64 = 1e-6;

/// Most cells per axis (bounds the rounding of a cell coordinate, see [`MARGIN`]).
const MAX_DIM: usize = 1 << 20;

/// Squared Euclidean distance, summed x, y, z in that order (as scikit-learn's k-d tree and
/// kiddo sum it), m².
#[inline(always)]
pub(crate) fn d2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let (dx, dy, dz) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    dx * dx + dy * dy + dz * dz
}

/// Points of a cloud sorted into cubic cells, z fastest: the cells `z0..=z1` of one (x, y)
/// column are one contiguous run of the sorted points.
pub(crate) struct CellGrid {
    lo: [f64; 3],
    /// Cells per metre.
    inv: f64,
    dims: [usize; 3],
    /// Sorted position of each cell's first point, one more than the cells.
    start: Vec<u32>,
    /// The points, sorted by cell.
    pub pts: Vec<[f64; 3]>,
    /// The index in the caller's slice of each sorted point (the lowest of its copies, once
    /// duplicates are merged).
    pub orig: Vec<u32>,
    /// Exact duplicates merged by [`CellGrid::merge_duplicates`], if they were.
    copies: Option<Copies>,
}

/// The points of the caller's that each sorted point stands for, once exact duplicates are
/// merged.
struct Copies {
    /// Copies of each sorted point.
    weight: Vec<u32>,
    /// Copies before each sorted position (one more than the points).
    before: Vec<u32>,
    /// The caller's indices of the copies of sorted point `s`: `of[before[s]..before[s + 1]]`,
    /// ascending.
    of: Vec<u32>,
}

impl CellGrid {
    /// The grid of cells `cell` wide (m, positive) over `pts`, or `None` where it would need
    /// more than `max_cells` cells or more than [`MAX_DIM`] on an axis. `pts` must be finite
    /// and fewer than `u32::MAX`.
    pub fn new(pts: &[[f64; 3]], cell: f64, max_cells: usize) -> Option<Self> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in pts {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let inv = 1.0 / cell;
        let mut dims = [0usize; 3];
        let mut cells = 1usize;
        for k in 0..3 {
            let d = ((hi[k] - lo[k]) * inv).floor();
            if !(d.is_finite() && d < MAX_DIM as f64) {
                return None;
            }
            dims[k] = d as usize + 1;
            cells = cells.checked_mul(dims[k])?;
        }
        // Cells are numbered in u32.
        if cells > max_cells || cells >= u32::MAX as usize {
            return None;
        }
        let mut grid = CellGrid {
            lo,
            inv,
            dims,
            start: vec![0u32; cells + 1],
            pts: vec![[0.0; 3]; pts.len()],
            orig: vec![0u32; pts.len()],
            copies: None,
        };
        let cell_of: Vec<u32> = pts.iter().map(|p| grid.cell_of(p) as u32).collect();
        for &c in &cell_of {
            grid.start[c as usize + 1] += 1;
        }
        for c in 0..cells {
            grid.start[c + 1] += grid.start[c];
        }
        let mut fill = grid.start.clone();
        for (i, &c) in cell_of.iter().enumerate() {
            let at = fill[c as usize] as usize;
            grid.orig[at] = i as u32;
            grid.pts[at] = pts[i];
            fill[c as usize] += 1;
        }
        Some(grid)
    }

    /// Most points in one cell.
    pub fn most(&self) -> usize {
        self.start
            .windows(2)
            .map(|w| (w[1] - w[0]) as usize)
            .max()
            .unwrap_or(0)
    }

    /// Merges the exact duplicates (equal coordinates) within each cell of more than `above`
    /// points into one sorted point that stands for all its copies ([`CellGrid::weight`],
    /// [`CellGrid::copies`]): a crowd of copies (a cloud's invalid points all at the origin,
    /// say) then costs a query one point instead of thousands. Distances from a merged point
    /// are those from each copy, so counts weighted by copies are the caller's counts.
    pub fn merge_duplicates(&mut self, above: usize) {
        let n = self.pts.len();
        let cells = self.start.len() - 1;
        let mut pts = Vec::with_capacity(n);
        let mut orig = Vec::with_capacity(n);
        let mut weight = Vec::with_capacity(n);
        let mut of = Vec::with_capacity(n);
        let mut start = vec![0u32; cells + 1];
        let mut order: Vec<usize> = Vec::new();
        for c in 0..cells {
            let (a, b) = (self.start[c] as usize, self.start[c + 1] as usize);
            order.clear();
            order.extend(a..b);
            if b - a > above {
                // Equal coordinates together, each run in the caller's order.
                order.sort_unstable_by(|&i, &j| {
                    let (p, q) = (&self.pts[i], &self.pts[j]);
                    (p[0].total_cmp(&q[0]))
                        .then(p[1].total_cmp(&q[1]))
                        .then(p[2].total_cmp(&q[2]))
                        .then(self.orig[i].cmp(&self.orig[j]))
                });
            }
            let mut k = 0;
            while k < order.len() {
                let p = self.pts[order[k]];
                let mut e = k + 1;
                while e < order.len() && self.pts[order[e]] == p {
                    e += 1;
                }
                pts.push(p);
                orig.push(self.orig[order[k]]);
                weight.push((e - k) as u32);
                of.extend(order[k..e].iter().map(|&i| self.orig[i]));
                k = e;
            }
            start[c + 1] = pts.len() as u32;
        }
        let mut before = Vec::with_capacity(weight.len() + 1);
        before.push(0u32);
        let mut total = 0u32;
        for &w in &weight {
            total += w;
            before.push(total);
        }
        self.pts = pts;
        self.orig = orig;
        self.start = start;
        self.copies = Some(Copies { weight, before, of });
    }

    /// Whether duplicates were merged ([`CellGrid::merge_duplicates`]).
    pub fn merged(&self) -> bool {
        self.copies.is_some()
    }

    /// The number of the caller's points.
    pub fn caller_len(&self) -> usize {
        self.copies.as_ref().map_or(self.pts.len(), |c| c.of.len())
    }

    /// The number of the caller's points that sorted point `s` stands for.
    #[inline]
    pub fn weight(&self, s: usize) -> usize {
        self.copies.as_ref().map_or(1, |c| c.weight[s] as usize)
    }

    /// The caller's indices of the points that sorted point `s` stands for (ascending).
    pub fn copies(&self, s: usize) -> &[u32] {
        match &self.copies {
            Some(c) => &c.of[c.before[s] as usize..c.before[s + 1] as usize],
            None => std::slice::from_ref(&self.orig[s]),
        }
    }

    /// The cell holding `p` (a point of the grid's cloud).
    fn cell_of(&self, p: &[f64; 3]) -> usize {
        let c = |k: usize| (((p[k] - self.lo[k]) * self.inv) as usize).min(self.dims[k] - 1);
        (c(0) * self.dims[1] + c(1)) * self.dims[2] + c(2)
    }

    /// The cells, from and to (inclusive) along each axis, that hold every point of the grid
    /// within `radius` (m) of `p` on each axis; `None` when no cell does.
    #[inline]
    fn span(&self, p: &[f64; 3], radius: f64) -> Option<([usize; 3], [usize; 3])> {
        let mut from = [0usize; 3];
        let mut to = [0usize; 3];
        for k in 0..3 {
            let t = (p[k] - self.lo[k]) * self.inv;
            let reach = radius * self.inv + MARGIN;
            let (a, b) = (t - reach, t + reach);
            if !(b >= 0.0 && a < self.dims[k] as f64) {
                return None;
            }
            // Truncation is the floor for these non-negative values (a negative `a`: cell 0).
            from[k] = a.max(0.0) as usize;
            to[k] = (b as usize).min(self.dims[k] - 1);
        }
        Some((from, to))
    }

    /// Calls `visit(from, to)` for runs of sorted positions that hold, between them, every
    /// point of the grid within `radius` (m) of `p` on each axis (and others near it), until
    /// `visit` returns `false`.
    #[inline]
    pub fn runs(&self, p: &[f64; 3], radius: f64, mut visit: impl FnMut(usize, usize) -> bool) {
        let Some((from, to)) = self.span(p, radius) else {
            return;
        };
        for x in from[0]..=to[0] {
            for y in from[1]..=to[1] {
                let column = (x * self.dims[1] + y) * self.dims[2];
                let a = self.start[column + from[2]] as usize;
                let b = self.start[column + to[2] + 1] as usize;
                if b > a && !visit(a, b) {
                    return;
                }
            }
        }
    }

    /// Whether at least `k` points (copies counted) lie within squared distance `r2` (m²) of
    /// `p` (counting stops once they do; on a merged grid, also once the points left cannot
    /// make up the difference).
    #[inline]
    pub fn reaches(&self, p: &[f64; 3], r2: f64, k: usize) -> bool {
        let radius = r2.sqrt();
        let mut count = 0usize;
        match &self.copies {
            None => self.runs(p, radius, |a, b| {
                for q in &self.pts[a..b] {
                    count += (d2(p, q) <= r2) as usize;
                }
                count < k
            }),
            Some(c) => {
                // A crowded grid: the heaviest runs first, and counting also stops once the
                // points left cannot make up the difference (a merged crowd out of reach
                // settles it at once).
                let mut left = self.count_around(p, radius);
                let mut runs = Vec::with_capacity(16);
                self.runs(p, radius, |a, b| {
                    runs.push((c.before[b] - c.before[a], a, b));
                    true
                });
                runs.sort_unstable_by_key(|r| std::cmp::Reverse(r.0));
                for (run, a, b) in runs {
                    for (q, &w) in self.pts[a..b].iter().zip(&c.weight[a..b]) {
                        if d2(p, q) <= r2 {
                            count += w as usize;
                        }
                    }
                    left -= run as usize;
                    if count >= k || count + left < k {
                        break;
                    }
                }
            }
        }
        count >= k
    }

    /// At least the number of points (copies counted) within `radius` (m) of `p`: the points
    /// of the cells around it.
    #[inline]
    pub fn count_around(&self, p: &[f64; 3], radius: f64) -> usize {
        let mut count = 0;
        match &self.copies {
            None => self.runs(p, radius, |a, b| {
                count += b - a;
                true
            }),
            Some(c) => self.runs(p, radius, |a, b| {
                count += (c.before[b] - c.before[a]) as usize;
                true
            }),
        }
        count
    }

    /// Calls `visit(j, d²)` for every sorted point `j` after position `i` whose squared
    /// distance from point `i` is at most `r2` (m²): each close pair once, from its first.
    #[inline]
    pub fn within_after(&self, i: usize, r2: f64, mut visit: impl FnMut(u32, f64)) {
        let p = &self.pts[i];
        self.runs(p, r2.sqrt(), |a, b| {
            self.scan(p, a.max(i + 1), b, r2, &mut visit);
            true
        });
    }

    /// Calls `visit(j)` for the sorted points `j` within squared distance `r2` (m²) of `p`
    /// among those marked: `marked_before[s]` is the number marked before position `s` (one
    /// more than the points), so runs with none are skipped; `visit` tells marked from not.
    #[inline]
    pub fn within_marked(
        &self,
        p: &[f64; 3],
        r2: f64,
        marked_before: &[u32],
        mut visit: impl FnMut(u32),
    ) {
        self.runs(p, r2.sqrt(), |a, b| {
            if marked_before[b] > marked_before[a] {
                self.scan(p, a, b, r2, |j, _| visit(j));
            }
            true
        });
    }

    /// Calls `visit(j, d²)` for every sorted point `j` whose squared distance from `p`
    /// (summed x, y, z, as [`crate::cluster`] sums it) is at most `r2` (m²).
    #[inline]
    pub fn within(&self, p: &[f64; 3], r2: f64, mut visit: impl FnMut(u32, f64)) {
        self.runs(p, r2.sqrt(), |a, b| {
            self.scan(p, a, b, r2, &mut visit);
            true
        });
    }

    /// Calls `visit(j, d²)` for every sorted point `j` in `a..b` (empty where `a >= b`)
    /// within squared distance `r2` (m²) of `p`.
    #[inline(always)]
    fn scan(&self, p: &[f64; 3], a: usize, b: usize, r2: f64, mut visit: impl FnMut(u32, f64)) {
        for (j, q) in (a..b).zip(self.pts.get(a..b).unwrap_or(&[])) {
            let d = d2(p, q);
            if d <= r2 {
                visit(j as u32, d);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn a_query_finds_exactly_the_points_a_scan_finds() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        // Clumps, duplicates, points on cell boundaries and a far corner.
        let mut pts: Vec<[f64; 3]> = (0..3000)
            .map(|k| match k % 7 {
                0 => [0.02 * (k % 13) as f64, 0.04, 0.02 * (k % 5) as f64],
                1 => [0.3, 0.3, 0.3],
                _ => [0; 3].map(|_| rng.random_range(-0.2..0.5)),
            })
            .collect();
        pts.push([-0.2, -0.2, 0.5]);
        let grid = CellGrid::new(&pts, 0.02, 1 << 20).expect("a grid");
        let mut seen = grid.orig.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..pts.len() as u32).collect::<Vec<_>>());
        for (s, &i) in grid.orig.iter().enumerate() {
            assert_eq!(grid.pts[s], pts[i as usize]);
        }
        for (q, radius) in [(0, 0.02), (1, 0.01), (7, 0.03), (3000, 0.02), (12, 0.0)] {
            let p = pts[q];
            let r2 = radius * radius;
            let mut got: Vec<u32> = Vec::new();
            grid.within(&p, r2, |j, d| {
                assert_eq!(grid.pts[j as usize], pts[grid.orig[j as usize] as usize]);
                assert!(d <= r2);
                got.push(grid.orig[j as usize]);
            });
            got.sort_unstable();
            let want: Vec<u32> = (0..pts.len() as u32)
                .filter(|&j| {
                    let o = pts[j as usize];
                    let (dx, dy, dz) = (p[0] - o[0], p[1] - o[1], p[2] - o[2]);
                    dx * dx + dy * dy + dz * dz <= r2
                })
                .collect();
            assert!(!want.is_empty());
            assert_eq!(got, want, "point {q}, radius {radius}");
            assert!(grid.count_around(&p, radius) >= want.len());
            assert!(grid.reaches(&p, r2, want.len()));
            assert!(!grid.reaches(&p, r2, want.len() + 1));
        }
    }

    #[test]
    fn merged_duplicates_count_as_their_copies() {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        // A crowd of copies, copies of a few other points, and points alone.
        let mut pts: Vec<[f64; 3]> = vec![[0.1, 0.1, 0.1]; 500];
        for k in 0..700 {
            pts.push(if k % 3 == 0 {
                [0.02 * (k % 4) as f64, 0.11, 0.1]
            } else {
                [0; 3].map(|_| rng.random_range(0.0..0.2))
            });
        }
        let mut grid = CellGrid::new(&pts, 0.02, 1 << 20).expect("a grid");
        assert!(grid.most() >= 500);
        grid.merge_duplicates(0);
        assert!(grid.pts.len() < pts.len() - 499);
        assert_eq!(grid.caller_len(), pts.len());
        let mut all: Vec<u32> = (0..grid.pts.len())
            .flat_map(|s| {
                let c = grid.copies(s);
                assert_eq!(c.len(), grid.weight(s));
                assert_eq!(c[0], grid.orig[s], "the lowest copy first");
                assert!(c.iter().all(|&o| pts[o as usize] == grid.pts[s]));
                c.to_vec()
            })
            .collect();
        all.sort_unstable();
        assert_eq!(all, (0..pts.len() as u32).collect::<Vec<_>>());
        for (q, radius) in [(0, 0.02), (600, 0.03), (1199, 0.01)] {
            let p = pts[q];
            let r2 = radius * radius;
            let want = pts
                .iter()
                .filter(|o| {
                    let (dx, dy, dz) = (p[0] - o[0], p[1] - o[1], p[2] - o[2]);
                    dx * dx + dy * dy + dz * dz <= r2
                })
                .count();
            let mut got = 0;
            grid.within(&p, r2, |j, _| got += grid.weight(j as usize));
            assert_eq!(got, want, "point {q}");
            assert!(grid.count_around(&p, radius) >= want);
            assert!(grid.reaches(&p, r2, want));
            assert!(!grid.reaches(&p, r2, want + 1));
        }
    }

    #[test]
    fn a_cloud_too_spread_has_no_grid() {
        let pts = [[0.0, 0.0, 0.0], [1e5, 1e5, 1e5]];
        assert!(CellGrid::new(&pts, 0.02, 1 << 20).is_none());
        assert!(CellGrid::new(&pts, 1e-12, usize::MAX).is_none());
        assert!(CellGrid::new(&pts, 1e5, 8).is_some());
    }
}
