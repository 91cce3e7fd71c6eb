//! One RGB-D frame as SLAM sees it: its ORB features that have a depth, their points in the
//! camera's optical frame, a grid to find features near a pixel, and a sparse sample of the
//! depth image for the dense maps.

use ferrobot_perception::{DepthImage, RgbImage};
use nalgebra::{Isometry3, Point3};

use crate::orb::{Descriptor, GreyImage, Keypoint, OrbExtractor};

/// Side of the cells of the feature grid, px.
const GRID: usize = 16;

/// The features of one frame that have a usable depth.
#[derive(Debug, Clone, Default)]
pub(crate) struct FrameFeatures {
    pub keypoints: Vec<Keypoint>,
    pub descriptors: Vec<Descriptor>,
    /// Each feature's point in the optical frame (x right, y down, z forward), m.
    pub points: Vec<Point3<f64>>,
    /// Feature indices by grid cell (row-major, `GRID` px cells).
    grid: Vec<Vec<u32>>,
    cols: usize,
    rows: usize,
}

/// Which depths make features and map points, and what is masked out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DepthUse {
    /// Nearest and farthest usable depth, m.
    pub min: f64,
    pub max: f64,
    /// The robot's own body: points within this radius (m) of the body frame's z axis are
    /// dropped (the arm and mast in view).
    pub self_radius: f64,
}

impl FrameFeatures {
    /// The features of `rgb` with a valid depth in `depth` away from depth edges (the 3 × 3
    /// neighbourhood within 5 % of the centre), in range, and off the robot's body: neither
    /// on it nor with it inside the patch the descriptor is drawn from (a corner where the
    /// arm's edge crosses the wall behind moves with the camera, not with the world).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        orb: &OrbExtractor,
        rgb: &RgbImage,
        depth: &DepthImage,
        k: &ferrobot_perception::Intrinsics,
        t_bc: &Isometry3<f64>,
        range: DepthUse,
    ) -> Self {
        let (w, h) = (rgb.width as usize, rgb.height as usize);
        let grey = GreyImage::from_rgb(w, h, &rgb.data).unwrap_or(GreyImage {
            width: w,
            height: h,
            data: vec![0; w * h],
        });
        let all = orb.extract(&grey);
        let is_self = SelfTest::new(t_bc, range);
        let body = (range.self_radius > 0.0).then(|| SelfMask::new(depth, k, &is_self));
        let cols = w.div_ceil(GRID);
        let rows = h.div_ceil(GRID);
        let mut f = FrameFeatures {
            grid: vec![Vec::new(); cols * rows],
            cols,
            rows,
            ..Default::default()
        };
        for (kp, d) in all.keypoints.iter().zip(&all.descriptors) {
            let (c, r) = (kp.u.round() as usize, kp.v.round() as usize);
            let Some(z) = depth_at(depth, c, r) else {
                continue;
            };
            if !(range.min..=range.max).contains(&z) {
                continue;
            }
            // A depth edge: the neighbours disagree.
            let mut edge = false;
            for dr in -1i64..=1 {
                for dc in -1i64..=1 {
                    let zz = depth_at(depth, (c as i64 + dc) as usize, (r as i64 + dr) as usize);
                    if zz.is_none_or(|zz| (zz - z).abs() > 0.05 * z) {
                        edge = true;
                    }
                }
            }
            if edge {
                continue;
            }
            let p = k.unproject(kp.v as f64, kp.u as f64, z);
            if let Some(body) = &body {
                if is_self.contains(&p) {
                    continue;
                }
                let reach = (DESCRIPTOR_REACH * orb.level_scale(kp.level)).ceil() as i64;
                if body.any_within(c as i64, r as i64, reach) {
                    continue;
                }
            }
            let i = f.keypoints.len() as u32;
            let cell =
                (kp.v as usize / GRID).min(rows - 1) * cols + (kp.u as usize / GRID).min(cols - 1);
            f.grid[cell].push(i);
            f.keypoints.push(*kp);
            f.descriptors.push(*d);
            f.points.push(p);
        }
        f
    }

    /// Number of features.
    pub fn len(&self) -> usize {
        self.keypoints.len()
    }

    /// Indices of the features within `radius` px of (`u`, `v`) on pyramid levels
    /// `levels` (inclusive).
    pub fn near(&self, u: f64, v: f64, radius: f64, levels: (u8, u8), out: &mut Vec<u32>) {
        out.clear();
        if self.cols == 0 {
            return;
        }
        let cmin = ((u - radius).max(0.0) / GRID as f64) as usize;
        let cmax = (((u + radius).max(0.0) / GRID as f64) as usize).min(self.cols - 1);
        let rmin = ((v - radius).max(0.0) / GRID as f64) as usize;
        let rmax = (((v + radius).max(0.0) / GRID as f64) as usize).min(self.rows - 1);
        let r2 = radius * radius;
        for r in rmin..=rmax {
            for c in cmin..=cmax {
                for &i in &self.grid[r * self.cols + c] {
                    let kp = &self.keypoints[i as usize];
                    if kp.level < levels.0 || kp.level > levels.1 {
                        continue;
                    }
                    let (du, dv) = (kp.u as f64 - u, kp.v as f64 - v);
                    if du * du + dv * dv <= r2 {
                        out.push(i);
                    }
                }
            }
        }
    }
}

