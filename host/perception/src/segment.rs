//! Object segmentation on a table: the points in a height band above the table's plane
//! (optionally only over the table: inside the convex hull of the plane's inliers), clustered
//! into objects, each with its features. PyRobot's pushing example does the same with a
//! fixed height (`z > 0.01` in `base_link`) and scikit-learn's DBSCAN (eps 0.02, 15 samples).
//!
//! Heights are signed distances along the plane's normal, so the plane must have been fitted
//! with `up` given (see [`RansacParams::up`](crate::plane::RansacParams::up)), or flipped to
//! point up.

use nalgebra::{Point3, Vector3};

use crate::cloud::check_points;
use crate::cluster::Clusterer;
use crate::error::{PerceptionError, Result};
use crate::features::{object_features, ObjectFeatures};
use crate::plane::{Plane, PlaneFit};

/// Tallest band above the table accepted, m.
pub const MAX_HEIGHT: f64 = 10.0;

/// Largest margin around the table's hull accepted, m.
pub const MAX_MARGIN: f64 = 1.0;

/// Which points above the table are objects' points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentParams {
    /// Points at most this high above the plane are left out (the table's own points and its
    /// noise), m: finite, `0 <= min_height < max_height`.
    pub min_height: f64,
    /// Points higher than this above the plane are left out (an arm, a shelf above), m:
    /// at most [`MAX_HEIGHT`].
    pub max_height: f64,
    /// Keep only points over the table: whose foot on the plane lies inside the convex hull
    /// of the plane's inliers (the table top as the camera saw it) grown by `margin`.
    pub over_table: bool,
    /// Growth of the table's hull with `over_table`, m: in [0, [`MAX_MARGIN`]].
    pub margin: f64,
}

impl Default for SegmentParams {
    /// PyRobot's pushing example's 1 cm above the table, up to 0.5 m, over the table only.
    fn default() -> Self {
        SegmentParams {
            min_height: 0.01,
            max_height: 0.5,
            over_table: true,
            margin: 0.0,
        }
    }
}

impl SegmentParams {
    /// Checks the ranges (see each field).
    pub fn check(&self) -> Result<()> {
        let bad = |name, value, range| Err(PerceptionError::Parameter { name, value, range });
        if !(self.min_height.is_finite() && self.min_height >= 0.0) {
            return bad("min_height", self.min_height, "a finite height >= 0 m");
        }
        if !(self.max_height.is_finite()
            && self.max_height > self.min_height
            && self.max_height <= MAX_HEIGHT)
        {
            return bad(
                "max_height",
                self.max_height,
                "a finite height above min_height, at most 10 m",
            );
        }
        if !(self.margin.is_finite() && (0.0..=MAX_MARGIN).contains(&self.margin)) {
            return bad("margin", self.margin, "a finite distance in [0, 1] m");
        }
        Ok(())
    }
}

/// The table top as a region of its plane: the convex hull of the plane's inliers, in 2-D
/// coordinates `(u, v)` of the plane (m).
#[derive(Debug, Clone, PartialEq)]
pub struct TableRegion {
    /// The plane.
    pub plane: Plane,
    /// A point of the plane: the origin of the 2-D coordinates, m.
    pub origin: Point3<f64>,
    /// First in-plane unit axis.
    pub u: Vector3<f64>,
    /// Second in-plane unit axis (`normal x u`).
    pub v: Vector3<f64>,
    /// Hull vertices `(u, v)`, m, counter-clockwise about the normal, no three collinear.
    pub hull: Vec<[f64; 2]>,
}

impl TableRegion {
    /// The convex hull of `fit`'s inliers among `points`. Errors: inlier indices outside the
    /// cloud, or inliers that span no area (fewer than 3 hull vertices).
    pub fn new(points: &[Point3<f64>], fit: &PlaneFit) -> Result<TableRegion> {
        let n = fit.plane.normal.into_inner();
        let u = if n.x.abs() < 0.9 {
            n.cross(&Vector3::x())
        } else {
            n.cross(&Vector3::y())
        }
        .normalize();
        let v = n.cross(&u);
        let origin = Point3::from(n * fit.plane.offset);
        let mut flat = Vec::with_capacity(fit.inliers.len());
        for &i in &fit.inliers {
            let p = points.get(i).ok_or(PerceptionError::Parameter {
                name: "inlier index",
                value: i as f64,
                range: "an index into the cloud",
            })?;
            let d = p - origin;
            flat.push([d.dot(&u), d.dot(&v)]);
        }
        let hull = convex_hull(flat);
        if hull.len() < 3 {
            return Err(PerceptionError::TooFewPoints {
                what: "the table's region (the convex hull of the plane's inliers)",
                need: 3,
                got: hull.len(),
            });
        }
        Ok(TableRegion {
            plane: fit.plane,
            origin,
            u,
            v,
            hull,
        })
    }

