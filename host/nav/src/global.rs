//! Global path planning on an occupancy grid: A* over the cells a round robot fits in
//! (8-connected, no corner cutting; the `pathfinding` crate's A*), optionally paying more near
//! obstacles so that the path keeps a margin where there is room (as move_base's inflation
//! layer does), then the path pulled taut (each waypoint joined to a far later one in free line
//! of sight, from alternating ends).

use crate::error::{Error, Result};
use crate::obstacles::{Obstacles, OccupancyGrid, NEIGHBOURS_8};
use ferrobot_geometry::validate;

/// A planned path in the map's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct GlobalPath {
    /// Waypoints from the start to the goal, m; the first is the start, the last the goal.
    pub points: Vec<[f64; 2]>,
    /// Length, m.
    pub length: f64,
}

/// A planner of collision-free paths for a round robot on an occupancy grid.
pub trait GlobalPlanner {
    /// A path from `start` to `goal` (m, map frame) that keeps a robot of `radius` m clear of
    /// every occupied cell (within the planner's stated tolerance); cells outside the grid
    /// are not traversable. Typed errors: values not finite or out of range, start or goal
    /// outside the grid or too near an obstacle, no path.
    fn plan(
        &self,
        map: &OccupancyGrid,
        start: [f64; 2],
        goal: [f64; 2],
        radius: f64,
    ) -> Result<GlobalPath>;
}

/// A* on the grid's cells, then the path pulled taut. A cell is open to the robot when its
/// centre's clearance (exact Euclidean distance transform to the nearest occupied cell's
/// centre, less half a cell) is at least the radius; straight lines of the pulled path are
/// checked every quarter cell, and a step between neighbouring open cells (kept where no
/// straight line is free) stays within 0.71 of a cell of an open cell's centre. So every point
/// of the path keeps a clearance of at least `radius − 0.71 · resolution` from the occupied
/// cells' inscribed discs (the distance field is 1-Lipschitz; between samples of a checked line
/// its bilinear interpolation loses at most √2 times the eighth of a cell they are apart, less
/// than the tolerance), and of at least `radius − 0.92 · resolution` from their squares (a
/// square's corner lies 0.21 of a cell beyond its inscribed disc).
#[derive(Debug, Clone, Copy, Default)]
pub struct GridAStar;

/// Rounds of pulling after the first, alternating ends.
const PULLS: usize = 6;

/// Largest robot radius, m.
pub const MAX_RADIUS: f64 = 10.0;

/// How much more a step costs where the clearance falls short of `radius + margin` by the whole
/// margin (it grows linearly from nothing at the margin's edge).
const MARGIN_PENALTY: f64 = 3.0;

impl GlobalPlanner for GridAStar {
    fn plan(
        &self,
        map: &OccupancyGrid,
        start: [f64; 2],
        goal: [f64; 2],
        radius: f64,
    ) -> Result<GlobalPath> {
        self.plan_with_margin(map, start, goal, radius, 0.0)
    }
}

