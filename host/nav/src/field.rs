//! The navigation field (a grid distance to the goal around obstacles) and the dynamic window
//! approach that follows it.

use ferrobot_control::trajectory::{step, Limits};
use ferrobot_geometry::{validate, wrap};

use crate::obstacles::Obstacles;

/// A navigation function: the shortest 8-connected grid distance (m) to the goal around the
/// obstacles inflated by the robot radius (Dijkstra over a grid of [`NavField::CELL`] cells
/// covering the start, the goal and the obstacles with a 2 m margin). Scoring the dynamic
/// window on it instead of the straight-line distance removes the local minimum in front of an
/// Most cells times round obstacles [`NavField::new`] takes (each a distance): a second or two.
const MAX_WORK: f64 = 1e9;

/// obstacle (Brock and Khatib's global dynamic window).
#[derive(Debug, Clone)]
pub struct NavField {
    origin: [f64; 2],
    nx: usize,
    ny: usize,
    dist: Vec<f64>,
}

impl NavField {
    /// Grid cell size, m.
    pub const CELL: f64 = 0.05;

    /// The field for `goal` from `start` among `obstacles` for a robot of `radius` (m); an
    /// error when the points are not finite, the grid would have more than
    /// [`ferrobot_geometry::validate::MAX_GRID_CELLS`] cells, or its cells times the round
    /// obstacles would pass `MAX_WORK`.
    pub fn new(
        start: [f64; 2],
        goal: [f64; 2],
        obstacles: &Obstacles,
        radius: f64,
    ) -> crate::error::Result<NavField> {
        ferrobot_geometry::validate::finite("navigation start", &start)?;
        ferrobot_geometry::validate::finite("navigation goal", &goal)?;
        ferrobot_geometry::validate::finite("robot radius", &[radius])?;
        let (mut lo, mut hi) = (
            [start[0].min(goal[0]), start[1].min(goal[1])],
            [start[0].max(goal[0]), start[1].max(goal[1])],
        );
        if let Some((a, b)) = obstacles.bounds() {
            lo = [lo[0].min(a[0]), lo[1].min(a[1])];
            hi = [hi[0].max(b[0]), hi[1].max(b[1])];
        }
        let origin = [lo[0] - 2.0, lo[1] - 2.0];
        let span = |k: usize| ((hi[k] + 2.0 - origin[k]) / Self::CELL).ceil() + 1.0;
        let cells = span(0) * span(1);
        if cells.is_nan() || cells > ferrobot_geometry::validate::MAX_GRID_CELLS as f64 {
            return Err(ferrobot_geometry::ValueError::OutOfRange {
                what: "navigation grid cells (start, goal, obstacles and map)".into(),
                value: cells,
                min: 1.0,
                max: ferrobot_geometry::validate::MAX_GRID_CELLS as f64,
            }
            .into());
        }
        // Each cell's clearance costs a distance to every circle: a budget on the product, so
        // that many circles over a wide area are an error rather than hours of work.
        let work = cells * (obstacles.circles.len() as f64 + 1.0);
        if work > MAX_WORK {
            return Err(ferrobot_geometry::ValueError::OutOfRange {
                what: "navigation grid cells times round obstacles".into(),
                value: work,
                min: 1.0,
                max: MAX_WORK,
            }
            .into());
        }
        let (nx, ny) = (span(0) as usize, span(1) as usize);
        // Each cell's clearance once (a cell is reached from up to eight neighbours).
        let closed: Vec<bool> = (0..nx * ny)
            .map(|k| {
                let (i, j) = (k % nx, k / nx);
                let (x, y) = (
                    origin[0] + i as f64 * Self::CELL,
                    origin[1] + j as f64 * Self::CELL,
                );
                obstacles.clearance([x, y]) < radius
            })
            .collect();
        let blocked = |i: usize, j: usize| closed[j * nx + i];
        let mut dist = vec![f64::INFINITY; nx * ny];
        let mut heap = std::collections::BinaryHeap::new();
        let gi = (((goal[0] - origin[0]) / Self::CELL).round() as usize).min(nx - 1);
        let gj = (((goal[1] - origin[1]) / Self::CELL).round() as usize).min(ny - 1);
        dist[gj * nx + gi] = 0.0;
        // Min-heap on distance: `Reverse` of the distance's bit pattern orders non-negative
        // floats correctly.
        heap.push((std::cmp::Reverse(0u64), gi, gj));
        while let Some((std::cmp::Reverse(db), i, j)) = heap.pop() {
            let d = f64::from_bits(db);
            if d > dist[j * nx + i] {
                continue;
            }
            for (di, dj) in [
                (-1i64, 0i64),
                (1, 0),
                (0, -1),
                (0, 1),
                (-1, -1),
                (-1, 1),
                (1, -1),
                (1, 1),
            ] {
                let (a, b) = (i as i64 + di, j as i64 + dj);
                if a < 0 || b < 0 || a >= nx as i64 || b >= ny as i64 {
                    continue;
                }
                let (a, b) = (a as usize, b as usize);
                if blocked(a, b) {
                    continue;
                }
                let nd = d + Self::CELL * ((di * di + dj * dj) as f64).sqrt();
                if nd < dist[b * nx + a] {
                    dist[b * nx + a] = nd;
                    heap.push((std::cmp::Reverse(nd.to_bits()), a, b));
                }
            }
        }
        Ok(NavField {
            origin,
            nx,
            ny,
            dist,
        })
    }

