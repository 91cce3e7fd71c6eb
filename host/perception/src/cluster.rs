//! Clustering of point clouds: DBSCAN with scikit-learn's semantics behind the [`Clusterer`]
//! trait, on a grid of cells or a k-d tree ([`Dbscan`], the fast one) and by exhaustive search
//! ([`ExhaustiveDbscan`], the literal algorithm, a reference for checking).
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

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;

use crate::cloud::check_points;
use crate::error::{PerceptionError, Result};
use crate::grid::{d2, CellGrid};

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

/// DBSCAN on a grid of cells `eps` wide, or kiddo's k-d tree ([`ImmutableKdTree`]) for a
/// cloud spread too far for a grid (either built once per call), single-threaded, with the
/// semantics of the [module](self). Cost: about linear in the number of points for a cloud of
/// surfaces, whatever its density (see [`Dbscan::cluster`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dbscan {
    /// The parameters.
    pub params: DbscanParams,
}

impl Dbscan {
    /// DBSCAN with checked parameters ([`DbscanParams::new`]).
    pub fn new(eps: f64, min_samples: usize) -> Result<Self> {
        Ok(Dbscan {
            params: DbscanParams::new(eps, min_samples)?,
        })
    }
}

/// Fraction by which a leader's ball is smaller than `eps / 2`: two points of one ball are
/// then closer than `eps` by a margin (1e-9 relative) far beyond the rounding of a computed
/// squared distance (a few 1e-16 relative), so what the balls prove holds for the very
/// comparisons scikit-learn makes.
const LEADER_SHRINK: f64 = 1.0 - 1e-9;

/// Below this many pairs, two leaders' groups are compared pair by pair; above, through a
/// k-d tree of one of them.
const BRUTE_PAIRS: usize = 1 << 14;

/// Most point indices kept for sparse groups (16 MiB of them); beyond, their border points
/// query the tree.
const SPARSE_BUDGET: usize = 1 << 22;

/// Above this many points around a mixed group's leader, its unsettled members count their
/// neighbours with the tree instead of among those points.
const MIXED_AROUND: usize = 4096;

/// What a leader's balls say about its group.
#[derive(Clone, Copy)]
enum Kind {
    /// At least `min_samples` points within `r` of the leader: every member is core.
    Dense,
    /// Fewer than `min_samples` points within `1.5 eps` of the leader (within `eps` for a
    /// group of one), which hold every member's neighbours: no member is core. Those points
    /// are `kept[from..to]`.
    Sparse { from: u32, to: u32 },
    /// Mixed (members counted one by one), or sparse with the points around not kept.
    Other,
}

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
enum Neighbours {
    Grid(CellGrid),
    Tree {
        pts: Vec<[f64; 3]>,
        tree: ImmutableKdTree<f64, 3>,
    },
}

