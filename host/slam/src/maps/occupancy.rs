//! SLAM's occupancy grid kept up to date as the map grows ([`OccupancyGrid`]): counts per cell
//! (of [`GridSettings::resolution`] m, in the map's frame) and per slab of the obstacle band of
//! the rays that reached, ended in and passed through it.

use ferrobot_nav::{grid_line, Cell, MapImage};
use nalgebra::{Isometry3, Point3};

use super::GridSettings;
use crate::error::{Error, Result};
use crate::map::Map;

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
