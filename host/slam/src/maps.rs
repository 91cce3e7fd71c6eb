//! The dense maps SLAM builds from its keyframes' depth samples at their current poses (so a
//! loop closure reshapes them): a coloured voxel cloud and a 2-D occupancy grid as PyRobot's
//! LoCoBot builds it (0.02 m cells, obstacles from points 0.1-0.8 m above the floor).

use std::collections::HashMap;

use ferrobot_nav::{grid_line, neighbours, Cell, MapImage, NEIGHBOURS_8};
use ferrobot_perception::PointCloud;
use nalgebra::{Isometry3, Point3};

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

/// Most cells an occupancy grid may span.
const MAX_CELLS: f64 = 50e6;

/// SLAM's occupancy grid ([`Map::occupancy`]) kept up to date as the map grows: each
/// keyframe's rays are counted once, when it first comes, and again only when a loop closure
/// moves it (its old rays are taken out first, so the counts are always those of the
/// keyframes at their current poses). [`OccupancyGrid::update`] gives the image
/// [`Map::occupancy`] would (which is this, fresh), for the cost of the new and moved
/// keyframes rather than of the whole map.
#[derive(Debug, Clone)]
pub struct OccupancyGrid {
    s: GridSettings,
    slabs: usize,
    /// The block of cells counted: its first cell (`floor(x / resolution)`,
    /// `floor(y / resolution)` of the map's frame) and its size, cells. It grows (with a
    /// margin) as the map does.
    first: [i64; 2],
    size: [usize; 2],
    /// Per cell of the block, row-major: rays that reached it, then per slab the rays that
    /// ended in it, then per slab the rays that passed through it.
    counts: Vec<u32>,
    /// The keyframes counted, in the map's order.
    counted: Vec<Counted>,
}

/// What a keyframe was counted with.
#[derive(Debug, Clone)]
struct Counted {
    /// Its identity in the map: time and number of depth samples.
    time: f64,
    samples: usize,
    /// Its body and camera poses when counted.
    pose: Isometry3<f64>,
    camera: Isometry3<f64>,
    /// Its bounds in the map's frame (x, y; m): the body's half metre and its rays' ends.
    lo: [f64; 2],
    hi: [f64; 2],
    /// Whether it had rays.
    rays: bool,
}

/// One ray: camera position, point, whether the point is an obstacle (else floor).
type Ray = ([f64; 3], [f64; 3], bool);

impl OccupancyGrid {
    /// An empty grid with these settings. Errors: settings out of range.
    pub fn new(s: GridSettings) -> Result<Self> {
        let slabs = s.slabs()?;
        Ok(OccupancyGrid {
            s,
            slabs,
            first: [0; 2],
            size: [0; 2],
            counts: Vec::new(),
            counted: Vec::new(),
        })
    }

    /// Brings the counts to `map`'s keyframes at their current poses and returns the grid
    /// ([`Map::occupancy`]'s image; `None` before any ray). A map that is not the one counted
    /// so far (its keyframes are not the ones counted, in order) is counted afresh. Errors: a
    /// grid of more than 50 million cells (the grid is then emptied).
    pub fn update(&mut self, map: &Map) -> Result<Option<MapImage>> {
        let kfs = map.keyframes();
        let same =
            self.counted.len() <= kfs.len()
                && self.counted.iter().zip(kfs).all(|(c, k)| {
                    c.time.to_bits() == k.time.to_bits() && c.samples == k.cloud.len()
                });
        if !same {
            self.clear();
        }
        let result = self.count_all(map);
        if result.is_err() {
            self.clear();
        }
        result?;
        Ok(self.image())
    }

    fn clear(&mut self) {
        self.first = [0; 2];
        self.size = [0; 2];
        self.counts.clear();
        self.counted.clear();
    }

    fn count_all(&mut self, map: &Map) -> Result<()> {
        for (i, kf) in map.keyframes().iter().enumerate() {
            let camera = kf.camera_pose();
            if let Some(c) = self.counted.get(i) {
                if c.pose == kf.pose && c.camera == camera {
                    continue;
                }
                // Moved: its old rays out (the block still holds them: it only grows).
                let (rays, _, _) = self.rays(&kf.cloud, &c.pose, &c.camera);
                self.count(&rays, false);
            }
            let (rays, lo, hi) = self.rays(&kf.cloud, &kf.pose, &camera);
            self.cover(lo, hi)?;
            self.count(&rays, true);
            let c = Counted {
                time: kf.time,
                samples: kf.cloud.len(),
                pose: kf.pose,
                camera,
                lo,
                hi,
                rays: !rays.is_empty(),
            };
            if i < self.counted.len() {
                self.counted[i] = c;
            } else {
                self.counted.push(c);
            }
        }
        Ok(())
    }

