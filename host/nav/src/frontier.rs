//! Frontiers for exploration (Yamauchi 1997): the borders between free and unknown space on a
//! map being built, grouped into connected frontiers, each with a place a round robot can reach
//! from which it sees the frontier, ranked by how far the robot must drive there.
//!
//! - A frontier cell is a free cell with an unknown 4-neighbour; frontier cells 8-connected to
//!   each other form one frontier, kept when it has at least [`FrontierSettings::min_cells`].
//! - The robot's reach: cells a robot of the radius fits in (clearance from occupied cells,
//!   unknown counted as free as the navigator counts it), found by Dijkstra from its place
//!   over free cells (8-connected).
//! - A frontier's view point: a reached cell between [`FrontierSettings::min_view`] and
//!   [`FrontierSettings::view`] of the frontier's cells (spreading from them over free cells,
//!   so not through a wall) with a clear line of sight to the frontier's middle cell (no
//!   occupied cell between: a frontier round a door's corner is seen from inside, not from
//!   the room before it), the one whose driving distance from the robot plus its distance
//!   from the frontier is least.

use std::collections::{BinaryHeap, VecDeque};

use ferrobot_geometry::validate;

use crate::error::{Error, Result};
use crate::map_file::{Cell, MapImage};
use crate::obstacles::{
    grid_line, neighbours, Obstacles, OccupancyGrid, NEIGHBOURS_4, NEIGHBOURS_8,
};

/// How frontiers are found.
#[derive(Debug, Clone, PartialEq)]
pub struct FrontierSettings {
    /// The robot's radius, m: the robot's reach keeps this clearance.
    pub radius: f64,
    /// View points keep this clearance, m (more than the radius: a view point is chosen on a
    /// map still being made, whose walls may lie a little off).
    pub view_clearance: f64,
    /// Frontiers of fewer cells are ignored (noise, a gap under furniture).
    pub min_cells: usize,
    /// A view point lies at least this far from its frontier, m (nearer, the camera looking
    /// down does not see it).
    pub min_view: f64,
    /// A view point lies within this distance of its frontier, m.
    pub view: f64,
    /// Places that failed before, `[x, y]` m: view points within [`FrontierSettings::avoid`]
    /// of them are not offered again.
    pub failed: Vec<[f64; 2]>,
    /// How near a failed place a view point may not be, m.
    pub avoid: f64,
    /// Frontiers given up (looked at and still there), by centroid `[x, y]` m: frontiers whose
    /// centroid lies within [`FrontierSettings::avoid`] of one are not offered again.
    pub done: Vec<[f64; 2]>,
}

impl FrontierSettings {
    /// For a robot of `radius` m: frontiers of 10 cells or more, view points 0.7-1.5 m from
    /// them with 0.15 m more clearance than the radius, failed places avoided by 0.4 m.
    pub fn new(radius: f64) -> Self {
        FrontierSettings {
            radius,
            view_clearance: radius + 0.15,
            min_cells: 10,
            min_view: 0.7,
            view: 1.5,
            failed: Vec::new(),
            avoid: 0.4,
            done: Vec::new(),
        }
    }
}

/// A frontier and where to see it from.
#[derive(Debug, Clone, PartialEq)]
pub struct Frontier {
    /// Its cells' mean, m.
    pub centroid: [f64; 2],
    /// Its cells.
    pub cells: usize,
    /// Where the robot sees it from, m: a place it reaches.
    pub view_point: [f64; 2],
    /// The heading that faces the frontier from the view point, rad.
    pub heading: f64,
    /// The driving distance from the robot to the view point, m.
    pub distance: f64,
}