/// How far from its corner a feature's descriptor looks, px at its pyramid level: the
/// binary tests' square of half-size 13 px, turned by up to 45°.
const DESCRIPTOR_REACH: f32 = 18.4;

/// Which optical-frame points are the robot's own body: those within the self radius of the
/// body frame's z axis. Built once per frame: the test runs on every depth pixel, so it keeps
/// only the two rows of `t_bc` it needs and compares squared distances (no square root, no
/// quaternion rotation per point).
#[derive(Debug, Clone, Copy)]
struct SelfTest {
    /// The body frame's x and y as affine functions of the optical-frame point.
    x: [f64; 4],
    y: [f64; 4],
    /// The self radius squared, m².
    r2: f64,
}

impl SelfTest {
    fn new(t_bc: &Isometry3<f64>, range: DepthUse) -> Self {
        let m = t_bc.to_homogeneous();
        let row = |i: usize| [m[(i, 0)], m[(i, 1)], m[(i, 2)], m[(i, 3)]];
        SelfTest {
            x: row(0),
            y: row(1),
            r2: range.self_radius * range.self_radius,
        }
    }

    /// Whether the optical-frame point `p` is the body's.
    fn contains(&self, p: &Point3<f64>) -> bool {
        let at = |a: &[f64; 4]| a[0] * p.x + a[1] * p.y + a[2] * p.z + a[3];
        let (x, y) = (at(&self.x), at(&self.y));
        x * x + y * y < self.r2
    }
}

/// The pixels of a depth image that are the robot's own body, counted in a summed-area table
/// so that any square's count is four look-ups.
struct SelfMask {
    /// Counts of body pixels above and left of each corner, `(w + 1) × (h + 1)`.
    sums: Vec<u32>,
    width: usize,
    height: usize,
}