    /// A keyframe's rays seen from `camera` (in the map's frame) and its bounds.
    fn rays(
        &self,
        cloud: &[(Point3<f32>, [u8; 3])],
        pose: &Isometry3<f64>,
        camera: &Isometry3<f64>,
    ) -> (Vec<Ray>, [f64; 2], [f64; 2]) {
        let s = &self.s;
        // The map holds where the robot stood (half a metre about its body).
        let b = pose.translation.vector;
        let mut lo = [b[0] - 0.5, b[1] - 0.5];
        let mut hi = [b[0] + 0.5, b[1] + 0.5];
        let o = [
            camera.translation.x,
            camera.translation.y,
            camera.translation.z,
        ];
        let mut rays = Vec::new();
        for (p, _) in cloud {
            let w = camera * Point3::new(p.x as f64, p.y as f64, p.z as f64);
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
        (rays, lo, hi)
    }

    /// Grows the block to hold every cell of the bounds `lo`..`hi` (m). Errors: more than
    /// [`MAX_CELLS`] cells.
    fn cover(&mut self, lo: [f64; 2], hi: [f64; 2]) -> Result<()> {
        let r = self.s.resolution;
        let (mut a, mut b) = ([0.0f64; 2], [0.0f64; 2]);
        for i in 0..2 {
            a[i] = (lo[i] / r).floor();
            b[i] = (hi[i] / r).floor();
            if self.size[i] > 0 {
                a[i] = a[i].min(self.first[i] as f64);
                b[i] = b[i].max((self.first[i] + self.size[i] as i64 - 1) as f64);
            }
        }
        // Checked in floating point, before any cast can saturate or a product wrap.
        let cells = (b[0] - a[0] + 1.0) * (b[1] - a[1] + 1.0);
        if cells.is_nan() || cells > MAX_CELLS {
            return Err(Error::InvalidSettings {
                why: format!(
                    "a grid of {} x {} cells is too large",
                    b[0] - a[0] + 1.0,
                    b[1] - a[1] + 1.0
                ),
            });
        }
        let inside = self.size[0] > 0
            && (0..2).all(|i| {
                a[i] as i64 >= self.first[i] && (b[i] as i64) < self.first[i] + self.size[i] as i64
            });
        if inside {
            return Ok(());
        }
        // A margin of a quarter of the span (at least 32 cells) on every side, so that a
        // growing map copies its counts a few times, not at every keyframe.
        let span = [b[0] - a[0] + 1.0, b[1] - a[1] + 1.0];
        let m = [(span[0] / 4.0).max(32.0), (span[1] / 4.0).max(32.0)];
        let (a, b) = if (span[0] + 2.0 * m[0]) * (span[1] + 2.0 * m[1]) <= MAX_CELLS {
            ([a[0] - m[0], a[1] - m[1]], [b[0] + m[0], b[1] + m[1]])
        } else {
            (a, b)
        };
        let first = [a[0] as i64, a[1] as i64];
        let size = [(b[0] - a[0]) as usize + 1, (b[1] - a[1]) as usize + 1];
        let stride = 1 + 2 * self.slabs;
        let mut counts = vec![0u32; size[0] * size[1] * stride];
        for j in 0..self.size[1] {
            let row = (j as i64 + self.first[1] - first[1]) as usize;
            let col = (self.first[0] - first[0]) as usize;
            let from = j * self.size[0] * stride;
            let to = (row * size[0] + col) * stride;
            let n = self.size[0] * stride;
            counts[to..to + n].copy_from_slice(&self.counts[from..from + n]);
        }
        self.first = first;
        self.size = size;
        self.counts = counts;
        Ok(())
    }

    /// Adds (or takes out) the rays' counts; every cell of theirs is in the block.
    fn count(&mut self, rays: &[Ray], add: bool) {
        let s = self.s;
        let slabs = self.slabs;
        let stride = 1 + 2 * slabs;
        let r = s.resolution;
        // The slab of height z within the band, if any.
        let slab_of = |z: f64| -> Option<usize> {
            (s.band[0]..=s.band[1])
                .contains(&z)
                .then(|| (((z - s.band[0]) / s.slab) as usize).min(slabs - 1))
        };
        let cell =
            |p: [f64; 3]| -> (i64, i64) { ((p[0] / r).floor() as i64, (p[1] / r).floor() as i64) };
        let (first, width) = (self.first, self.size[0]);
        let at = |(i, j): (i64, i64)| -> usize {
            ((j - first[1]) as usize * width + (i - first[0]) as usize) * stride
        };
        let counts = &mut self.counts;
        let mut bump = |k: usize| {
            if add {
                counts[k] += 1;
            } else {
                counts[k] -= 1;
            }
        };
        for &(o, e, obstacle) in rays {
            let (i0, j0) = cell(o);
            let (i1, j1) = cell(e);
            // The cells from the camera's to the point's, its last cell excluded; the ray's
            // height over a cell from how far along it the cell lies.
            let steps = (i1 - i0).abs().max((j1 - j0).abs()).max(1) as f64;
            for (i, j) in grid_line((i0, j0), (i1, j1)).take_while(|&c| c != (i1, j1)) {
                let k = at((i, j));
                bump(k);
                let along = ((i - i0).abs().max((j - j0).abs()) as f64 / steps).min(1.0);
                if let Some(z) = slab_of(o[2] + along * (e[2] - o[2])) {
                    bump(k + 1 + slabs + z);
                }
            }
            let k = at((i1, j1));
            bump(k);
            if obstacle {
                // The point and the slabs within `surface` of it (the band clamps the range).
                let clamp = |z: f64| slab_of(z.clamp(s.band[0], s.band[1]));
                if let (Some(a), Some(b)) = (clamp(e[2] - s.surface), clamp(e[2] + s.surface)) {
                    for z in a..=b {
                        bump(k + 1 + z);
                    }
                }
            }
        }
    }

    /// The grid over the counted keyframes' bounds, one cell of margin; `None` without rays.
    fn image(&self) -> Option<MapImage> {
        if !self.counted.iter().any(|c| c.rays) {
            return None;
        }
        let s = &self.s;
        let r = s.resolution;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for c in &self.counted {
            for i in 0..2 {
                lo[i] = lo[i].min(c.lo[i]);
                hi[i] = hi[i].max(c.hi[i]);
            }
        }
        let corner = [
            (lo[0] / r).floor() as i64 - 1,
            (lo[1] / r).floor() as i64 - 1,
        ];
        let origin = [corner[0] as f64 * r, corner[1] as f64 * r];
        let width = ((hi[0] - origin[0]) / r).ceil() as usize + 2;
        let height = ((hi[1] - origin[1]) / r).ceil() as usize + 2;
        let stride = 1 + 2 * self.slabs;
        let slabs = self.slabs;
        let mut cells = vec![Cell::Unknown; width * height];
        for (j, row) in cells.chunks_exact_mut(width).enumerate() {
            let gj = corner[1] + j as i64 - self.first[1];
            if gj < 0 || gj >= self.size[1] as i64 {
                continue;
            }
            for (i, out) in row.iter_mut().enumerate() {
                let gi = corner[0] + i as i64 - self.first[0];
                if gi < 0 || gi >= self.size[0] as i64 {
                    continue;
                }
                let k = (gj as usize * self.size[0] + gi as usize) * stride;
                let c = &self.counts[k..k + stride];
                let occupied = (0..slabs).any(|z| {
                    let (h, p) = (c[1 + z], c[1 + slabs + z]);
                    h >= s.min_hits && h as f64 >= s.min_ratio * (h + p) as f64
                });
                *out = if occupied {
                    Cell::Occupied
                } else if c[0] > 0 {
                    Cell::Free
                } else {
                    Cell::Unknown
                };
            }
        }
        Some(MapImage {
            origin,
            resolution: r,
            width,
            height,
            cells,
        })
    }
}

/// Agreement of two maps of the same resolution: the intersection over union of their free
/// cells and of their occupied cells, over the cells of `truth` (cells of `estimate` outside it,
/// or `Unknown`, count as not free and not occupied). Occupied cells match within `slack`
/// cells (a wall drawn one cell off still counts), at most [`MAX_SLACK`].
pub fn map_iou(estimate: &MapImage, truth: &MapImage, slack: usize) -> Result<MapIou> {
    map_iou_seen(estimate, truth, truth, slack)
}

/// Largest `slack` of [`map_iou`] and [`map_iou_seen`], cells: each occupied cell looks at
/// (2·slack + 1)² cells.
pub const MAX_SLACK: usize = 100;

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
    for (what, m) in [
        ("estimate", estimate),
        ("truth", must),
        ("whole truth", all),
    ] {
        m.check().map_err(|e| Error::Trajectory {
            why: format!("{what} map: {e}"),
        })?;
    }
    if slack > MAX_SLACK {
        return Err(Error::Trajectory {
            why: format!("a slack of {slack} cells is more than {MAX_SLACK}"),
        });
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::Keyframe;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// A keyframe at `(x, y, yaw)` whose camera (0.5 m up, pitched 0.4 rad down) sees `n`
    /// pseudo-random points 0.4-3 m ahead: floor, obstacles and points above the band.
    fn keyframe(time: f64, x: f64, y: f64, yaw: f64, n: usize, seed: &mut u64) -> Keyframe {
        let mut next = || {
            *seed ^= *seed << 13;
            *seed ^= *seed >> 7;
            *seed ^= *seed << 17;
            (*seed >> 11) as f64 / (1u64 << 53) as f64
        };
        // Optical frame (x right, y down, z forward) in the body: pitched down.
        let camera = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.5),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.4)
                * UnitQuaternion::from_euler_angles(-std::f64::consts::FRAC_PI_2, 0.0, 0.0)
                * UnitQuaternion::from_euler_angles(0.0, 0.0, -std::f64::consts::FRAC_PI_2),
        );
        // Every point three times (a surface seen by neighbouring pixels), so that obstacles
        // get the hits a cell needs.
        let cloud = (0..n / 3)
            .flat_map(|_| {
                let p = Point3::new(
                    (next() * 2.0 - 1.0) as f32,
                    (next() * 1.0 - 0.6) as f32,
                    (0.4 + next() * 2.6) as f32,
                );
                [(p, [0u8; 3]); 3]
            })
            .collect();
        Keyframe {
            time,
            pose: Isometry3::from_parts(
                Translation3::new(x, y, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            ),
            camera,
            descriptors: Vec::new(),
            landmarks: Vec::new(),
            cloud,
        }
    }

    #[test]
    fn the_kept_grid_is_the_fresh_one_as_keyframes_come_and_move() {
        let s = GridSettings::default();
        let mut seed = 0x5eed_0000_1234_abcdu64;
        let mut map = Map {
            keyframes: Vec::new(),
            landmarks: Vec::new(),
            edges: Vec::new(),
        };
        let mut kept = OccupancyGrid::new(s).expect("settings");
        assert_eq!(kept.update(&map).expect("empty"), None);
        // A drive that leaves the block more than once (it grows), then a turn back.
        for k in 0..12 {
            let (x, y, yaw) = (0.6 * k as f64, 0.2 * k as f64, 0.3 * k as f64);
            map.keyframes
                .push(keyframe(k as f64, x, y, yaw, 400, &mut seed));
            let fresh = map.occupancy(&s).expect("fresh").expect("rays");
            assert_eq!(
                kept.update(&map).expect("kept"),
                Some(fresh),
                "keyframe {k}"
            );
        }
        let cells = |m: &MapImage, c: Cell| m.cells.iter().filter(|&&x| x == c).count();
        let before = map.occupancy(&s).expect("grid").expect("rays");
        let (occupied, free) = (cells(&before, Cell::Occupied), cells(&before, Cell::Free));
        assert!(
            occupied > 100 && free > 1000,
            "{occupied} occupied, {free} free"
        );
        // A loop closure moves the keyframes from the fifth on.
        for kf in &mut map.keyframes[4..] {
            kf.pose = Isometry3::from_parts(
                Translation3::new(0.05, -0.03, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.02),
            ) * kf.pose;
        }
        let fresh = map.occupancy(&s).expect("fresh").expect("rays");
        assert_ne!(fresh, before, "the move changes the grid");
        assert_eq!(kept.update(&map).expect("kept"), Some(fresh));
        // Another map (fewer keyframes): counted afresh.
        map.keyframes.truncate(3);
        let fresh = map.occupancy(&s).expect("fresh").expect("rays");
        assert_eq!(kept.update(&map).expect("kept"), Some(fresh));
        // A keyframe that would need a grid too large: an error, and the grid starts again.
        map.keyframes
            .push(keyframe(99.0, 1e6, 0.0, 0.0, 10, &mut seed));
        assert!(kept.update(&map).is_err());
        map.keyframes.pop();
        let fresh = map.occupancy(&s).expect("fresh").expect("rays");
        assert_eq!(kept.update(&map).expect("kept"), Some(fresh));
    }
}