impl Neighbours {
    /// The grid of cells `eps` wide over `points` where it needs at most
    /// [`GRID_CELLS_PER_POINT`] cells per point, else the tree.
    fn new(points: &[Point3<f64>], eps: f64) -> Result<Self> {
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
    fn weight(&self, s: usize) -> usize {
        match self {
            Neighbours::Grid(g) => g.weight(s),
            Neighbours::Tree { .. } => 1,
        }
    }

    /// Values by position, `v`, given to every point of the caller's (in its order).
    fn to_caller<T: Copy + Default>(&self, v: &[T]) -> Vec<T> {
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
    fn tree(pts: Vec<[f64; 3]>) -> Result<Self> {
        let tree = ImmutableKdTree::new_from_slice(&pts)
            .map_err(|e| PerceptionError::KdTree(format!("{e:?}")))?;
        Ok(Neighbours::Tree { pts, tree })
    }

    /// The points, by position.
    fn pts(&self) -> &[[f64; 3]] {
        match self {
            Neighbours::Grid(g) => &g.pts,
            Neighbours::Tree { pts, .. } => pts,
        }
    }

    /// The caller's index of the point at position `s`.
    fn orig(&self, s: usize) -> usize {
        match self {
            Neighbours::Grid(g) => g.orig[s] as usize,
            Neighbours::Tree { .. } => s,
        }
    }

    /// Calls `visit(position, d²)` for every point within squared distance `r2` of `p`.
    #[inline]
    fn within(&self, p: &[f64; 3], r2: f64, mut visit: impl FnMut(u32, f64)) {
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
    fn at_most(&self, p: &[f64; 3], eps: f64) -> usize {
        match self {
            Neighbours::Grid(g) => g.count_around(p, eps),
            Neighbours::Tree { .. } => usize::MAX,
        }
    }
}

impl Clusterer for Dbscan {
    /// DBSCAN as the [module](self) defines it. The work is organised so that a dense cloud
    /// (a camera's surfaces, hundreds of neighbours per point) costs little more than a
    /// sparse one, and the labels stay exact. Neighbours are found on a grid of cells `eps`
    /// wide, the points sorted by cell (a cloud too spread for a grid of
    /// [`GRID_CELLS_PER_POINT`] cells per point: kiddo's k-d tree); the steps below work on
    /// the points in that order.
    ///
    /// 1. *Leaders.* Scanning the points, a point whose grid cells around hold fewer than
    ///    `min_samples` points is not core (noise, mostly) and is left to step 3. Any other
    ///    point not yet in a group becomes a leader and takes every ungrouped point within
    ///    `r = eps / 2` (less 1e-9) of it into its group. Any two points within `r` of one
    ///    leader are within `eps` of each other. When the leader's ball holds at least
    ///    `min_samples` points, every member of its group is core (the ball lies inside each
    ///    member's neighbourhood). Otherwise, on the grid, each member counts its own
    ///    neighbours in the cells around it, stopping at `min_samples`. On the tree, where a
    ///    query costs more, the leader's ball of `1.5 eps` (which holds every member's
    ///    neighbourhood) decides for all: with fewer than `min_samples` points, no member is
    ///    core, and those points are kept for step 3; else the distance of the leader's
    ///    `min_samples`-th nearest settles most members by the triangle inequality, and the
    ///    others count their neighbours among the points around.
    /// 2. *Clusters.* The core members of one group are connected among themselves; two
    ///    groups are connected when some pair of their core members is within `eps` (only
    ///    groups whose leaders are within `2 eps` can be): at once when both leaders are
    ///    core and within `eps`, else checked pair by pair or through a k-d tree; joined in
    ///    a union-find.
    /// 3. *Labels* in scikit-learn's order; each border point looks through its neighbours
    ///    (fewer than `min_samples`: those kept in step 1, or a radius query) for the lowest
    ///    cluster among its core neighbours.
    fn cluster(&self, points: &[Point3<f64>]) -> Result<Clustering> {
        self.params.check()?;
        check_cloud(points)?;
        self.cluster_on(&Neighbours::new(points, self.params.eps)?)
    }
}

impl Dbscan {
    /// [`Clusterer::cluster`] on the checked points in `index`.
    fn cluster_on(&self, index: &Neighbours) -> Result<Clustering> {
        let pts = index.pts();
        let n = pts.len();
        let min_samples = self.params.min_samples;
        let eps = self.params.eps;
        let eps2 = eps * eps;

        // 1. Leaders, their groups, and which points are core (by position).
        let r = 0.5 * eps * LEADER_SHRINK;
        let r2 = r * r;
        // A member's neighbours lie within eps + r < 1.5 eps of its leader.
        let outer2 = 2.25 * eps2;
        const NONE: u32 = u32::MAX;
        // Not core by the count of its cells around; in no group.
        const FEW: u32 = u32::MAX - 1;
        let mut group = vec![NONE; n];
        let mut core = vec![false; n];
        let mut leaders: Vec<u32> = Vec::new();
        let mut kind: Vec<Kind> = Vec::new();
        let mut kept: Vec<u32> = Vec::new();
        let mut joined: Vec<(u32, f64)> = Vec::new();
        let mut around: Vec<(u32, f64)> = Vec::new();
        for i in 0..n {
            if group[i] != NONE {
                continue;
            }
            if index.at_most(&pts[i], eps) < min_samples {
                group[i] = FEW;
                continue;
            }
            let g = leaders.len() as u32;
            leaders.push(i as u32);
            group[i] = g;
            joined.clear();
            joined.push((i as u32, 0.0));
            let mut count = 0usize;
            index.within(&pts[i], r2, |j, d| {
                count += index.weight(j as usize);
                if group[j as usize] == NONE {
                    group[j as usize] = g;
                    joined.push((j, d));
                }
            });
            if count >= min_samples {
                for &(m, _) in &joined {
                    core[m as usize] = true;
                }
                kind.push(Kind::Dense);
                continue;
            }
            if let Neighbours::Grid(grid) = index {
                // Each member counts its own neighbours: a few cells of contiguous points,
                // counting until min_samples.
                for &(m, _) in &joined {
                    core[m as usize] = grid.reaches(&pts[m as usize], eps2, min_samples);
                }
                kind.push(Kind::Other);
                continue;
            }
            // A group of one (a point alone within r: noise, mostly) needs only its own
            // neighbourhood; a larger one the ball that holds all its members'.
            let alone = joined.len() == 1;
            around.clear();
            index.within(&pts[i], if alone { eps2 } else { outer2 }, |j, d| {
                around.push((j, d))
            });
            if alone && around.len() >= min_samples {
                core[i] = true;
                kind.push(Kind::Other);
                continue;
            }
            if around.len() < min_samples {
                // No member is core; keep the points around for their border test.
                if kept.len() + around.len() <= SPARSE_BUDGET {
                    let from = kept.len() as u32;
                    kept.extend(around.iter().map(|&(j, _)| j));
                    kind.push(Kind::Sparse {
                        from,
                        to: kept.len() as u32,
                    });
                } else {
                    kind.push(Kind::Other);
                }
                continue;
            }
            kind.push(Kind::Other);
            // The leader's min_samples-th nearest, at dk: a member dm from the leader has at
            // least min_samples neighbours when dm + dk <= eps, fewer when eps + dm < dk (by
            // the triangle inequality; the margins cover rounding); otherwise it counts them
            // among the points around (which hold them all).
            // When min_samples of them are within eps, the k-th nearest is among those: select
            // in that smaller part, gathered at the front.
            let mut within = 0;
            for k in 0..around.len() {
                if around[k].1 <= eps2 {
                    around.swap(within, k);
                    within += 1;
                }
            }
            let nearest = if within >= min_samples {
                &mut around[..within]
            } else {
                &mut around[..]
            };
            let (_, &mut (_, dk2), _) =
                nearest.select_nth_unstable_by(min_samples - 1, |a, b| a.1.total_cmp(&b.1));
            let dk = dk2.sqrt();
            for &(m, dm2) in &joined {
                let dm = dm2.sqrt();
                core[m as usize] = if dm + dk <= eps * (1.0 - 1e-9) {
                    true
                } else if (eps + dm) * (1.0 + 1e-9) < dk {
                    false
                } else if around.len() <= MIXED_AROUND {
                    let p = &pts[m as usize];
                    let count = around
                        .iter()
                        .filter(|&&(x, _)| d2(p, &pts[x as usize]) <= eps2)
                        .count();
                    count >= min_samples
                } else {
                    // Many points around (a crowd just beyond the member's reach): the index
                    // visits only its own neighbours.
                    let mut count = 0usize;
                    index.within(&pts[m as usize], eps2, |_, _| count += 1);
                    count >= min_samples
                };
            }
        }

        // 2. The core members of each group (ascending), then the groups joined: leaders
        // within eps of each other that are both core at once, the rest pair by pair.
        let groups = leaders.len();
        let mut start = vec![0usize; groups + 1];
        for i in 0..n {
            if core[i] {
                start[group[i] as usize + 1] += 1;
            }
        }
        for g in 0..groups {
            start[g + 1] += start[g];
        }
        let mut fill = start.clone();
        let mut members = vec![[0.0f64; 3]; start[groups]];
        for i in 0..n {
            if core[i] {
                let g = group[i] as usize;
                members[fill[g]] = pts[i];
                fill[g] += 1;
            }
        }
        let active: Vec<u32> = (0..groups as u32)
            .filter(|&g| start[g as usize + 1] > start[g as usize])
            .collect();
        let mut sets = UnionFind::new(groups);
        if active.len() > 1 {
            let lpts: Vec<[f64; 3]> = active
                .iter()
                .map(|&g| pts[leaders[g as usize] as usize])
                .collect();
            let reach2 = 4.0 * eps2;
            let mut pending: Vec<(u32, u32)> = Vec::new();
            near_pairs(&lpts, reach2, |ia, ib, d2| {
                let (ga, gb) = (active[ia] as usize, active[ib] as usize);
                if d2 <= eps2 && core[leaders[ga] as usize] && core[leaders[gb] as usize] {
                    sets.union(ga, gb);
                } else {
                    pending.push((ia as u32, ib as u32));
                }
            })?;
            let mut bridge = Bridge::default();
            for &(ia, ib) in &pending {
                let (ga, gb) = (active[ia as usize] as usize, active[ib as usize] as usize);
                if sets.find(ga) == sets.find(gb) {
                    continue;
                }
                let a = &members[start[ga]..start[ga + 1]];
                let b = &members[start[gb]..start[gb + 1]];
                let (la, lb) = (&lpts[ia as usize], &lpts[ib as usize]);
                if bridge.connects(a, la, b, lb, eps)? {
                    sets.union(ga, gb);
                }
            }
        }

        // 3. Labels: clusters numbered by their lowest core point in the caller's order;
        // border points take the lowest cluster among their core neighbours.
        let mut first = vec![usize::MAX; groups];
        for i in 0..n {
            if core[i] {
                let s = sets.find(group[i] as usize);
                first[s] = first[s].min(index.orig(i));
            }
        }
        let mut roots: Vec<usize> = (0..groups).filter(|&s| first[s] != usize::MAX).collect();
        roots.sort_unstable_by_key(|&s| first[s]);
        let clusters = roots.len();
        let mut label_of_set = vec![NOISE; groups];
        for (label, &s) in roots.iter().enumerate() {
            label_of_set[s] = label as i32;
        }
        let mut labels = vec![NOISE; n];
        for i in 0..n {
            if core[i] {
                labels[i] = label_of_set[sets.find(group[i] as usize)];
            }
        }
        // A sparse group none of whose points around is core has only noise.
        let sparse_near_core: Vec<bool> = kind
            .iter()
            .map(|k| match *k {
                Kind::Sparse { from, to } => kept[from as usize..to as usize]
                    .iter()
                    .any(|&j| core[j as usize]),
                _ => true,
            })
            .collect();
        if clusters > 0 {
            // On the grid, the core points before each position: runs without one are
            // skipped.
            let core_before: Vec<u32> = match index {
                Neighbours::Grid(_) => std::iter::once(0)
                    .chain(core.iter().scan(0u32, |c, &k| {
                        *c += k as u32;
                        Some(*c)
                    }))
                    .collect(),
                Neighbours::Tree { .. } => Vec::new(),
            };
            for i in 0..n {
                if core[i] || (group[i] != FEW && !sparse_near_core[group[i] as usize]) {
                    continue;
                }
                let mut best = i32::MAX;
                let mut consider = |j: usize| {
                    if core[j] && labels[j] < best {
                        best = labels[j];
                    }
                };
                match kind.get(group[i] as usize) {
                    Some(&Kind::Sparse { from, to }) => {
                        for &j in &kept[from as usize..to as usize] {
                            if d2(&pts[i], &pts[j as usize]) <= eps2 {
                                consider(j as usize);
                            }
                        }
                    }
                    _ => match index {
                        Neighbours::Grid(g) => {
                            g.within_marked(&pts[i], eps2, &core_before, |j| consider(j as usize))
                        }
                        Neighbours::Tree { .. } => {
                            index.within(&pts[i], eps2, |j, _| consider(j as usize))
                        }
                    },
                }
                if best != i32::MAX {
                    labels[i] = best;
                }
            }
        }
        // Back to the caller's order (and to every copy of a merged point).
        Ok(Clustering {
            labels: index.to_caller(&labels),
            core: index.to_caller(&core),
            clusters,
        })
    }
}

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
fn near_pairs(
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
struct Bridge {
    a: Vec<[f64; 3]>,
    b: Vec<[f64; 3]>,
}

impl Bridge {
    /// Whether some point of `a` (a group within `eps / 2` of leader `la`) lies within `eps`
    /// of some point of `b` (within `eps / 2` of `lb`).
    fn connects(
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
struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        UnionFind {
            parent: (0..n as u32).collect(),
            size: vec![1; n],
        }
    }

    fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] as usize != x {
            let up = self.parent[self.parent[x] as usize];
            self.parent[x] = up;
            x = up as usize;
        }
        x
    }

    fn union(&mut self, a: usize, b: usize) {
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

/// DBSCAN by exhaustive search: scikit-learn's algorithm line for line (neighbourhoods by
/// comparing every pair, core flags, then a depth-first search from each unlabelled core
/// point in index order that labels every unlabelled neighbour of each core point it
/// reaches). O(n²) time and O(n) memory: a reference to check [`Dbscan`] against, and enough
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

#[cfg(test)]
mod tests {
    use super::*;
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
