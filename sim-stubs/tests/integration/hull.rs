//! The collision hull of a movable mesh (`ferrobot_sim::hull`): a face of more than four
//! vertices meets other shapes at four spread over it.

use ferrobot_sim::hull::{Hull, SEARCH_MAX};
use rapier3d::parry::shape::{PolygonalFeature, PolygonalFeatureMap};
use rapier3d::prelude::{Real, Vector};

/// A regular `n`-gon of radius 1 in the plane z = `z`.
fn ring(n: usize, z: Real) -> Vec<Vector> {
    (0..n)
        .map(|i| {
            let a = i as Real * std::f32::consts::TAU / n as Real;
            Vector::new(a.cos(), a.sin(), z)
        })
        .collect()
}

#[test]
fn a_24_sided_prism_stands_on_a_square_spread_over_its_base() {
    let mut points = ring(24, 0.0);
    points.extend(ring(24, 1.0));
    let hull = Hull::new(&points).unwrap();
    let mut f = PolygonalFeature::default();
    hull.local_support_feature(Vector::new(0.0, 0.0, -1.0), &mut f);
    assert_eq!(f.num_vertices, 4);
    // The inscribed square: centred on the axis, area 2 (of the 24-gon's 3.1).
    let c: Vector = f.vertices.iter().copied().sum::<Vector>() / 4.0;
    assert!(c.length() < 1e-5, "support centred at {c:?}");
    let area = (f.vertices[0] - f.vertices[2])
        .cross(f.vertices[1] - f.vertices[3])
        .length()
        / 2.0;
    assert!((area - 2.0).abs() < 1e-4, "area {area}");
    for v in &f.vertices {
        assert!(v.z.abs() < 1e-6, "{v:?} not on the base");
    }
}

#[test]
fn a_large_face_gets_four_evenly_spaced_vertices() {
    // A 48-sided prism: its base has more vertices than the search takes, so four evenly
    // spaced ones of them (every twelfth) stand for it: a square inscribed in the base.
    let n = SEARCH_MAX + 8;
    let mut points = ring(n, 0.0);
    points.extend(ring(n, 1.0));
    let hull = Hull::new(&points).unwrap();
    let mut f = PolygonalFeature::default();
    hull.local_support_feature(Vector::new(0.0, 0.0, -1.0), &mut f);
    assert_eq!(f.num_vertices, 4);
    let step = std::f32::consts::TAU / n as Real;
    let angles: Vec<Real> = f.vertices.iter().map(|v| v.y.atan2(v.x)).collect();
    for (v, a) in f.vertices.iter().zip(&angles) {
        // A vertex of the base's ring.
        assert!(v.z.abs() < 1e-6 && (v.length() - 1.0).abs() < 1e-5, "{v:?}");
        let k = a / step;
        assert!((k - k.round()).abs() < 1e-3, "{v:?} is not a ring vertex");
    }
    // Around the base, a quarter turn (twelve vertices) apart.
    let mut sorted = angles.clone();
    sorted.sort_by(f32::total_cmp);
    for i in 0..4 {
        let d = (sorted[(i + 1) % 4] - sorted[i]).rem_euclid(std::f32::consts::TAU);
        let quarter = std::f32::consts::FRAC_PI_2;
        assert!((d - quarter).abs() < 1e-4, "{:?}", f.vertices);
    }
}