    /// The grid path from `start` to the goal by steepest descent (cell centres, m), ending at
    /// the goal; empty when `start` cannot reach the goal. Ties go to the first neighbour in a
    /// fixed order, so a goal straight behind an obstacle is passed on a definite side.
    pub fn path(&self, start: [f64; 2]) -> Vec<[f64; 2]> {
        let cell = |p: [f64; 2]| {
            (
                (((p[0] - self.origin[0]) / Self::CELL).round().max(0.0) as usize).min(self.nx - 1),
                (((p[1] - self.origin[1]) / Self::CELL).round().max(0.0) as usize).min(self.ny - 1),
            )
        };
        let (mut i, mut j) = cell(start);
        let mut path = Vec::new();
        if !self.dist[j * self.nx + i].is_finite() {
            return path;
        }
        loop {
            path.push([
                self.origin[0] + i as f64 * Self::CELL,
                self.origin[1] + j as f64 * Self::CELL,
            ]);
            let d = self.dist[j * self.nx + i];
            if d == 0.0 {
                return path;
            }
            let mut best = (d, i, j);
            for (di, dj) in [
                (1i64, 0i64),
                (0, 1),
                (-1, 0),
                (0, -1),
                (1, 1),
                (-1, 1),
                (-1, -1),
                (1, -1),
            ] {
                let (a, b) = (i as i64 + di, j as i64 + dj);
                if a < 0 || b < 0 || a >= self.nx as i64 || b >= self.ny as i64 {
                    continue;
                }
                let nd = self.dist[b as usize * self.nx + a as usize];
                if nd < best.0 {
                    best = (nd, a as usize, b as usize);
                }
            }
            // Dijkstra distances strictly decrease along some neighbour until the goal.
            if best.0 >= d {
                return path;
            }
            (i, j) = (best.1, best.2);
        }
    }

    /// Distance to the goal from `p` (m), bilinearly interpolated over finite cells; outside
    /// the grid, the nearest edge value plus the distance to it. Infinite inside obstacles.
    pub fn at(&self, p: [f64; 2]) -> f64 {
        let fx = (p[0] - self.origin[0]) / Self::CELL;
        let fy = (p[1] - self.origin[1]) / Self::CELL;
        let cx = fx.clamp(0.0, (self.nx - 1) as f64);
        let cy = fy.clamp(0.0, (self.ny - 1) as f64);
        let outside = Self::CELL * (fx - cx).hypot(fy - cy);
        let (i, j) = (
            (cx.floor() as usize).min(self.nx - 2),
            (cy.floor() as usize).min(self.ny - 2),
        );
        let (tx, ty) = (cx - i as f64, cy - j as f64);
        let mut sum = 0.0;
        let mut wsum = 0.0;
        for (a, b, w) in [
            (i, j, (1.0 - tx) * (1.0 - ty)),
            (i + 1, j, tx * (1.0 - ty)),
            (i, j + 1, (1.0 - tx) * ty),
            (i + 1, j + 1, tx * ty),
        ] {
            let d = self.dist[b * self.nx + a];
            if d.is_finite() && w > 0.0 {
                sum += w * d;
                wsum += w;
            }
        }
        if wsum > 0.0 {
            sum / wsum + outside
        } else {
            f64::INFINITY
        }
    }
}

/// How far along the global path the window's local goal lies, m, with room about the base.
const LOOKAHEAD: f64 = 0.6;

