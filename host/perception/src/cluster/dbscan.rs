//! The fast DBSCAN ([`Dbscan`]): leaders and their groups, groups joined into clusters,
//! labels in scikit-learn's order; points in m, labels exactly scikit-learn's.

use nalgebra::Point3;

use super::join::{near_pairs, Bridge, UnionFind};
use super::neighbours::Neighbours;
use super::{check_cloud, Clusterer, Clustering, DbscanParams, NOISE};
use crate::error::Result;
use crate::grid::d2;

/// DBSCAN on a grid of cells `eps` wide, or kiddo's k-d tree ([`ImmutableKdTree`](kiddo::ImmutableKdTree)) for a
/// cloud spread too far for a grid (either built once per call), single-threaded, with the
/// semantics of the [module](super). Cost: about linear in the number of points for a cloud of
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

/// A point's group before it has one.
const NONE: u32 = u32::MAX;
/// A point not core by the count of its cells around; in no group.
const FEW: u32 = u32::MAX - 1;

/// What the leaders found (step 1 of [`Dbscan::cluster`]), by position: each point's group
/// (or [`FEW`]) and whether it is core; each group's leader and [`Kind`]; the points kept
/// around sparse groups.
struct Groups {
    group: Vec<u32>,
    core: Vec<bool>,
    leaders: Vec<u32>,
    kind: Vec<Kind>,
    kept: Vec<u32>,
}

impl Clusterer for Dbscan {
    /// DBSCAN as the [module](super) defines it. The work is organised so that a dense cloud
    /// (a camera's surfaces, hundreds of neighbours per point) costs little more than a
    /// sparse one, and the labels stay exact. Neighbours are found on a grid of cells `eps`
    /// wide, the points sorted by cell (a cloud too spread for a grid of
    /// `GRID_CELLS_PER_POINT` cells per point: kiddo's k-d tree); the steps below work on
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
    pub(super) fn cluster_on(&self, index: &Neighbours) -> Result<Clustering> {
        // 1. Leaders, their groups, and which points are core (by position).
        let g = self.leaders(index);
        // 2. The core members of each group (ascending), then the groups joined: leaders
        // within eps of each other that are both core at once, the rest pair by pair.
        let mut sets = self.join(index, &g)?;
        // 3. Labels: clusters numbered by their lowest core point in the caller's order;
        // border points take the lowest cluster among their core neighbours.
        let (mut labels, clusters) = number_clusters(index, &g, &mut sets);
        if clusters > 0 {
            self.label_borders(index, &g, &mut labels);
        }
        // Back to the caller's order (and to every copy of a merged point).
        Ok(Clustering {
            labels: index.to_caller(&labels),
            core: index.to_caller(&g.core),
            clusters,
        })
    }

    /// Step 1: the leaders, their groups, and which points are core.
    fn leaders(&self, index: &Neighbours) -> Groups {
        let pts = index.pts();
        let n = pts.len();
        let min_samples = self.params.min_samples;
        let eps = self.params.eps;
        let r = 0.5 * eps * LEADER_SHRINK;
        let r2 = r * r;
        let mut g = Groups {
            group: vec![NONE; n],
            core: vec![false; n],
            leaders: Vec::new(),
            kind: Vec::new(),
            kept: Vec::new(),
        };
        let mut joined: Vec<(u32, f64)> = Vec::new();
        let mut around: Vec<(u32, f64)> = Vec::new();
        for (i, p) in pts.iter().enumerate() {
            if g.group[i] != NONE {
                continue;
            }
            if index.at_most(p, eps) < min_samples {
                g.group[i] = FEW;
                continue;
            }
            let id = g.leaders.len() as u32;
            g.leaders.push(i as u32);
            g.group[i] = id;
            joined.clear();
            joined.push((i as u32, 0.0));
            let mut count = 0usize;
            let group = &mut g.group;
            index.within(p, r2, |j, d| {
                count += index.weight(j as usize);
                if group[j as usize] == NONE {
                    group[j as usize] = id;
                    joined.push((j, d));
                }
            });
            let kind = self.settle(index, i, &joined, count, &mut around, &mut g);
            g.kind.push(kind);
        }
        g
    }

