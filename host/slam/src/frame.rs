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
    /// neighbourhood within 5 % of the centre), in range and off the robot's body.
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
            if range.self_radius > 0.0 {
                let pb = t_bc * p;
                if pb.x.hypot(pb.y) < range.self_radius {
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
            if range.self_radius > 0.0 {
                let pb = t_bc * p;
                if pb.x.hypot(pb.y) < range.self_radius {
                    continue;
                }
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
