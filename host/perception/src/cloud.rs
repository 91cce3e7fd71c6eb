//! Back-projection of depth pixels and point clouds.

use nalgebra::{Isometry3, Point3};

use crate::error::{PerceptionError, Result};
use crate::image::{DepthImage, RgbImage};
use crate::intrinsics::Intrinsics;

/// Farthest depth a range may keep, m (no depth camera sees further).
pub const MAX_DEPTH: f64 = 1000.0;

/// Largest coordinate (absolute, on each axis) of a point the algorithms accept, m: 1000 km
/// from the frame's origin is beyond any sensor, and keeps every squared distance between
/// two points finite.
pub const MAX_COORDINATE: f64 = 1.0e6;

/// Checks that every point is finite and within [`MAX_COORDINATE`] of the origin on each axis:
/// the first that is not is a typed error naming its index.
pub fn check_points(points: &[Point3<f64>]) -> Result<()> {
    for (index, p) in points.iter().enumerate() {
        let [x, y, z] = [p.x, p.y, p.z];
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            return Err(PerceptionError::NonFinitePoint { index, x, y, z });
        }
        if x.abs() > MAX_COORDINATE || y.abs() > MAX_COORDINATE || z.abs() > MAX_COORDINATE {
            return Err(PerceptionError::PointOutOfRange {
                index,
                x,
                y,
                z,
                limit: MAX_COORDINATE,
            });
        }
    }
    Ok(())
}

/// The depths a point cloud keeps: `min < z < max`, m (PyRobot's default is (0.2, 1.5)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthRange {
    /// Lower bound (exclusive), m.
    pub min: f64,
    /// Upper bound (exclusive), m.
    pub max: f64,
}

impl DepthRange {
    /// PyRobot's LoCoBot default, (0.2, 1.5) m.
    pub const PYROBOT: DepthRange = DepthRange { min: 0.2, max: 1.5 };

    /// A checked range: `0 <= min < max <= MAX_DEPTH`.
    pub fn new(min: f64, max: f64) -> Result<Self> {
        if !(min.is_finite() && max.is_finite() && min >= 0.0 && min < max && max <= MAX_DEPTH) {
            return Err(PerceptionError::DepthRange { min, max });
        }
        Ok(DepthRange { min, max })
    }

    /// Whether depth `z` (m) is kept.
    pub fn keeps(&self, z: f64) -> bool {
        z > self.min && z < self.max
    }
}

/// Points with colours, in one frame (named by whoever made it: the optical frame or
/// `base_link`), m.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PointCloud {
    /// Points, m.
    pub points: Vec<Point3<f64>>,
    /// Colour of each point (R, G, B), as many as points.
    pub colours: Vec<[u8; 3]>,
}

impl PointCloud {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The cloud with every point mapped by `t` (e.g. optical frame to `base_link`).
    pub fn transformed(&self, t: &Isometry3<f64>) -> PointCloud {
        PointCloud {
            points: self.points.iter().map(|p| t * p).collect(),
            colours: self.colours.clone(),
        }
    }

    /// Points as `[x, y, z]` rows (N x 3), m.
    pub fn xyz(&self) -> Vec<[f64; 3]> {
        self.points.iter().map(|p| [p.x, p.y, p.z]).collect()
    }

    /// Mean of the points, or `None` for an empty cloud.
    pub fn centroid(&self) -> Option<Point3<f64>> {
        if self.points.is_empty() {
            return None;
        }
        let s = self
            .points
            .iter()
            .fold(nalgebra::Vector3::zeros(), |a, p| a + p.coords);
        Some(Point3::from(s / self.points.len() as f64))
    }
}

/// The images' sizes agree with the intrinsics and with each other, and their buffers with
/// their sizes (their fields are public: an image need not come from its `new`).
fn check_sizes(k: &Intrinsics, depth: &DepthImage, rgb: Option<&RgbImage>) -> Result<()> {
    k.validate()?;
    depth.check()?;
    if let Some(c) = rgb {
        c.check()?;
    }
    if depth.width != k.width || depth.height != k.height {
        return Err(PerceptionError::Size(format!(
            "depth image {}x{} but intrinsics for {}x{}",
            depth.width, depth.height, k.width, k.height
        )));
    }
    if let Some(c) = rgb {
        if c.width != depth.width || c.height != depth.height {
            return Err(PerceptionError::Size(format!(
                "colour image {}x{} but depth image {}x{} (depth must be aligned to colour)",
                c.width, c.height, depth.width, depth.height
            )));
        }
    }
    Ok(())
}

/// The cloud of every pixel whose depth `range` keeps, in the optical frame: pixel (r, c) with
/// depth d gives d K^-1 [c, r, 1]. Colours come from `rgb` (aligned to depth), or grey.
pub fn backproject(
    k: &Intrinsics,
    depth: &DepthImage,
    rgb: Option<&RgbImage>,
    range: DepthRange,
) -> Result<PointCloud> {
    check_sizes(k, depth, rgb)?;
    let w = k.width as usize;
    let mut cloud = PointCloud::default();
    for (i, &d) in depth.data.iter().enumerate() {
        let z = d as f64;
        if !range.keeps(z) {
            continue;
        }
        let (r, c) = (i / w, i % w);
        cloud.points.push(k.unproject(r as f64, c as f64, z));
        cloud.colours.push(match rgb {
            Some(img) => [img.data[3 * i], img.data[3 * i + 1], img.data[3 * i + 2]],
            None => [128; 3],
        });
    }
    Ok(cloud)
}

