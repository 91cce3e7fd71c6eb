//! Obstacle scans from a depth image: the points of PyRobot's occupancy band that a depth
//! camera sees, in the map's frame (m), minus the robot's own body, as a [`Scan`] for the live
//! obstacle layer.

use ferrobot_geometry::Pose2;
use ferrobot_perception::{DepthImage, Intrinsics};
use nalgebra::{Isometry3, Point3};

use crate::navigator::Scan;

/// Depth beyond this is not reported, m (a D435's error grows with the square of the range).
pub const SCAN_RANGE: f64 = 2.5;
/// Every this many rows and columns of the depth image are scanned.
pub const SCAN_STRIDE: usize = 4;
/// Heights above the floor that are obstacles, m (PyRobot's occupancy band).
pub const OBSTACLE_BAND: [f64; 2] = [0.1, 0.8];

/// A ball of the robot's own body in the base's frame: its centre (m) and radius (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ball {
    /// Centre, m.
    pub centre: Point3<f64>,
    /// Radius, m.
    pub radius: f64,
}

/// The obstacles a depth image shows, as a [`Scan`] in the map's frame: every
/// [`SCAN_STRIDE`]-th pixel with a depth up to [`SCAN_RANGE`], kept when it lies within
/// [`OBSTACLE_BAND`] above the floor and outside the robot's own body `body` (balls in the
/// base's frame). `camera` is the optical frame's pose in the map,
/// `base` the base's pose in it. The scan's near range is where the lowest rays of the image
/// reach down to the band: nearer, a low obstacle is out of view, so nothing there is cleared.
pub fn obstacle_scan(
    depth: &DepthImage,
    k: &Intrinsics,
    camera: &Isometry3<f64>,
    base: Pose2,
    body: &[Ball],
) -> Scan {
    let mut points = Vec::new();
    let w = depth.width as usize;
    let h = depth.height as usize;
    // Beyond this from the base's centre no point is the body's.
    let reach = body
        .iter()
        .map(|b| b.centre.x.hypot(b.centre.y) + b.radius)
        .fold(0.0, f64::max);
    let (sin, cos) = base.theta.sin_cos();
    for row in (0..h).step_by(SCAN_STRIDE) {
        for col in (0..w).step_by(SCAN_STRIDE) {
            let Some(z) = depth.get(row, col) else {
                continue;
            };
            let z = z as f64;
            if !(z > 0.0 && z <= SCAN_RANGE) {
                continue;
            }
            let p = camera * k.unproject(row as f64, col as f64, z);
            if !(OBSTACLE_BAND[0]..=OBSTACLE_BAND[1]).contains(&p.z) {
                continue;
            }
            let (dx, dy) = (p.x - base.x, p.y - base.y);
            if dx.hypot(dy) < reach {
                let q = Point3::new(cos * dx + sin * dy, cos * dy - sin * dx, p.z);
                if body.iter().any(|b| (q - b.centre).norm() < b.radius) {
                    continue;
                }
            }
            points.push([p.x, p.y]);
        }
    }
    // The optical axis (z) on the floor's plane gives the heading.
    let axis = camera * Point3::new(0.0, 0.0, 1.0) - camera * Point3::origin();
    let at = camera.translation.vector;
    Scan {
        sensor: [at.x, at.y, axis.y.atan2(axis.x)],
        half_fov: (0.5 * k.width as f64 / k.fx).atan(),
        near: blind_distance(camera, k).min(SCAN_RANGE),
        range: SCAN_RANGE,
        points,
    }
}

