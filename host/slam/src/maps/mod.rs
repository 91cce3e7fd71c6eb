//! The dense maps SLAM builds from its keyframes' depth samples at their current poses (so a
//! loop closure reshapes them): a coloured voxel cloud and a 2-D occupancy grid as PyRobot's
//! LoCoBot builds it (0.02 m cells, obstacles from points 0.1-0.8 m above the floor), kept up
//! to date by [`OccupancyGrid`]; and how well a grid agrees with a ground truth ([`map_iou`]).

use std::collections::HashMap;

use ferrobot_nav::MapImage;
use ferrobot_perception::PointCloud;
use nalgebra::Point3;

use crate::error::{Error, Result};
use crate::map::Map;

mod compare;
mod occupancy;

pub use compare::{map_iou, map_iou_seen, reachable_part, MapIou, MAX_SLACK};
pub use occupancy::OccupancyGrid;

/// Settings of the occupancy grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridSettings {
    /// Cell size, m (PyRobot: 0.02).
    pub resolution: f64,
    /// Heights above the floor (world z = 0) whose points are obstacles, m (PyRobot: 0.1-0.8).
    pub band: [f64; 2],
    /// Points lower than this are floor: they clear the cells on their ray, m.
    pub floor: f64,
    /// A cell is occupied when, in some slab of the band this high (m), at least this many of
    /// its rays ended in it ...
    pub slab: f64,
    /// ... at least this many of its rays ended in it ...
    pub min_hits: u32,
    /// ... and at least this fraction of the rays that reached it in that slab.
    pub min_ratio: f64,
    /// A point marks every slab within this height of it, m: a flat top at a slab's edge (a
    /// bed's top at 0.5 m) is held by the slab below too, which the rays grazing over the top
    /// do not pass (they would outvote its points in the slab above).
    pub surface: f64,
}

impl Default for GridSettings {
    fn default() -> Self {
        GridSettings {
            resolution: 0.02,
            band: [0.1, 0.8],
            floor: 0.05,
            slab: 0.1,
            min_hits: 2,
            min_ratio: 0.3,
            surface: 0.02,
        }
    }
}

impl Map {
    /// Every keyframe's depth sample in the world, averaged per voxel of `voxel` m (position
    /// and colour): the dense coloured map.
    pub fn cloud(&self, voxel: f64) -> Result<PointCloud> {
        if !(voxel.is_finite() && (1e-3..=1.0).contains(&voxel)) {
            return Err(Error::InvalidSettings {
                why: format!("voxel size {voxel} m is not in [0.001, 1]"),
            });
        }
        let mut cells: HashMap<[i32; 3], ([f64; 3], [u32; 3], u32)> = HashMap::new();
        let mut order = Vec::new();
        for kf in &self.keyframes {
            let t = kf.camera_pose();
            for (p, c) in &kf.cloud {
                let w = t * Point3::new(p.x as f64, p.y as f64, p.z as f64);
                let key = [
                    (w.x / voxel).floor() as i32,
                    (w.y / voxel).floor() as i32,
                    (w.z / voxel).floor() as i32,
                ];
                let e = cells.entry(key).or_insert_with(|| {
                    order.push(key);
                    ([0.0; 3], [0; 3], 0)
                });
                for i in 0..3 {
                    e.0[i] += w[i];
                    e.1[i] += c[i] as u32;
                }
                e.2 += 1;
            }
        }
        let mut cloud = PointCloud::default();
        for key in order {
            let (s, c, n) = cells[&key];
            let nf = n as f64;
            cloud
                .points
                .push(Point3::new(s[0] / nf, s[1] / nf, s[2] / nf));
            cloud
                .colours
                .push([(c[0] / n) as u8, (c[1] / n) as u8, (c[2] / n) as u8]);
        }
        Ok(cloud)
    }

    /// The occupancy grid of the keyframes' depth samples: rays from the camera clear the cells
    /// they cross; points in the obstacle band mark their cell. Each cell keeps its counts per
    /// slab of the band ([`GridSettings::slab`] high): a ray passing above a low obstacle (a
    /// ball, a bed's top seen from higher up) clears only the slab it passes through, so it does
    /// not outvote the obstacle's own points; a point counts in the slabs within
    /// [`GridSettings::surface`] of it. A cell is occupied when some slab is, free when a
    /// ray reached it and no slab is. The grid covers what was seen, with one cell of margin;
    /// `None` before any keyframe.
    pub fn occupancy(&self, s: &GridSettings) -> Result<Option<MapImage>> {
        OccupancyGrid::new(*s)?.update(self)
    }
}

impl GridSettings {
    /// Checks the settings; the number of slabs the band is cut into.
    fn slabs(&self) -> Result<usize> {
        let s = self;
        if !(s.resolution.is_finite() && (1e-3..=1.0).contains(&s.resolution)) {
            return Err(Error::InvalidSettings {
                why: format!("resolution {} m is not in [0.001, 1]", s.resolution),
            });
        }
        if !(s.band[0].is_finite() && s.band[1].is_finite() && s.band[0] < s.band[1]) {
            return Err(Error::InvalidSettings {
                why: format!("obstacle band {:?} m is not an interval", s.band),
            });
        }
        let slabs = (s.band[1] - s.band[0]) / s.slab;
        if !(s.slab.is_finite() && slabs.is_finite() && (0.0..=64.0).contains(&slabs)) {
            return Err(Error::InvalidSettings {
                why: format!(
                    "slabs of {} m cut the band {:?} m into more than 64 or none",
                    s.slab, s.band
                ),
            });
        }
        let slabs = (slabs.ceil() as usize).max(1);
        if !(s.surface.is_finite() && (0.0..=s.slab).contains(&s.surface)) {
            return Err(Error::InvalidSettings {
                why: format!(
                    "a surface's height {} m is not within [0, {}] (the slab)",
                    s.surface, s.slab
                ),
            });
        }
        // A cell no ray reached would pass `min_hits = 0` and be occupied; a NaN ratio or
        // floor would mark nothing, or drop every floor ray.
        if s.min_hits == 0 || !(s.min_ratio.is_finite() && (0.0..=1.0).contains(&s.min_ratio)) {
            return Err(Error::InvalidSettings {
                why: format!(
                    "min_hits {} must be at least 1 and min_ratio {} in [0, 1]",
                    s.min_hits, s.min_ratio
                ),
            });
        }
        if !(s.floor.is_finite() && s.floor <= s.band[0]) {
            return Err(Error::InvalidSettings {
                why: format!(
                    "the floor's height {} m must be finite and not above the band {:?} m",
                    s.floor, s.band
                ),
            });
        }
        Ok(slabs)
    }
}