impl SelfMask {
    fn new(depth: &DepthImage, k: &ferrobot_perception::Intrinsics, is_self: &SelfTest) -> Self {
        let (w, h) = (depth.width as usize, depth.height as usize);
        let mut sums = vec![0u32; (w + 1) * (h + 1)];
        if depth.data.len() != w * h {
            return SelfMask {
                sums,
                width: w,
                height: h,
            };
        }
        // The body frame's x (and y) of pixel (c, r) at depth z is z (a·u(c) + b·v(r) + d) + e
        // with u, v the pixel's ray ((c − cx) / fx, (r − cy) / fy): the column's part once per
        // image and the row's once per row, leaving a multiply-add per pixel that the
        // compiler vectorises (a ray per pixel, with its two divisions, was SLAM's costliest
        // step after feature extraction).
        let (sx, sy) = (&is_self.x, &is_self.y);
        let (ax, ay): (Vec<f64>, Vec<f64>) = (0..w)
            .map(|c| {
                let u = (c as f64 - k.cx) / k.fx;
                (sx[0] * u, sy[0] * u)
            })
            .unzip();
        let mut on_body = vec![0u32; w];
        for (r, zs) in depth.data.chunks_exact(w).enumerate() {
            let v = (r as f64 - k.cy) / k.fy;
            let (bx, by) = (sx[1] * v + sx[2], sy[1] * v + sy[2]);
            for (((on, &z), &ax), &ay) in on_body.iter_mut().zip(zs).zip(&ax).zip(&ay) {
                let valid = z.is_finite() & (z > 0.0);
                let z = z as f64;
                let (x, y) = (z * (ax + bx) + sx[3], z * (ay + by) + sy[3]);
                *on = (valid & (x * x + y * y < is_self.r2)) as u32;
            }
            // Counts below w · h < 2³²: wrapping adds that never wrap (and no overflow check
            // per pixel in the test profile).
            let (done, next) = sums.split_at_mut((r + 1) * (w + 1));
            let above = &done[r * (w + 1) + 1..];
            let mut row = 0u32;
            for ((s, &a), &on) in next[1..w + 1].iter_mut().zip(above).zip(&on_body) {
                row = row.wrapping_add(on);
                *s = a.wrapping_add(row);
            }
        }
        SelfMask {
            sums,
            width: w,
            height: h,
        }
    }

    /// Whether any body pixel lies within `reach` px (the square) of pixel (`col`, `row`).
    fn any_within(&self, col: i64, row: i64, reach: i64) -> bool {
        let clamp = |x: i64, n: usize| x.clamp(0, n as i64) as usize;
        let (c0, c1) = (
            clamp(col - reach, self.width),
            clamp(col + reach + 1, self.width),
        );
        let (r0, r1) = (
            clamp(row - reach, self.height),
            clamp(row + reach + 1, self.height),
        );
        let at = |r: usize, c: usize| self.sums[r * (self.width + 1) + c] as i64;
        at(r1, c1) - at(r0, c1) - at(r1, c0) + at(r0, c0) > 0
    }
}

/// The depth at pixel (`col`, `row`), m, when valid (finite and positive).
pub(crate) fn depth_at(depth: &DepthImage, col: usize, row: usize) -> Option<f64> {
    if col >= depth.width as usize || row >= depth.height as usize {
        return None;
    }
    let z = depth.data[row * depth.width as usize + col];
    (z.is_finite() && z > 0.0).then_some(z as f64)
}