/// The points seen at chosen pixels ([`pixels_to_points`]), in one frame, m.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PixelPoints {
    /// The point of each pixel; `None` where its depth is invalid (0).
    pub points: Vec<Option<Point3<f64>>>,
    /// The colour of each pixel (R, G, B).
    pub colours: Vec<[u8; 3]>,
}

impl PixelPoints {
    /// The points mapped by `t` (e.g. optical frame to `base_link`).
    pub fn transformed(&self, t: &Isometry3<f64>) -> PixelPoints {
        PixelPoints {
            points: self.points.iter().map(|p| p.map(|p| t * p)).collect(),
            colours: self.colours.clone(),
        }
    }
}

/// The 3-D points (optical frame, m) seen at the pixels (`rows[i]`, `cols[i]`), with their
/// colours: `None` where the depth is invalid (0). Every pixel must lie inside the image.
pub fn pixels_to_points(
    k: &Intrinsics,
    depth: &DepthImage,
    rgb: Option<&RgbImage>,
    rows: &[i64],
    cols: &[i64],
) -> Result<PixelPoints> {
    check_sizes(k, depth, rgb)?;
    if rows.len() != cols.len() {
        return Err(PerceptionError::PixelCount {
            rows: rows.len(),
            cols: cols.len(),
        });
    }
    let mut points = Vec::with_capacity(rows.len());
    let mut colours = Vec::with_capacity(rows.len());
    for (&r, &c) in rows.iter().zip(cols) {
        let i = k.index(r, c)?;
        let z = depth.data[i] as f64;
        points.push((z > 0.0).then(|| k.unproject(r as f64, c as f64, z)));
        colours.push(match rgb {
            Some(img) => [img.data[3 * i], img.data[3 * i + 1], img.data[3 * i + 2]],
            None => [128; 3],
        });
    }
    Ok(PixelPoints { points, colours })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k() -> Intrinsics {
        Intrinsics::new(8, 6, 10.0, 10.0, 4.0, 3.0).unwrap()
    }

    /// Images built without their `new` (the fields are public) whose buffers do not hold
    /// their sizes are size errors, not points of rows that do not exist or a panic.
    #[test]
    fn images_whose_buffers_lie_are_refused() {
        let depth = |n: usize| DepthImage {
            width: 8,
            height: 6,
            data: vec![1.0; n],
        };
        let rgb = |n: usize| RgbImage {
            width: 8,
            height: 6,
            data: vec![9; n],
        };
        let range = DepthRange::PYROBOT;
        for n in [0, 47, 49, 96] {
            let r = backproject(&k(), &depth(n), None, range);
            assert!(matches!(r, Err(PerceptionError::Size(_))), "{n}: {r:?}");
            let r = pixels_to_points(&k(), &depth(n), None, &[5], &[7]);
            assert!(matches!(r, Err(PerceptionError::Size(_))), "{n}: {r:?}");
        }
        for n in [0, 143, 145] {
            let r = backproject(&k(), &depth(48), Some(&rgb(n)), range);
            assert!(matches!(r, Err(PerceptionError::Size(_))), "{n}: {r:?}");
        }
        let cloud = backproject(&k(), &depth(48), Some(&rgb(144)), range).expect("good");
        assert_eq!(cloud.len(), 48);
    }

    #[test]
    fn a_flat_wall_backprojects_to_a_plane_and_the_filter_holds() {
        let mut d = vec![1.0f32; 48];
        d[0] = 0.1; // too near
        d[1] = 0.0; // invalid
        d[2] = 2.0; // too far
        let depth = DepthImage::new(8, 6, d).unwrap();
        let cloud = backproject(&k(), &depth, None, DepthRange::PYROBOT).unwrap();
        assert_eq!(cloud.len(), 45);
        assert!(cloud.points.iter().all(|p| (p.z - 1.0).abs() < 1e-12));
        // Pixel (3, 4) is the principal point: on the axis.
        let pts = pixels_to_points(&k(), &depth, None, &[3, 0], &[4, 1])
            .unwrap()
            .points;
        let p = pts[0].unwrap();
        assert!(p.x.abs() < 1e-12 && p.y.abs() < 1e-12);
        assert!(pts[1].is_none());
    }

    #[test]
    fn bad_pixels_and_ranges_are_errors() {
        let depth = DepthImage::new(8, 6, vec![1.0; 48]).unwrap();
        assert!(matches!(
            pixels_to_points(&k(), &depth, None, &[6], &[0]),
            Err(PerceptionError::PixelOutside { .. })
        ));
        assert!(matches!(
            pixels_to_points(&k(), &depth, None, &[1, 2], &[0]),
            Err(PerceptionError::PixelCount { .. })
        ));
        assert!(DepthRange::new(1.5, 0.2).is_err());
        assert!(DepthRange::new(f64::NAN, 1.0).is_err());
        let small = DepthImage::new(4, 6, vec![1.0; 24]).unwrap();
        assert!(backproject(&k(), &small, None, DepthRange::PYROBOT).is_err());
    }
}