    /// Whether the foot of `p` on the plane lies inside the hull grown by `margin` (m): on
    /// the inner side of every edge's line, or within `margin` of it.
    pub fn contains(&self, p: &Point3<f64>, margin: f64) -> bool {
        let d = p - self.origin;
        let q = [d.dot(&self.u), d.dot(&self.v)];
        let k = self.hull.len();
        (0..k).all(|i| {
            let (a, b) = (self.hull[i], self.hull[(i + 1) % k]);
            let e = [b[0] - a[0], b[1] - a[1]];
            let cross = e[0] * (q[1] - a[1]) - e[1] * (q[0] - a[0]);
            cross >= -margin * (e[0] * e[0] + e[1] * e[1]).sqrt()
        })
    }
}

/// Andrew's monotone chain: the hull counter-clockwise, without collinear vertices.
fn convex_hull(mut pts: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop(); // the last point starts the other chain
    }
    hull
}

/// The indices (ascending) of the points of `points` (m) that are objects' points above the
/// table `fit` (found in the same cloud): higher than `min_height` and at most `max_height`
/// above its plane and, with `over_table`, over the table's region. Errors: bad parameters,
/// non-finite or out-of-range points, inliers that are not the cloud's.
pub fn above_table(
    points: &[Point3<f64>],
    fit: &PlaneFit,
    params: &SegmentParams,
) -> Result<Vec<usize>> {
    params.check()?;
    check_points(points)?;
    let region = if params.over_table {
        Some(TableRegion::new(points, fit)?)
    } else {
        None
    };
    Ok((0..points.len())
        .filter(|&i| {
            let p = &points[i];
            let h = fit.plane.signed_distance(p);
            h > params.min_height
                && h <= params.max_height
                && region.as_ref().is_none_or(|r| r.contains(p, params.margin))
        })
        .collect())
}

/// One object found on the table.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentedObject {
    /// Indices of its points in the cloud, ascending.
    pub indices: Vec<usize>,
    /// Its features, in the cloud's frame.
    pub features: ObjectFeatures,
}

