//! The live obstacles a depth camera reports: cells of a fixed size, each with when it was last
//! seen, marked where the camera sees something and cleared where it looks and sees nothing
//! (move_base's obstacle layer, for a camera that sees a wedge).

use std::collections::HashMap;

use ferrobot_geometry::{validate, wrap};

use crate::error::Result;
use crate::obstacles::OccupancyGrid;

/// What a range sensor (a depth camera's obstacle band, cut to the plane) saw.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Scan {
    /// The sensor's place and heading `[x, y, yaw]` in the map's frame, m and rad.
    pub sensor: [f64; 3],
    /// Half its horizontal field of view, rad.
    pub half_fov: f64,
    /// Nearer than this it does not see (its blind zone, or the robot's own body), m.
    pub near: f64,
    /// Farther than this it does not report, m.
    pub range: f64,
    /// The obstacle points it saw, `[x, y]` m in the map's frame.
    pub points: Vec<[f64; 2]>,
}

/// Live obstacle cells, keyed by their index at the layer's resolution.
#[derive(Debug, Clone)]
pub struct LiveObstacles {
    resolution: f64,
    cells: HashMap<(i64, i64), f64>,
}

impl LiveObstacles {
    /// An empty layer of `resolution` m cells; an error unless it is in [0.001, 10] m.
    pub fn new(resolution: f64) -> Result<Self> {
        validate::in_range("live obstacle cell size", resolution, 0.001, 10.0)?;
        Ok(LiveObstacles {
            resolution,
            cells: HashMap::new(),
        })
    }

    /// The cell size, m.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// How many cells are remembered.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether no cell is remembered.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The cells' centres, m.
    pub fn centres(&self) -> impl Iterator<Item = [f64; 2]> + '_ {
        let r = self.resolution;
        self.cells
            .keys()
            .map(move |&(i, j)| [i as f64 * r, j as f64 * r])
    }

    /// The same obstacles in cells of `resolution` m (each cell moved to the cell holding its
    /// centre, keeping the latest time).
    pub fn resampled(&self, resolution: f64) -> Result<Self> {
        let mut out = LiveObstacles::new(resolution)?;
        let r = self.resolution;
        for (&(i, j), &t) in &self.cells {
            let c = out.cell([i as f64 * r, j as f64 * r]);
            let e = out.cells.entry(c).or_insert(t);
            *e = e.max(t);
        }
        Ok(out)
    }

    fn cell(&self, p: [f64; 2]) -> (i64, i64) {
        let r = self.resolution;
        ((p[0] / r).round() as i64, (p[1] / r).round() as i64)
    }

    /// Takes in what a camera saw at time `now` (s): cells inside its wedge (beyond `near`,
    /// nearer than `range`) that it did not see again are cleared, as are cells older than
    /// `memory` s; the points it saw are marked, except where `known` (the map) already holds
    /// an obstacle. Returns the centres of the cells newly marked. Non-finite points are
    /// ignored; a scan whose pose or extent is not finite or out of range is an error.
    pub fn observe(
        &mut self,
        now: f64,
        scan: &Scan,
        memory: f64,
        known: Option<&OccupancyGrid>,
    ) -> Result<Vec<[f64; 2]>> {
        let Scan {
            sensor,
            half_fov,
            near,
            range,
            ref points,
        } = *scan;
        validate::finite("sensor pose", &sensor)?;
        validate::in_range(
            "sensor half field of view",
            half_fov,
            0.0,
            std::f64::consts::PI,
        )?;
        validate::in_range("sensor range", range, 0.0, 100.0)?;
        validate::in_range("sensor near range", near, 0.0, range)?;
        validate::finite("observation time", &[now])?;
        validate::in_range("live obstacle memory", memory, 0.0, 1e6)?;
        let r = self.resolution;
        let seen: HashMap<(i64, i64), ()> = points
            .iter()
            .filter(|p| p[0].is_finite() && p[1].is_finite())
            .filter(|p| (p[0] - sensor[0]).hypot(p[1] - sensor[1]) <= range)
            .map(|&p| (self.cell(p), ()))
            .collect();
        self.cells.retain(|c, t| {
            let p = [c.0 as f64 * r, c.1 as f64 * r];
            let (dx, dy) = (p[0] - sensor[0], p[1] - sensor[1]);
            let d = dx.hypot(dy);
            let inside = d < range - r
                && d > near + r
                && wrap(dy.atan2(dx) - sensor[2]).abs() < half_fov
                && !seen.contains_key(c);
            !inside && now - *t <= memory
        });
        let mut new = Vec::new();
        for c in seen.into_keys() {
            let p = [c.0 as f64 * r, c.1 as f64 * r];
            // What the map already holds needs no live cell.
            if known.is_some_and(|m| m.is_occupied(p)) {
                continue;
            }
            if self.cells.insert(c, now).is_none() {
                new.push(p);
            }
        }
        Ok(new)
    }
}
