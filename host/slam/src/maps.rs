//! The dense maps SLAM builds from its keyframes' depth samples at their current poses (so a
//! loop closure reshapes them): a coloured voxel cloud and a 2-D occupancy grid as PyRobot's
//! LoCoBot builds it (0.02 m cells, obstacles from points 0.1-0.8 m above the floor).

use std::collections::HashMap;

use ferrobot_nav::{grid_line, neighbours, Cell, MapImage, NEIGHBOURS_8};
use ferrobot_perception::PointCloud;
use nalgebra::Point3;

use crate::error::{Error, Result};
use crate::map::Map;

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
        if !(slabs.is_finite() && (0.0..=64.0).contains(&slabs)) {
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
        // The slab of height z within the band, if any.
        let slab_of = |z: f64| -> Option<usize> {
            (s.band[0]..=s.band[1])
                .contains(&z)
                .then(|| (((z - s.band[0]) / s.slab) as usize).min(slabs - 1))
        };
        // Rays: (camera xyz, point xyz, is obstacle).
        let mut rays: Vec<([f64; 3], [f64; 3], bool)> = Vec::new();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for kf in &self.keyframes {
            // The map holds where the robot stood (half a metre about its body).
            let b = kf.pose.translation;
            for i in 0..2 {
                lo[i] = lo[i].min(b.vector[i] - 0.5);
                hi[i] = hi[i].max(b.vector[i] + 0.5);
            }
            let t = kf.camera_pose();
            let o = [t.translation.x, t.translation.y, t.translation.z];
            for (p, _) in &kf.cloud {
                let w = t * Point3::new(p.x as f64, p.y as f64, p.z as f64);
                let obstacle = (s.band[0]..=s.band[1]).contains(&w.z);
                if !(obstacle || w.z < s.floor) {
                    continue;
                }
                let e = [w.x, w.y, w.z];
                for i in 0..2 {
                    lo[i] = lo[i].min(e[i]).min(o[i]);
                    hi[i] = hi[i].max(e[i]).max(o[i]);
                }
                rays.push((o, e, obstacle));
            }
        }
        if rays.is_empty() {
            return Ok(None);
        }
        let r = s.resolution;
        let origin = [(lo[0] / r).floor() * r - r, (lo[1] / r).floor() * r - r];
        let (fw, fh) = (
            ((hi[0] - origin[0]) / r).ceil() + 2.0,
            ((hi[1] - origin[1]) / r).ceil() + 2.0,
        );
        // Checked in floating point, before any cast can saturate or a product wrap.
        let cells = fw * fh;
        if cells.is_nan() || cells > 50e6 {
            return Err(Error::InvalidSettings {
                why: format!("a grid of {fw} x {fh} cells is too large"),
            });
        }
        let (width, height) = (fw as usize, fh as usize);
        let n = width * height;
        // Per slab and cell: rays that ended there, rays that passed through.
        let mut hits = vec![0u32; n * slabs];
        let mut passes = vec![0u32; n * slabs];
        // Cells some ray reached at any height.
        let mut reached = vec![false; n];
        let cell = |p: [f64; 3]| -> (i64, i64) {
            (
                ((p[0] - origin[0]) / r).floor() as i64,
                ((p[1] - origin[1]) / r).floor() as i64,
            )
        };
        for (o, e, obstacle) in rays {
            let (i0, j0) = cell(o);
            let (i1, j1) = cell(e);
            // The cells from the camera's to the point's, its last cell excluded; the ray's
            // height over a cell from how far along it the cell lies.
            let steps = (i1 - i0).abs().max((j1 - j0).abs()).max(1) as f64;
            for (i, j) in grid_line((i0, j0), (i1, j1)).take_while(|&c| c != (i1, j1)) {
                let k = j as usize * width + i as usize;
                reached[k] = true;
                let along = ((i - i0).abs().max((j - j0).abs()) as f64 / steps).min(1.0);
                if let Some(z) = slab_of(o[2] + along * (e[2] - o[2])) {
                    passes[z * n + k] += 1;
                }
            }
            let k = j1 as usize * width + i1 as usize;
            reached[k] = true;
            if obstacle {
                // The point and the slabs within `surface` of it (the band clamps the range).
                let clamp = |z: f64| slab_of(z.clamp(s.band[0], s.band[1]));
                if let (Some(a), Some(b)) = (clamp(e[2] - s.surface), clamp(e[2] + s.surface)) {
                    for z in a..=b {
                        hits[z * n + k] += 1;
                    }
                }
            }
        }
        let cells = (0..n)
            .map(|k| {
                let occupied = (0..slabs).any(|z| {
                    let (h, p) = (hits[z * n + k], passes[z * n + k]);
                    h >= s.min_hits && h as f64 >= s.min_ratio * (h + p) as f64
                });
                if occupied {
                    Cell::Occupied
                } else if reached[k] {
                    Cell::Free
                } else {
                    Cell::Unknown
                }
            })
            .collect();
        Ok(Some(MapImage {
            origin,
            resolution: r,
            width,
            height,
            cells,
        }))
    }
}

/// Agreement of two maps of the same resolution: the intersection over union of their free
/// cells and of their occupied cells, over the cells of `truth` (cells of `estimate` outside it,
/// or `Unknown`, count as not free and not occupied). Occupied cells match within `slack`
/// cells (a wall drawn one cell off still counts).
pub fn map_iou(estimate: &MapImage, truth: &MapImage, slack: usize) -> Result<MapIou> {
    map_iou_seen(estimate, truth, truth, slack)
}