impl GridAStar {
    /// As [`GlobalPlanner::plan`], and where there is room the path keeps `margin` m more than
    /// the radius: a step through a cell whose clearance falls short of `radius + margin` costs
    /// up to `MARGIN_PENALTY` + 1 times as much, and a straight line of the pulled path keeps
    /// `radius + margin` of clearance, or as much as its ends have when that is less (never
    /// less than `radius`). So a path runs down the middle of a doorway and keeps off corners,
    /// and a narrow passage is still taken when it is the way.
    pub fn plan_with_margin(
        &self,
        map: &OccupancyGrid,
        start: [f64; 2],
        goal: [f64; 2],
        radius: f64,
        margin: f64,
    ) -> Result<GlobalPath> {
        validate::finite("path start", &start)?;
        validate::finite("path goal", &goal)?;
        validate::in_range("robot radius", radius, 0.0, MAX_RADIUS)?;
        validate::in_range("path margin", margin, 0.0, MAX_RADIUS)?;
        map.check()?;
        let field = Obstacles::new(Vec::new(), Some(map))?;
        let (w, h) = (map.width, map.height);
        let clearance: Vec<f64> = (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| field.clearance(map.centre(i, j)))
            .collect();
        // Cells a robot centred on them fits in.
        let is_open: Vec<bool> = clearance.iter().map(|&c| c >= radius).collect();
        // The extra cost per unit of step of entering each cell, in thousandths.
        let extra: Vec<u64> = clearance
            .iter()
            .map(|&c| {
                if margin <= 0.0 || c >= radius + margin {
                    0
                } else {
                    let short = ((radius + margin - c) / margin).clamp(0.0, 1.0);
                    (1000.0 * MARGIN_PENALTY * short) as u64
                }
            })
            .collect();
        let end = |p: [f64; 2], what: &'static str| -> Result<(usize, usize)> {
            let (i, j) = map.cell(p).ok_or(Error::OutsideMap { what, at: p })?;
            let clear = field.clearance(p);
            if clear < radius || !is_open[j * w + i] {
                return Err(Error::Blocked {
                    what,
                    at: p,
                    clearance: clear.min(field.clearance(map.centre(i, j))),
                    radius,
                });
            }
            Ok((i, j))
        };
        let s = end(start, "start")?;
        let g = end(goal, "goal")?;
        // Integer costs (mm-like units of a cell): straight 1000, diagonal 1414.
        const STRAIGHT: u64 = 1000;
        const DIAGONAL: u64 = 1414;
        let free = |i: i64, j: i64| {
            i >= 0
                && j >= 0
                && (i as usize) < w
                && (j as usize) < h
                && is_open[j as usize * w + i as usize]
        };
        let heuristic = |&(i, j): &(usize, usize)| {
            let dx = i.abs_diff(g.0) as u64;
            let dy = j.abs_diff(g.1) as u64;
            let (lo, hi) = (dx.min(dy), dx.max(dy));
            STRAIGHT * (hi - lo) + DIAGONAL * lo
        };
        let successors = |&(i, j): &(usize, usize)| {
            let (i, j) = (i as i64, j as i64);
            let mut next = Vec::with_capacity(8);
            for (di, dj) in NEIGHBOURS_8 {
                let (a, b) = (i + di, j + dj);
                if !free(a, b) {
                    continue;
                }
                let diagonal = di != 0 && dj != 0;
                // No corner cutting: both cells beside a diagonal step must be open too.
                if diagonal && !(free(i + di, j) && free(i, j + dj)) {
                    continue;
                }
                let base = if diagonal { DIAGONAL } else { STRAIGHT };
                let penalty = base * extra[b as usize * w + a as usize] / 1000;
                next.push(((a as usize, b as usize), base + penalty));
            }
            next
        };
        let (cells, _) =
            pathfinding::directed::astar::astar(&s, successors, heuristic, |c| *c == g).ok_or(
                Error::NoPath {
                    from: start,
                    to: goal,
                    radius,
                },
            )?;
        // The path: the start, the cells' centres between, the goal.
        let mut raw = Vec::with_capacity(cells.len() + 2);
        raw.push(start);
        raw.extend(
            cells
                .iter()
                .skip(1)
                .take(cells.len().saturating_sub(2))
                .map(|&(i, j)| map.centre(i, j)),
        );
        raw.push(goal);
        let visible = |a: [f64; 2], b: [f64; 2]| {
            let keep = (radius + margin)
                .min(field.clearance(a))
                .min(field.clearance(b))
                .max(radius);
            let len = (b[0] - a[0]).hypot(b[1] - a[1]);
            let n = (len / (0.25 * map.resolution)).ceil().max(1.0) as usize;
            (0..=n).all(|k| {
                let t = k as f64 / n as f64;
                field.clearance([a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]) >= keep
            })
        };
        // Pulling keeps only waypoints of the path it is given, and from one end: a grid
        // path's stair steps leave kinks where a corner is turned. So the pulled path is cut
        // into cell-long pieces and pulled again from the other end, in turn.
        let mut points = pull_taut(&raw, &visible);
        for _ in 0..PULLS {
            points.reverse();
            points = pull_taut(&densify(&points, map.resolution), &visible);
        }
        if PULLS % 2 == 1 {
            points.reverse();
        }
        let length = points
            .windows(2)
            .map(|p| (p[1][0] - p[0][0]).hypot(p[1][1] - p[0][1]))
            .sum();
        Ok(GlobalPath { points, length })
    }
}

/// `path` with points added along each segment at most `step` (m) apart.
fn densify(path: &[[f64; 2]], step: f64) -> Vec<[f64; 2]> {
    let mut out = vec![path[0]];
    for w in path.windows(2) {
        let len = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        let n = (len / step).ceil().max(1.0) as usize;
        for k in 1..=n {
            let t = k as f64 / n as f64;
            out.push([
                w[0][0] + (w[1][0] - w[0][0]) * t,
                w[0][1] + (w[1][1] - w[0][1]) * t,
            ]);
        }
    }
    out
}

/// `path` with each kept waypoint joined to a far later one it sees (`visible`), found by
/// doubling the reach and then halving between the last seen and the first unseen waypoint
/// (a logarithmic number of checks per kept waypoint; the farthest seen one could be missed
/// where what is seen is not contiguous, which the alternating rounds make up for). The ends are
/// kept. Consecutive waypoints of `path` need not see each other (a step between neighbouring
/// open cells): they are then kept as they are.
fn pull_taut(path: &[[f64; 2]], visible: &impl Fn([f64; 2], [f64; 2]) -> bool) -> Vec<[f64; 2]> {
    let last = path.len() - 1;
    let mut out = vec![path[0]];
    let mut i = 0;
    while i < last {
        let mut seen = i + 1;
        let mut unseen = None;
        let mut step = 2;
        while seen < last {
            let j = (i + step).min(last);
            if visible(path[i], path[j]) {
                seen = j;
                step *= 2;
            } else {
                unseen = Some(j);
                break;
            }
        }
        if let Some(mut b) = unseen {
            while b - seen > 1 {
                let m = seen + (b - seen) / 2;
                if visible(path[i], path[m]) {
                    seen = m;
                } else {
                    b = m;
                }
            }
        }
        out.push(path[seen]);
        i = seen;
    }
    out
}