/// The dynamic window approach to a goal among round obstacles and an occupancy-grid map.
#[derive(Debug, Clone)]
pub struct Dwa {
    /// Goal `[x, y]`, m.
    pub goal: [f64; 2],
    /// Obstacles.
    pub obstacles: Obstacles,
    /// Robot radius, m.
    pub radius: f64,
    /// Limits of the window.
    pub limits: Limits,
    /// Control period, s.
    pub dt: f64,
    /// Prediction horizon, s.
    pub horizon: f64,
    /// Distance to the goal around the obstacles.
    pub nav: NavField,
    /// The global path to follow ([`NavField::path`]); trajectories are scored on their
    /// distance from it, which breaks the symmetry in front of an obstacle.
    pub path: Vec<[f64; 2]>,
}

impl Dwa {
    /// The most prediction steps (`horizon / dt`) the window simulates per candidate.
    pub const MAX_STEPS: usize = 1000;

    /// The best `(v, ω)` from the current pose and velocity, or `None` when no admissible
    /// velocity avoids a collision within the horizon. `None` too for a window that cannot be
    /// evaluated: non-finite inputs, limits failing [`Limits::check`], `dt` outside
    /// [`validate::REFERENCE_DT`], or more than [`Dwa::MAX_STEPS`] prediction steps.
    pub fn command(&self, x: [f64; 3], v0: f64, w0: f64) -> Option<(f64, f64)> {
        let (lo, hi) = validate::REFERENCE_DT;
        let steps = self.horizon / self.dt;
        if validate::finite("DWA state", &[x[0], x[1], x[2], v0, w0]).is_err()
            || self.limits.check().is_err()
            || !(lo..=hi).contains(&self.dt)
            || !(0.0..=Self::MAX_STEPS as f64).contains(&steps)
        {
            return None;
        }
        let l = &self.limits;
        let (vlo, vhi) = (
            (v0 - l.accel_v * self.dt).max(-l.v * 0.2),
            (v0 + l.accel_v * self.dt).min(l.v),
        );
        let (wlo, whi) = (
            (w0 - l.accel_w * self.dt).max(-l.w),
            (w0 + l.accel_w * self.dt).min(l.w),
        );
        let mut best: Option<(f64, (f64, f64))> = None;
        let steps = (self.horizon / self.dt).round() as usize;
        // Never faster than can still stop at the goal.
        let d_now = (self.goal[0] - x[0]).hypot(self.goal[1] - x[1]);
        let v_cap = (2.0 * l.accel_v * d_now).sqrt().max(vlo);
        // The local goal: the path point `LOOKAHEAD` beyond the one nearest the robot (the
        // goal itself once the path runs out or was not found).
        // In a narrow place (a doorway) the carrot comes nearer, so the base keeps to the
        // path instead of cutting the corner beyond it with its body still in the door.
        let room = self.obstacles.clearance([x[0], x[1]]) - self.radius;
        let lookahead = (3.0 * room).clamp(0.2, LOOKAHEAD);
        let carrot = {
            let near = self
                .path
                .iter()
                .enumerate()
                .min_by(|a, b| {
                    let da = (a.1[0] - x[0]).hypot(a.1[1] - x[1]);
                    let db = (b.1[0] - x[0]).hypot(b.1[1] - x[1]);
                    da.total_cmp(&db)
                })
                .map_or(0, |(k, _)| k);
            let mut along = 0.0;
            let mut c = self.goal;
            for k in near..self.path.len() {
                if k > near {
                    let (a, b) = (self.path[k - 1], self.path[k]);
                    along += (b[0] - a[0]).hypot(b[1] - a[1]);
                }
                if along >= lookahead {
                    c = self.path[k];
                    break;
                }
            }
            c
        };
        for i in 0..=10 {
            let v = vlo + (vhi - vlo) * i as f64 / 10.0;
            if v > v_cap + 1e-12 {
                continue;
            }
            for j in 0..=20 {
                let w = wlo + (whi - wlo) * j as f64 / 20.0;
                let mut p = x;
                let mut clearance = f64::INFINITY;
                let mut hit = false;
                // Closest approach to the local goal along the arc, and the heading error there.
                let mut dist = (carrot[0] - x[0]).hypot(carrot[1] - x[1]);
                let mut heading = wrap((carrot[1] - x[1]).atan2(carrot[0] - x[0]) - x[2]).abs();
                for _ in 0..steps {
                    p = step(p, [v, w], self.dt);
                    let d = self.obstacles.clearance([p[0], p[1]]) - self.radius;
                    clearance = clearance.min(d);
                    if d < 0.0 {
                        hit = true;
                    }
                    let dg = (carrot[0] - p[0]).hypot(carrot[1] - p[1]);
                    if dg < dist {
                        dist = dg;
                        heading = wrap((carrot[1] - p[1]).atan2(carrot[0] - p[0]) - p[2]).abs();
                    }
                }
                // Admissible: it can still stop before the nearest obstacle.
                if hit || (v > 0.0 && v * v / (2.0 * l.accel_v) > clearance.max(0.0)) {
                    continue;
                }
                let off_path = self
                    .path
                    .iter()
                    .map(|q| (q[0] - p[0]).hypot(q[1] - p[1]))
                    .fold(f64::INFINITY, f64::min);
                let off_path = if off_path.is_finite() { off_path } else { 0.0 };
                // Clearance is rewarded up to 0.3 m: beyond that an obstacle does not matter,
                // and an unbounded reward would hold the base still in front of it.
                let cost = 1.0 * dist + 0.5 * off_path + 0.3 * heading
                    - 0.5 * clearance.min(0.3)
                    - 0.1 * v;
                if best.is_none_or(|(c, _)| cost < c) {
                    best = Some((cost, (v, w)));
                }
            }
        }
        best.map(|(_, u)| u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Many round obstacles over a wide area (10,000 over 100 m, once about 10¹¹ distances,
    /// eight times over) are refused at once; ten are planned round.
    #[test]
    fn many_obstacles_over_a_wide_area_are_refused_at_once() {
        let circles: Vec<[f64; 3]> = (0..10_000)
            .map(|k| [f64::from(k % 100), f64::from(k / 100), 0.05])
            .collect();
        let many = Obstacles::new(circles, None).expect("circles");
        let t = std::time::Instant::now();
        let r = NavField::new([-1.0, -1.0], [0.5, 0.5], &many, 0.2);
        assert!(r.is_err(), "planned");
        assert!(t.elapsed().as_secs_f64() < 1.0, "{:?}", t.elapsed());
        let few = Obstacles::new(
            (0..10).map(|k| [f64::from(k) * 0.5, 1.0, 0.1]).collect(),
            None,
        )
        .expect("circles");
        NavField::new([0.0, 0.0], [4.0, 2.0], &few, 0.2).expect("ten");
    }

    /// A field whose grid would exceed the cell cap, or with a non-finite point, is refused
    /// before anything is allocated.
    #[test]
    fn a_navigation_field_too_large_is_refused_before_allocating() {
        let far = NavField::new([0.0, 0.0], [1000.0, 1000.0], &Obstacles::default(), 0.2);
        assert!(matches!(
            far,
            Err(crate::Error::Value(
                ferrobot_geometry::ValueError::OutOfRange { .. }
            ))
        ));
        let nan = NavField::new([0.0, f64::NAN], [1.0, 1.0], &Obstacles::default(), 0.2);
        assert!(matches!(
            nan,
            Err(crate::Error::Value(
                ferrobot_geometry::ValueError::NotFinite { .. }
            ))
        ));
    }

    /// In free space the field is the straight-line distance within the 8-connected grid's
    /// metric error (at most 8.3 % longer, plus a cell); around an obstacle it is longer than
    /// the straight line and its path keeps the inflated clearance.
    #[test]
    fn the_navigation_field_measures_around_obstacles() {
        let free =
            NavField::new([0.0, 0.0], [2.0, 1.0], &Obstacles::default(), 0.2).expect("field");
        let d = free.at([0.0, 0.0]);
        let e = 2f64.hypot(1.0);
        assert!(
            d >= e - NavField::CELL && d <= e * 1.083 + NavField::CELL,
            "{d} vs {e}"
        );
        let obs = Obstacles::new(vec![[1.0, 0.0, 0.1]], None).expect("obstacles");
        let f = NavField::new([0.0, 0.0], [2.0, 0.0], &obs, 0.3).expect("field");
        // Around a 0.4 m inflated disc: two tangents of √(1 − 0.4²) and an arc of
        // 0.4 (π − 2 acos 0.4): 2.162 m; the grid metric reads up to 8.3 % more.
        let exact =
            2.0 * (1.0f64 - 0.16).sqrt() + 0.4 * (std::f64::consts::PI - 2.0 * 0.4f64.acos());
        let d = f.at([0.0, 0.0]);
        assert!(
            d > exact - NavField::CELL && d < exact * 1.083 + NavField::CELL,
            "{d} vs {exact}"
        );
        let path = f.path([0.0, 0.0]);
        assert!(path.len() > 10);
        let last = path[path.len() - 1];
        assert!((last[0] - 2.0).hypot(last[1]) < NavField::CELL);
        for q in &path {
            assert!((q[0] - 1.0).hypot(q[1]) >= 0.4 - 1e-9, "{q:?}");
        }
    }
}