/// The objects on the table `fit`: the points [`above_table`] clustered by `clusterer`
/// (noise dropped), in the order of the clusterer's labels. An empty table gives no
/// objects, not an error. Errors: those of [`above_table`] and of the clusterer.
pub fn segment_objects(
    points: &[Point3<f64>],
    fit: &PlaneFit,
    params: &SegmentParams,
    clusterer: &dyn Clusterer,
) -> Result<Vec<SegmentedObject>> {
    let above = above_table(points, fit, params)?;
    if above.is_empty() {
        return Ok(Vec::new());
    }
    let selected: Vec<Point3<f64>> = above.iter().map(|&i| points[i]).collect();
    let clustering = clusterer.cluster(&selected)?;
    clustering
        .members()
        .into_iter()
        .map(|m| {
            let indices: Vec<usize> = m.iter().map(|&k| above[k]).collect();
            let features = object_features(points, &indices)?;
            Ok(SegmentedObject { indices, features })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::Dbscan;
    use crate::plane::{fit_plane, RansacParams};
    use crate::synthetic::{sample_rectangle, sample_solid, surface_centroid, Solid};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A 0.6 x 1.0 m table top at 0.1 m, five boxes on it (their footprints cut out of the
    /// table's points), points on all their faces but the bottom, 1 mm noise on the table,
    /// 300 stray points and a floor patch beside the table.
    fn scene(seed: u64) -> (Vec<Point3<f64>>, Vec<Solid>) {
        let h = 0.1;
        let boxes: Vec<Solid> = [
            ([0.50, -0.30], [0.06, 0.04, 0.05], 0.3),
            ([0.55, 0.00], [0.03, 0.03, 0.08], 0.0),
            ([0.75, 0.25], [0.08, 0.05, 0.03], 1.0),
            ([0.80, -0.15], [0.05, 0.05, 0.05], 2.0),
            ([0.60, 0.35], [0.04, 0.07, 0.06], -0.5),
        ]
        .iter()
        .map(|&(c, s, yaw)| Solid::Box {
            centre: Point3::new(c[0], c[1], h + s[2] / 2.0),
            size: Vector3::new(s[0], s[1], s[2]),
            yaw,
        })
        .collect();
        let mut pts = sample_rectangle(
            seed,
            Point3::new(0.65, 0.0, h),
            Vector3::x(),
            Vector3::y(),
            [0.6, 1.0],
            40_000.0,
            0.001,
            &boxes,
            0.0,
        );
        for (k, b) in boxes.iter().enumerate() {
            pts.extend(sample_solid(seed * 10 + k as u64, b, 400_000.0));
        }
        // The floor beside the table, seen past its edge: below the plane, left out.
        pts.extend(sample_rectangle(
            seed + 1,
            Point3::new(0.65, 0.8, 0.0),
            Vector3::x(),
            Vector3::y(),
            [0.6, 0.4],
            10_000.0,
            0.001,
            &[],
            0.0,
        ));
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 2);
        for _ in 0..300 {
            pts.push(Point3::new(
                rng.random_range(0.3..1.0),
                rng.random_range(-0.6..0.6),
                rng.random_range(0.0..0.5),
            ));
        }
        (pts, boxes)
    }

    #[test]
    fn boxes_on_a_table_are_found_with_their_centroids() {
        for seed in [1, 2, 3] {
            let (pts, boxes) = scene(seed);
            let fit = fit_plane(
                &pts,
                &RansacParams {
                    threshold: 0.005,
                    seed,
                    ..Default::default()
                },
            )
            .unwrap();
            assert!((fit.plane.offset - 0.1).abs() < 5e-4, "{:?}", fit.plane);
            let objects = segment_objects(
                &pts,
                &fit,
                &SegmentParams::default(),
                &Dbscan::new(0.02, 15).unwrap(),
            )
            .unwrap();
            assert_eq!(objects.len(), boxes.len(), "seed {seed}");
            for b in &boxes {
                // The object nearest the box; its centroid within 2 mm of the mean of the
                // box's faces (the band leaves out the bottom centimetre of each side, so
                // the expectation is that of the faces above it).
                let want = band_centroid(b, 0.01);
                let o = objects
                    .iter()
                    .min_by(|x, y| {
                        let dx = (x.features.centroid - want).norm();
                        let dy = (y.features.centroid - want).norm();
                        dx.total_cmp(&dy)
                    })
                    .unwrap();
                let err = (o.features.centroid - want).norm();
                assert!(err < 0.002, "seed {seed}: {b:?} off by {err} m");
            }
        }
    }

    /// The centroid of a box's surface (bottom face left out) above height `cut` over its
    /// base: the top face and the sides' parts above the cut.
    fn band_centroid(b: &Solid, cut: f64) -> Point3<f64> {
        let Solid::Box { centre, size, .. } = *b else {
            unreachable!()
        };
        let cut_box = Solid::Box {
            centre: centre + Vector3::new(0.0, 0.0, cut / 2.0),
            size: size - Vector3::new(0.0, 0.0, cut),
            yaw: 0.0,
        };
        surface_centroid(&cut_box)
    }

    #[test]
    fn the_table_region_leaves_out_what_is_beside_the_table() {
        let (mut pts, _) = scene(4);
        // Something hanging beside the table (not over it), from 0.15 to 0.45 m: an arm.
        let post = Solid::Box {
            centre: Point3::new(1.2, 0.0, 0.3),
            size: Vector3::new(0.05, 0.05, 0.3),
            yaw: 0.0,
        };
        let first_post = pts.len();
        pts.extend(sample_solid(9, &post, 400_000.0));
        let fit = fit_plane(
            &pts,
            &RansacParams {
                threshold: 0.005,
                ..Default::default()
            },
        )
        .unwrap();
        let over = above_table(&pts, &fit, &SegmentParams::default()).unwrap();
        assert!(over.iter().all(|&i| i < first_post));
        let anywhere = above_table(
            &pts,
            &fit,
            &SegmentParams {
                over_table: false,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(anywhere.iter().any(|&i| i >= first_post));
        let region = TableRegion::new(&pts, &fit).unwrap();
        assert!(region.contains(&Point3::new(0.65, 0.0, 0.3), 0.0));
        assert!(!region.contains(&Point3::new(1.2, 0.0, 0.3), 0.0));
        assert!(region.contains(&Point3::new(0.96, 0.0, 0.3), 0.02));
    }

    #[test]
    fn bad_parameters_are_typed_errors() {
        let (pts, _) = scene(5);
        let fit = fit_plane(&pts, &RansacParams::default()).unwrap();
        let d = Dbscan::new(0.02, 15).unwrap();
        for p in [
            SegmentParams {
                min_height: -0.1,
                ..Default::default()
            },
            SegmentParams {
                min_height: f64::NAN,
                ..Default::default()
            },
            SegmentParams {
                max_height: 0.0,
                ..Default::default()
            },
            SegmentParams {
                max_height: f64::INFINITY,
                ..Default::default()
            },
            SegmentParams {
                max_height: 11.0,
                ..Default::default()
            },
            SegmentParams {
                margin: -0.1,
                ..Default::default()
            },
            SegmentParams {
                margin: f64::NAN,
                ..Default::default()
            },
        ] {
            assert!(
                matches!(
                    segment_objects(&pts, &fit, &p, &d),
                    Err(PerceptionError::Parameter { .. })
                ),
                "{p:?}"
            );
        }
        // Nothing above the table: no objects.
        let table_only: Vec<_> = fit.inliers.iter().map(|&i| pts[i]).collect();
        let fit2 = fit_plane(&table_only, &RansacParams::default()).unwrap();
        let none = segment_objects(&table_only, &fit2, &SegmentParams::default(), &d).unwrap();
        assert!(none.is_empty());
        // A fit from another cloud: its inliers are not this cloud's.
        let tiny = &pts[..10];
        assert!(matches!(
            above_table(tiny, &fit, &SegmentParams::default()),
            Err(PerceptionError::Parameter { .. })
        ));
    }
}