/// As [`map_iou`] against `must`, the part of the truth a map must hold (say the
/// [`reachable_part`] of a floor plan: floor the robot can reach and the faces next to it),
/// where an occupied cell of `estimate` that `must` leaves unknown is judged against the whole
/// truth `all`: right (in both maps) when `all` has an obstacle within `slack` cells of it (the
/// top of a bed seen from above is the bed), wrong otherwise. Both truths share one grid.
pub fn map_iou_seen(
    estimate: &MapImage,
    must: &MapImage,
    all: &MapImage,
    slack: usize,
) -> Result<MapIou> {
    let truth = must;
    for m in [estimate, all] {
        if (m.resolution - truth.resolution).abs() > 1e-9 {
            return Err(Error::Trajectory {
                why: format!(
                    "maps of resolution {} and {} m",
                    m.resolution, truth.resolution
                ),
            });
        }
    }
    if all.width != truth.width || all.height != truth.height || all.origin != truth.origin {
        return Err(Error::Trajectory {
            why: "the two truths are not on one grid".into(),
        });
    }
    let r = truth.resolution;
    let at = |m: &MapImage, x: f64, y: f64| -> Cell {
        let i = ((x - m.origin[0]) / r).floor();
        let j = ((y - m.origin[1]) / r).floor();
        if i < 0.0 || j < 0.0 || i >= m.width as f64 || j >= m.height as f64 {
            return Cell::Unknown;
        }
        m.cells[j as usize * m.width + i as usize]
    };
    let near_occupied = |m: &MapImage, x: f64, y: f64| -> bool {
        let s = slack as i64;
        (-s..=s).any(|di| {
            (-s..=s).any(|dj| at(m, x + di as f64 * r, y + dj as f64 * r) == Cell::Occupied)
        })
    };
    let (mut fi, mut fu, mut oi, mut ou) = (0usize, 0usize, 0usize, 0usize);
    for j in 0..truth.height {
        for i in 0..truth.width {
            let x = truth.origin[0] + (i as f64 + 0.5) * r;
            let y = truth.origin[1] + (j as f64 + 0.5) * r;
            let t = truth.cells[j * truth.width + i];
            let e = at(estimate, x, y);
            let (tf, ef) = (t == Cell::Free, e == Cell::Free);
            fi += (tf && ef) as usize;
            fu += (tf || ef) as usize;
            let (to, eo) = (t == Cell::Occupied, e == Cell::Occupied);
            if to || eo {
                ou += 1;
                let hit = if to {
                    near_occupied(estimate, x, y)
                } else {
                    near_occupied(all, x, y)
                };
                oi += hit as usize;
            }
        }
    }
    let ratio = |a: usize, b: usize| if b == 0 { 1.0 } else { a as f64 / b as f64 };
    Ok(MapIou {
        free: ratio(fi, fu),
        occupied: ratio(oi, ou),
        cells: ratio(fi + oi, fu + ou),
    })
}

/// The part of a ground-truth map that a robot starting at `from` (m) can map: the free cells
/// joined to its cell through free cells (8-connected) and the occupied cells within one cell
/// of them (the surfaces it can see); the rest is unknown: the inside of furniture and walls,
/// and what lies beyond the outer walls. An error when `from` is outside the map or not on a
/// free cell.
pub fn reachable_part(truth: &MapImage, from: [f64; 2]) -> Result<MapImage> {
    truth.check().map_err(|e| Error::Trajectory {
        why: format!("ground-truth map: {e}"),
    })?;
    let r = truth.resolution;
    let (w, h) = (truth.width, truth.height);
    let i = ((from[0] - truth.origin[0]) / r).floor();
    let j = ((from[1] - truth.origin[1]) / r).floor();
    if !(i >= 0.0 && j >= 0.0 && i < w as f64 && j < h as f64) {
        return Err(Error::Trajectory {
            why: format!("the start {from:?} m is outside the map"),
        });
    }
    let start = (i as usize, j as usize);
    if truth.cells[start.1 * w + start.0] != Cell::Free {
        return Err(Error::Trajectory {
            why: format!("the start {from:?} m is not on a free cell"),
        });
    }
    let mut reached = vec![false; w * h];
    reached[start.1 * w + start.0] = true;
    let mut queue = std::collections::VecDeque::from([start]);
    while let Some(c) = queue.pop_front() {
        for ((x, y), _) in neighbours(c, w, h, &NEIGHBOURS_8) {
            let k = y * w + x;
            if !reached[k] && truth.cells[k] == Cell::Free {
                reached[k] = true;
                queue.push_back((x, y));
            }
        }
    }
    let mut cells = vec![Cell::Unknown; w * h];
    for b in 0..h {
        for a in 0..w {
            let k = b * w + a;
            cells[k] = match truth.cells[k] {
                Cell::Free if reached[k] => Cell::Free,
                Cell::Occupied => {
                    // Next to a reached cell (an occupied cell is never reached itself).
                    let seen = neighbours((a, b), w, h, &NEIGHBOURS_8)
                        .any(|((x, y), _)| reached[y * w + x]);
                    if seen {
                        Cell::Occupied
                    } else {
                        Cell::Unknown
                    }
                }
                _ => Cell::Unknown,
            };
        }
    }
    Ok(MapImage {
        cells,
        ..truth.clone()
    })
}

/// The agreement [`map_iou`] measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapIou {
    /// Intersection over union of the free cells.
    pub free: f64,
    /// Intersection over union of the occupied cells, within the slack.
    pub occupied: f64,
    /// Cells labelled alike (free, or occupied within the slack) over cells either map labels
    /// free or occupied: the two classes together.
    pub cells: f64,
}