/// How far from the camera (m, along the floor) its image's lowest rays come down to the
/// bottom of [`OBSTACLE_BAND`]: nearer, an obstacle of the band's least height is out of view.
/// The lower corners are the farthest-reaching rays of the bottom row; a camera that looks
/// level or up never sees the band's bottom ahead ([`f64::INFINITY`]).
fn blind_distance(camera: &Isometry3<f64>, k: &Intrinsics) -> f64 {
    let above = camera.translation.z - OBSTACLE_BAND[0];
    if above <= 0.0 {
        return 0.0;
    }
    let row = f64::from(k.height) - 1.0;
    [0.0, f64::from(k.width) - 1.0]
        .into_iter()
        .map(|col| {
            let d = camera.rotation * k.unproject(row, col, 1.0).coords;
            if d.z >= 0.0 {
                f64::INFINITY
            } else {
                above / -d.z * d.x.hypot(d.y)
            }
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

    fn intrinsics() -> Intrinsics {
        Intrinsics {
            width: 64,
            height: 48,
            fx: 60.0,
            fy: 60.0,
            cx: 31.5,
            cy: 23.5,
        }
    }

    /// An optical frame at `at` (m, base frame) looking along the base's x, pitched down by
    /// `pitch` rad.
    fn camera(at: [f64; 3], pitch: f64) -> Isometry3<f64> {
        // Optical x right (-y), y down (-z), z ahead (x).
        let optical = Rotation3::from_matrix_unchecked(Matrix3::new(
            0.0, 0.0, 1.0, //
            -1.0, 0.0, 0.0, //
            0.0, -1.0, 0.0,
        ));
        let tilt = Rotation3::from_axis_angle(&Vector3::y_axis(), pitch);
        Isometry3::from_parts(
            Translation3::new(at[0], at[1], at[2]),
            UnitQuaternion::from_rotation_matrix(&(tilt * optical)),
        )
    }

    #[test]
    fn nearer_than_the_blind_distance_the_band_s_bottom_is_out_of_view() {
        let k = intrinsics();
        let cam = camera([0.1, 0.0, 0.6], 0.45);
        let d = blind_distance(&cam, &k);
        assert!(d > 0.2 && d < 1.0, "{d}");
        // Along the lower corners' bearing, a point at the band's bottom just beyond the
        // distance is above the image's bottom edge, just nearer it is below it.
        let corner = cam.rotation * k.unproject(47.0, 0.0, 1.0).coords;
        let bearing = corner.y.atan2(corner.x);
        let in_view = |r: f64| {
            let p = Point3::new(0.1 + r * bearing.cos(), r * bearing.sin(), OBSTACLE_BAND[0]);
            let (_, v) = k.project(&(cam.inverse() * p)).expect("ahead");
            v <= 47.0
        };
        assert!(in_view(d + 0.01), "beyond {d}");
        assert!(!in_view(d - 0.01), "before {d}");
        // Level, the band's bottom is never seen ahead; below it, nothing hides it.
        assert_eq!(
            blind_distance(&camera([0.0, 0.0, 0.6], -0.5), &k),
            f64::INFINITY
        );
        assert_eq!(blind_distance(&camera([0.0, 0.0, 0.05], 0.3), &k), 0.0);
    }

    #[test]
    fn the_robot_s_own_body_is_left_out_of_a_scan_and_what_lies_beyond_is_kept() {
        let k = intrinsics();
        // A level camera 0.4 m up, a wall 1 m ahead, and in front of the image's centre a
        // link (a 0.05 m sphere 0.4 m ahead) whose pixels read its depth.
        let cam = camera([0.0, 0.0, 0.4], 0.0);
        let link = Ball {
            centre: Point3::new(0.4, 0.0, 0.4),
            radius: 0.05,
        };
        let mut data = vec![1.0f32; 64 * 48];
        for row in 0..48 {
            for col in 0..64 {
                let ray = k.unproject(row as f64, col as f64, 1.0);
                if ray.x.hypot(ray.y) < 0.1 {
                    data[row * 64 + col] = 0.4;
                }
            }
        }
        let depth = DepthImage::new(64, 48, data).expect("depth");
        let placed = Ball {
            radius: link.radius + 0.03,
            ..link
        };
        // The base at (2, 1) turned a quarter: the scan is in the map's frame.
        let base = Pose2::new(2.0, 1.0, std::f64::consts::FRAC_PI_2);
        let in_map = optimise_planar(base) * cam;
        let masked = obstacle_scan(&depth, &k, &in_map, base, &[placed]);
        let blind = obstacle_scan(&depth, &k, &in_map, base, &[]);
        let near = |s: &Scan| {
            s.points
                .iter()
                .filter(|p| (p[0] - 2.0).hypot(p[1] - 1.4) < 0.02)
                .count()
        };
        assert!(
            near(&blind) > 0,
            "the link's pixels are points without the mask"
        );
        assert_eq!(near(&masked), 0, "the link is the robot's own");
        // The wall's points (1 m ahead, +y in the map) are kept either way.
        let wall = |s: &Scan| {
            s.points
                .iter()
                .filter(|p| (p[1] - 2.0).abs() < 0.02)
                .count()
        };
        assert!(wall(&masked) > 0);
        assert_eq!(wall(&masked), wall(&blind));
        assert!((masked.sensor[2] - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    }

    fn optimise_planar(p: Pose2) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(p.x, p.y, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), p.theta),
        )
    }
}