/// Every `stride`-th pixel's point (optical frame, m) and colour, where the depth is in
/// `range` and off the robot's body.
pub(crate) fn sample_cloud(
    rgb: &RgbImage,
    depth: &DepthImage,
    k: &ferrobot_perception::Intrinsics,
    t_bc: &Isometry3<f64>,
    range: DepthUse,
    stride: usize,
) -> Vec<(Point3<f32>, [u8; 3])> {
    let (w, h) = (depth.width as usize, depth.height as usize);
    let is_self = SelfTest::new(t_bc, range);
    let mut out = Vec::with_capacity((w / stride) * (h / stride));
    for r in (stride / 2..h).step_by(stride) {
        for c in (stride / 2..w).step_by(stride) {
            let Some(z) = depth_at(depth, c, r) else {
                continue;
            };
            if !(range.min..=range.max).contains(&z) {
                continue;
            }
            let p = k.unproject(r as f64, c as f64, z);
            if range.self_radius > 0.0 && is_self.contains(&p) {
                continue;
            }
            let i = 3 * (r * w + c);
            let col = if rgb.data.len() >= i + 3 {
                [rgb.data[i], rgb.data[i + 1], rgb.data[i + 2]]
            } else {
                [0; 3]
            };
            out.push((Point3::new(p.x as f32, p.y as f32, p.z as f32), col));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::orb::OrbSettings;
    use ferrobot_perception::Intrinsics;

    #[test]
    fn the_body_mask_is_the_self_test_of_every_pixel() {
        // Depths from 0.2 to 3 m with invalid pixels (0, NaN, infinity), a camera tilted down
        // and turned on a body whose axis passes through the view: the mask's count of every
        // pixel is the self test of its point.
        let (w, h) = (97u32, 64u32);
        let k = Intrinsics::new(w, h, 80.0, 82.0, 47.3, 30.9).expect("k");
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let data: Vec<f32> = (0..w * h)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                match state % 23 {
                    0 => 0.0,
                    1 => f32::NAN,
                    2 => f32::INFINITY,
                    _ => 0.2 + (state >> 40) as f32 / (1u64 << 24) as f32 * 2.8,
                }
            })
            .collect();
        let depth = DepthImage {
            width: w,
            height: h,
            data,
        };
        let look = nalgebra::UnitQuaternion::from_euler_angles(-1.9, 0.1, -1.4);
        let t_bc = Isometry3::from_parts(nalgebra::Translation3::new(0.3, -0.1, 0.9), look);
        let range = DepthUse {
            min: 0.1,
            max: 5.0,
            self_radius: 1.2,
        };
        let test = SelfTest::new(&t_bc, range);
        let mask = SelfMask::new(&depth, &k, &test);
        let mut on = 0;
        for r in 0..h as usize {
            for c in 0..w as usize {
                let want = depth_at(&depth, c, r)
                    .is_some_and(|z| test.contains(&k.unproject(r as f64, c as f64, z)));
                let got = mask.any_within(c as i64, r as i64, 0);
                assert_eq!(got, want, "pixel ({c}, {r})");
                on += want as usize;
            }
        }
        let n = (w * h) as usize;
        assert!(
            on > n / 5 && on < 4 * n / 5,
            "{on} of {n} pixels on the body"
        );
    }

    #[test]
    fn no_feature_has_the_robots_body_in_its_patch() {
        // A checkered wall 2 m ahead; the body is what lies within 0.3 m of the optical axis
        // (the camera is the body here), a disc of 93 px radius in the middle of the image.
        let (w, h) = (320u32, 240u32);
        let k = Intrinsics::new(w, h, 620.0, 620.0, 160.0, 120.0).expect("k");
        let rgb: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let (c, r) = (i % w, i / w);
                let v = if (c / 12 + r / 12) % 2 == 0 { 40 } else { 210 };
                [v, v, v]
            })
            .collect();
        let rgb = RgbImage::new(w, h, rgb).expect("rgb");
        let depth = DepthImage::new(w, h, vec![2.0; (w * h) as usize]).expect("depth");
        let orb = OrbExtractor::new(OrbSettings::default());
        let range = |self_radius| DepthUse {
            min: 0.3,
            max: 4.0,
            self_radius,
        };
        let t_bc = Isometry3::identity();
        let all = FrameFeatures::new(&orb, &rgb, &depth, &k, &t_bc, range(0.0));
        let off = FrameFeatures::new(&orb, &rgb, &depth, &k, &t_bc, range(0.3));
        let body_px = 0.3 / 2.0 * 620.0;
        let near = |f: &FrameFeatures, margin: f64| {
            f.keypoints
                .iter()
                .filter(|kp| {
                    let reach = margin * orb.level_scale(kp.level) as f64;
                    (kp.u as f64 - 160.0).hypot(kp.v as f64 - 120.0) < body_px + reach
                })
                .count()
        };
        // Corners on the body and beside it are found without the mask ...
        assert!(near(&all, 0.0) > 10, "{}", near(&all, 0.0));
        assert!(near(&all, 18.0) > near(&all, 0.0));
        // ... and with it none has a body pixel within its patch, while the rest stay.
        assert_eq!(near(&off, 18.0), 0);
        assert!(off.len() > 10 && off.len() < all.len(), "{}", off.len());
    }
}