/// The frontiers of `map` that a robot at `from` (m) reaches, nearest first. Errors: a map that
/// cannot be used, settings out of range, a place not finite.
pub fn frontiers(map: &MapImage, from: [f64; 2], s: &FrontierSettings) -> Result<Vec<Frontier>> {
    map.check()?;
    validate::finite("robot place", &from)?;
    validate::in_range("robot radius", s.radius, 0.0, crate::global::MAX_RADIUS)?;
    validate::in_range(
        "view clearance",
        s.view_clearance,
        0.0,
        crate::global::MAX_RADIUS,
    )?;
    validate::in_range("view distance", s.view, 0.0, 100.0)?;
    validate::in_range("least view distance", s.min_view, 0.0, s.view)?;
    validate::in_range("failed-place distance", s.avoid, 0.0, 100.0)?;
    for f in s.failed.iter().chain(&s.done) {
        validate::finite("failed place", f)?;
    }
    let (w, h) = (map.width, map.height);
    let r = map.resolution;
    let centre = |i: usize, j: usize| {
        [
            map.origin[0] + (i as f64 + 0.5) * r,
            map.origin[1] + (j as f64 + 0.5) * r,
        ]
    };
    // Clearance from the occupied cells.
    let grid = OccupancyGrid {
        origin: centre(0, 0),
        resolution: r,
        width: w,
        height: h,
        occupied: map.cells.iter().map(|c| *c == Cell::Occupied).collect(),
    };
    let field = Obstacles::new(Vec::new(), Some(&grid))?;
    let at = |i: usize, j: usize| map.cells[j * w + i];
    let fits: Vec<bool> = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| at(i, j) != Cell::Occupied && field.clearance(centre(i, j)) >= s.radius)
        .collect();
    // Dijkstra from the robot's cell over free cells it fits in (its own cell, and the
    // unknown ones under and about it, count: it stands there).
    let start = grid.cell(from).ok_or(Error::OutsideMap {
        what: "robot",
        at: from,
    })?;
    let passable = |i: usize, j: usize| {
        fits[j * w + i]
            && (at(i, j) == Cell::Free || {
                let c = centre(i, j);
                (c[0] - from[0]).hypot(c[1] - from[1]) <= s.radius + r
            })
    };
    let mut dist = vec![f64::INFINITY; w * h];
    let mut heap = BinaryHeap::new();
    dist[start.1 * w + start.0] = 0.0;
    heap.push(Node(0.0, start.0, start.1));
    while let Some(Node(d, i, j)) = heap.pop() {
        if d > dist[j * w + i] {
            continue;
        }
        for ((a, b), (di, dj)) in neighbours((i, j), w, h, &NEIGHBOURS_8) {
            if !passable(a, b) {
                continue;
            }
            let diagonal = di != 0 && dj != 0;
            if diagonal && !(passable(a, j) && passable(i, b)) {
                continue;
            }
            let nd = d + if diagonal {
                r * std::f64::consts::SQRT_2
            } else {
                r
            };
            if nd < dist[b * w + a] {
                dist[b * w + a] = nd;
                heap.push(Node(nd, a, b));
            }
        }
    }
    // Frontier cells, grouped.
    let is_frontier = |i: usize, j: usize| {
        at(i, j) == Cell::Free
            && neighbours((i, j), w, h, &NEIGHBOURS_4).any(|((a, b), _)| at(a, b) == Cell::Unknown)
    };
    let mut group = vec![usize::MAX; w * h];
    let mut groups: Vec<Vec<(usize, usize)>> = Vec::new();
    for j in 0..h {
        for i in 0..w {
            if group[j * w + i] != usize::MAX || !is_frontier(i, j) {
                continue;
            }
            let id = groups.len();
            let mut cells = Vec::new();
            let mut queue = VecDeque::from([(i, j)]);
            group[j * w + i] = id;
            while let Some((a, b)) = queue.pop_front() {
                cells.push((a, b));
                for ((x, y), _) in neighbours((a, b), w, h, &NEIGHBOURS_8) {
                    if group[y * w + x] == usize::MAX && is_frontier(x, y) {
                        group[y * w + x] = id;
                        queue.push_back((x, y));
                    }
                }
            }
            groups.push(cells);
        }
    }
    // View points: from every frontier cell, the reached cells within the view distance
    // (a breadth-first spread over free cells, so the view is not through a wall).
    let reach = (s.view / r).ceil() as i64;
    let near = (s.min_view / r).floor() as i64;
    let mut out = Vec::new();
    for cells in groups.iter().filter(|c| c.len() >= s.min_cells) {
        let n = cells.len() as f64;
        let centroid = cells.iter().fold([0.0, 0.0], |acc, &(i, j)| {
            let c = centre(i, j);
            [acc[0] + c[0] / n, acc[1] + c[1] / n]
        });
        if s.done
            .iter()
            .any(|d| (d[0] - centroid[0]).hypot(d[1] - centroid[1]) < s.avoid)
        {
            continue;
        }
        // The frontier's cell nearest its centroid: the view point must see it.
        let middle = cells
            .iter()
            .copied()
            .min_by(|&a, &b| {
                let (ca, cb) = (centre(a.0, a.1), centre(b.0, b.1));
                let da = (ca[0] - centroid[0]).hypot(ca[1] - centroid[1]);
                let db = (cb[0] - centroid[0]).hypot(cb[1] - centroid[1]);
                da.total_cmp(&db)
            })
            .unwrap_or((0, 0));
        // (cost, driving distance, cell)
        let mut best: Option<(f64, f64, (usize, usize))> = None;
        let mut seen = std::collections::HashSet::new();
        let mut queue: VecDeque<((usize, usize), i64)> = cells.iter().map(|&c| (c, 0)).collect();
        for &c in cells {
            seen.insert(c);
        }
        while let Some(((i, j), k)) = queue.pop_front() {
            let d = dist[j * w + i];
            let c = centre(i, j);
            let refused = s
                .failed
                .iter()
                .any(|f| (f[0] - c[0]).hypot(f[1] - c[1]) < s.avoid);
            // Nearer the frontier is better too: a door looked through from afar shows a
            // narrow cone of the room behind it.
            let cost = d + k as f64 * r;
            if k >= near
                && d.is_finite()
                && !refused
                && field.clearance(c) >= s.view_clearance
                && best.is_none_or(|(b, _, _)| cost < b)
                && in_sight(map, (i, j), middle)
            {
                best = Some((cost, d, (i, j)));
            }
            if k >= reach {
                continue;
            }
            for ((x, y), _) in neighbours((i, j), w, h, &NEIGHBOURS_8) {
                if at(x, y) == Cell::Free && seen.insert((x, y)) {
                    queue.push_back(((x, y), k + 1));
                }
            }
        }
        if let Some((_, d, (i, j))) = best {
            let v = centre(i, j);
            out.push(Frontier {
                centroid,
                cells: cells.len(),
                view_point: v,
                heading: (centroid[1] - v[1]).atan2(centroid[0] - v[0]),
                distance: d,
            });
        }
    }
    out.sort_by(|a, b| a.distance.total_cmp(&b.distance));
    Ok(out)
}

/// Whether no occupied cell of `map` lies on the straight line between cells `a` and `b`
/// (Bresenham's line; unknown cells do not block).
fn in_sight(map: &MapImage, a: (usize, usize), b: (usize, usize)) -> bool {
    grid_line((a.0 as i64, a.1 as i64), (b.0 as i64, b.1 as i64))
        .all(|(x, y)| map.cells[y as usize * map.width + x as usize] != Cell::Occupied)
}

/// A Dijkstra node: distance (m) and cell, ordered nearest first.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Node(f64, usize, usize);

impl Eq for Node {}

impl Ord for Node {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        other.0.total_cmp(&self.0)
    }
}

impl PartialOrd for Node {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