    /// Which members of the group point `i` leads (`joined`, with their squared distances
    /// to it; `count` points within `r` of it) are core; the group's kind.
    fn settle(
        &self,
        index: &Neighbours,
        i: usize,
        joined: &[(u32, f64)],
        count: usize,
        around: &mut Vec<(u32, f64)>,
        g: &mut Groups,
    ) -> Kind {
        let pts = index.pts();
        let min_samples = self.params.min_samples;
        let eps = self.params.eps;
        let eps2 = eps * eps;
        // A member's neighbours lie within eps + r < 1.5 eps of its leader.
        let outer2 = 2.25 * eps2;
        if count >= min_samples {
            for &(m, _) in joined {
                g.core[m as usize] = true;
            }
            return Kind::Dense;
        }
        if let Neighbours::Grid(grid) = index {
            // Each member counts its own neighbours: a few cells of contiguous points,
            // counting until min_samples.
            for &(m, _) in joined {
                g.core[m as usize] = grid.reaches(&pts[m as usize], eps2, min_samples);
            }
            return Kind::Other;
        }
        // A group of one (a point alone within r: noise, mostly) needs only its own
        // neighbourhood; a larger one the ball that holds all its members'.
        let alone = joined.len() == 1;
        around.clear();
        index.within(&pts[i], if alone { eps2 } else { outer2 }, |j, d| {
            around.push((j, d))
        });
        if alone && around.len() >= min_samples {
            g.core[i] = true;
            return Kind::Other;
        }
        if around.len() < min_samples {
            // No member is core; keep the points around for their border test.
            if g.kept.len() + around.len() <= SPARSE_BUDGET {
                let from = g.kept.len() as u32;
                g.kept.extend(around.iter().map(|&(j, _)| j));
                return Kind::Sparse {
                    from,
                    to: g.kept.len() as u32,
                };
            }
            return Kind::Other;
        }
        self.settle_mixed(index, joined, around, &mut g.core);
        Kind::Other
    }

    /// The core members of a mixed group on the tree (`joined`, with their squared distances
    /// to the leader), from the points `around` the leader within `1.5 eps`.
    fn settle_mixed(
        &self,
        index: &Neighbours,
        joined: &[(u32, f64)],
        around: &mut [(u32, f64)],
        core: &mut [bool],
    ) {
        let pts = index.pts();
        let min_samples = self.params.min_samples;
        let eps = self.params.eps;
        let eps2 = eps * eps;
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
        for &(m, dm2) in joined {
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

    /// Step 2: the groups joined where some pair of their core members is within `eps`.
    fn join(&self, index: &Neighbours, g: &Groups) -> Result<UnionFind> {
        let pts = index.pts();
        let eps = self.params.eps;
        let eps2 = eps * eps;
        let groups = g.leaders.len();
        let (start, members) = core_members(pts, g);
        let active: Vec<u32> = (0..groups as u32)
            .filter(|&g| start[g as usize + 1] > start[g as usize])
            .collect();
        let mut sets = UnionFind::new(groups);
        if active.len() > 1 {
            let lpts: Vec<[f64; 3]> = active
                .iter()
                .map(|&a| pts[g.leaders[a as usize] as usize])
                .collect();
            let reach2 = 4.0 * eps2;
            let mut pending: Vec<(u32, u32)> = Vec::new();
            let (core, leaders) = (&g.core, &g.leaders);
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
        Ok(sets)
    }

    /// Step 3's border points (all but core ones): each takes the lowest cluster among its
    /// core neighbours, if any.
    fn label_borders(&self, index: &Neighbours, g: &Groups, labels: &mut [i32]) {
        let pts = index.pts();
        let n = pts.len();
        let eps = self.params.eps;
        let eps2 = eps * eps;
        let (group, core, kept) = (&g.group, &g.core, &g.kept);
        // A sparse group none of whose points around is core has only noise.
        let sparse_near_core: Vec<bool> = g
            .kind
            .iter()
            .map(|k| match *k {
                Kind::Sparse { from, to } => kept[from as usize..to as usize]
                    .iter()
                    .any(|&j| core[j as usize]),
                _ => true,
            })
            .collect();
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
            match g.kind.get(group[i] as usize) {
                Some(&Kind::Sparse { from, to }) => {
                    for &j in &kept[from as usize..to as usize] {
                        if d2(&pts[i], &pts[j as usize]) <= eps2 {
                            consider(j as usize);
                        }
                    }
                }
                _ => match index {
                    Neighbours::Grid(grid) => {
                        grid.within_marked(&pts[i], eps2, &core_before, |j| consider(j as usize))
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
}

/// The core members' points of each group, by group: group `g`'s are
/// `members[start[g]..start[g + 1]]`, ascending by position.
fn core_members(pts: &[[f64; 3]], g: &Groups) -> (Vec<usize>, Vec<[f64; 3]>) {
    let n = pts.len();
    let groups = g.leaders.len();
    let (group, core) = (&g.group, &g.core);
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
    (start, members)
}

/// Step 3's core points: clusters numbered by their lowest core point in the caller's order;
/// every other point [`NOISE`] for now. Returns the labels and the number of clusters.
fn number_clusters(index: &Neighbours, g: &Groups, sets: &mut UnionFind) -> (Vec<i32>, usize) {
    let n = index.pts().len();
    let groups = g.leaders.len();
    let (group, core) = (&g.group, &g.core);
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
    (labels, clusters)
}
