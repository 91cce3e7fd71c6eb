//! Per-object features of a cloud's points: count, centroid, axis-aligned extent, and the
//! principal axis (the direction of largest spread). In the cloud's frame, m.

use nalgebra::{Matrix3, Point3, SymmetricEigen, Unit, Vector3};

use crate::cloud::check_points;
use crate::error::{PerceptionError, Result};

/// What an object's points say about it, in the cloud's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectFeatures {
    /// Number of points.
    pub count: usize,
    /// Mean of the points, m.
    pub centroid: Point3<f64>,
    /// Smallest x, y and z of the points (axis-aligned box's lower corner), m.
    pub min: Point3<f64>,
    /// Largest x, y and z of the points (axis-aligned box's upper corner), m.
    pub max: Point3<f64>,
    /// Unit eigenvector of the points' covariance with the largest eigenvalue (the direction
    /// of largest spread); its sign is chosen so that its largest component is positive.
    /// Arbitrary when the spread is the same in every direction (a single point, a sphere).
    pub principal_axis: Unit<Vector3<f64>>,
    /// Eigenvalues of the covariance (population, `1/n`), largest first, m².
    pub variances: Vector3<f64>,
}

impl ObjectFeatures {
    /// Size of the axis-aligned box holding the points, along x, y and z, m.
    pub fn extent(&self) -> Vector3<f64> {
        self.max - self.min
    }
}

/// The features of all of `points` (m). Errors: empty, non-finite or out-of-range points.
pub fn features(points: &[Point3<f64>]) -> Result<ObjectFeatures> {
    check_points(points)?;
    features_of(points.iter().copied(), points.len())
}

/// The features of the points of `points` at `indices` (one object of a clustering).
/// Errors: no indices, an index outside the cloud, non-finite or out-of-range points.
pub fn object_features(points: &[Point3<f64>], indices: &[usize]) -> Result<ObjectFeatures> {
    if let Some(&bad) = indices.iter().find(|&&i| i >= points.len()) {
        return Err(PerceptionError::Parameter {
            name: "point index",
            value: bad as f64,
            range: "an index into the cloud",
        });
    }
    let picked: Vec<Point3<f64>> = indices.iter().map(|&i| points[i]).collect();
    check_points(&picked)?;
    features_of(picked.iter().copied(), picked.len())
}

fn features_of(
    points: impl Iterator<Item = Point3<f64>> + Clone,
    n: usize,
) -> Result<ObjectFeatures> {
    if n == 0 {
        return Err(PerceptionError::EmptyCloud { what: "object" });
    }
    let (sum, min, max) = points.clone().fold(
        (
            Vector3::zeros(),
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(s, lo, hi), p| (s + p.coords, lo.inf(&p.coords), hi.sup(&p.coords)),
    );
    let centroid = sum / n as f64;
    let cov = points.fold(Matrix3::zeros(), |m, p| {
        let d = p.coords - centroid;
        m + d * d.transpose()
    }) / n as f64;
    let eig = SymmetricEigen::new(cov);
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let mut axis = eig.eigenvectors.column(order[0]).into_owned();
    let big = axis.iamax();
    if axis[big] < 0.0 {
        axis = -axis;
    }
    Ok(ObjectFeatures {
        count: n,
        centroid: Point3::from(centroid),
        min: Point3::from(min),
        max: Point3::from(max),
        principal_axis: Unit::try_new(axis, 1e-9).unwrap_or(Vector3::x_axis()),
        variances: Vector3::new(
            eig.eigenvalues[order[0]],
            eig.eigenvalues[order[1]],
            eig.eigenvalues[order[2]],
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{sample_solid, surface_centroid, Solid};

    #[test]
    fn an_elongated_box_gives_its_long_axis() {
        // A 20 x 4 x 3 cm box on a table, turned 0.6 rad: its surface's principal axis is its
        // long side, within 1 degree.
        for (seed, yaw) in [(1, 0.6), (2, -1.2), (3, 2.5)] {
            let b = Solid::Box {
                centre: Point3::new(0.5, -0.1, 0.115),
                size: Vector3::new(0.2, 0.04, 0.03),
                yaw,
            };
            let pts = sample_solid(seed, &b, 1.0e6);
            let f = features(&pts).unwrap();
            let long = Vector3::new(f64::cos(yaw), f64::sin(yaw), 0.0);
            let angle = f.principal_axis.dot(&long).abs().clamp(0.0, 1.0).acos();
            assert!(angle < 1f64.to_radians(), "yaw {yaw}: {angle} rad");
            assert!(f.principal_axis.iter().any(|&c| c > 0.5), "sign rule");
            assert!((f.centroid - surface_centroid(&b)).norm() < 0.002);
            // The extent of a box turned by yaw: |cos| L + |sin| W along x.
            let ex = 0.2 * yaw.cos().abs() + 0.04 * yaw.sin().abs();
            assert!(
                (f.extent().x - ex).abs() < 0.003,
                "{} vs {ex}",
                f.extent().x
            );
            assert!((f.extent().z - 0.03).abs() < 1e-3);
            assert!(f.variances[0] >= f.variances[1] && f.variances[1] >= f.variances[2]);
            assert_eq!(f.count, pts.len());
        }
    }

    #[test]
    fn one_point_and_bad_input() {
        let p = [Point3::new(1.0, 2.0, 3.0)];
        let f = features(&p).unwrap();
        assert_eq!(f.centroid, p[0]);
        assert_eq!(f.extent(), Vector3::zeros());
        assert!((f.principal_axis.norm() - 1.0).abs() < 1e-12);
        assert!(matches!(
            features(&[]),
            Err(PerceptionError::EmptyCloud { .. })
        ));
        assert!(matches!(
            object_features(&p, &[]),
            Err(PerceptionError::EmptyCloud { .. })
        ));
        assert!(matches!(
            object_features(&p, &[1]),
            Err(PerceptionError::Parameter { .. })
        ));
        assert!(matches!(
            features(&[Point3::new(f64::INFINITY, 0.0, 0.0)]),
            Err(PerceptionError::NonFinitePoint { .. })
        ));
    }
}
