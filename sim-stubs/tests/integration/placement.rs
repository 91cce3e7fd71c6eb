//! Placing bodies (`ferrobot_sim::placement`): scattered apart inside a region or on a
//! support, the same for a seed; bad requests are typed errors.

use ferrobot_sim::placement::{footprint, scatter, scatter_on, Region, RESTING};
use ferrobot_sim::scene::{Scene, SceneError};
use nalgebra::{Isometry3, Vector3};

const TABLE: Region = Region {
    x: [0.3, 0.55],
    y: [-0.3, 0.3],
    within: Some([0.0, 0.0, 0.5]),
};

#[test]
fn bodies_land_apart_inside_the_region_resting_as_before() {
    let scene = Scene::bundled("tabletop").unwrap();
    let ids = [
        "red_cube",
        "green_cylinder",
        "yellow_capsule",
        "orange_block",
    ];
    for seed in 1..20 {
        let s = scatter(&scene, &ids, TABLE, seed, 0.03).unwrap();
        let moved: Vec<_> = s
            .bodies
            .iter()
            .filter(|b| ids.contains(&b.id.as_str()))
            .collect();
        for (k, b) in moved.iter().enumerate() {
            let old = scene.body(&b.id).unwrap();
            let (lo, hi) = b.world_bounds();
            assert!(
                lo.x >= 0.3 - 1e-9 && hi.x <= 0.55 + 1e-9,
                "{} {lo} {hi}",
                b.id
            );
            assert!(lo.y >= -0.3 - 1e-9 && hi.y <= 0.3 + 1e-9);
            assert!(b.pose.translation.vector.xy().norm() <= 0.5);
            assert_eq!(b.pose.translation.z, old.pose.translation.z);
            // The tilt is kept: the body's z axis is as upright as before.
            let up = |p: &Isometry3<f64>| (p.rotation * Vector3::z()).z;
            assert!((up(&b.pose) - up(&old.pose)).abs() < 1e-9);
            for o in &moved[k + 1..] {
                let d = (b.pose.translation.vector - o.pose.translation.vector)
                    .xy()
                    .norm();
                assert!(d >= footprint(b) + footprint(o) + 0.03 - 1e-9);
            }
        }
        // The others stay.
        assert_eq!(s.body("mug"), scene.body("mug"));
    }
    // Another seed, other places.
    let a = scatter(&scene, &ids, TABLE, 1, 0.03).unwrap();
    let b = scatter(&scene, &ids, TABLE, 2, 0.03).unwrap();
    assert_ne!(a.body("red_cube"), b.body("red_cube"));
    assert_eq!(a, scatter(&scene, &ids, TABLE, 1, 0.03).unwrap());
}

#[test]
fn bad_requests_are_typed_errors() {
    let scene = Scene::bundled("tabletop").unwrap();
    let bad = |ids: &[&str], region: Region, gap: f64| {
        matches!(
            scatter(&scene, ids, region, 1, gap),
            Err(SceneError::Invalid { .. })
        )
    };
    assert!(bad(&["table"], TABLE, 0.0));
    assert!(bad(&["nothing"], TABLE, 0.0));
    assert!(bad(&[], TABLE, f64::NAN));
    assert!(bad(
        &[],
        Region {
            within: Some([0.0, 0.0, f64::NAN]),
            ..TABLE
        },
        0.0
    ));
    assert!(bad(
        &[],
        Region {
            x: [0.0, f64::INFINITY],
            y: [0.0, 1.0],
            within: None,
        },
        0.0
    ));
    // Ten bodies do not fit in a 10 cm square.
    assert!(bad(
        &[],
        Region {
            x: [0.3, 0.4],
            y: [0.0, 0.1],
            within: None,
        },
        0.01
    ));
}

// scatter_on

/// Every object of the tabletop lands on the table, apart from the others and inside the
/// edges by the gap, the same for a seed and different for another.
#[test]
fn the_tabletops_objects_are_scattered_apart_on_the_table() {
    let gap = 0.02;
    let mut a = Scene::bundled("tabletop").unwrap();
    let ids = scatter_on(&mut a, "table", 7, gap).unwrap();
    assert_eq!(ids.len(), 10, "{ids:?}");
    let original = Scene::bundled("tabletop").unwrap();
    let (lo, hi) = a.body("table").unwrap().world_bounds();
    let foot: Vec<([f64; 2], f64)> = ids
        .iter()
        .map(|id| {
            let (blo, bhi) = a.body(id).unwrap().world_bounds();
            assert!(
                blo.x >= lo.x + gap - 1e-9 && bhi.x <= hi.x - gap + 1e-9,
                "{id}"
            );
            assert!(
                blo.y >= lo.y + gap - 1e-9 && bhi.y <= hi.y - gap + 1e-9,
                "{id}"
            );
            assert!((blo.z - hi.z).abs() <= RESTING, "{id} rests at {}", blo.z);
            let c = a.body(id).unwrap().pose.translation.vector;
            // The footprint's circle, from the body's box before it was turned.
            let (olo, ohi) = original.body(id).unwrap().world_bounds();
            ([c.x, c.y], (ohi - olo).xy().norm() / 2.0)
        })
        .collect();
    for (i, (p, r)) in foot.iter().enumerate() {
        for (q, s) in &foot[i + 1..] {
            let d = (p[0] - q[0]).hypot(p[1] - q[1]);
            assert!(d + 1e-9 >= r + s + gap, "{d} m apart, radii {r} and {s}");
        }
    }
    let mut b = Scene::bundled("tabletop").unwrap();
    scatter_on(&mut b, "table", 7, gap).unwrap();
    assert_eq!(a, b);
    let mut c = Scene::bundled("tabletop").unwrap();
    scatter_on(&mut c, "table", 8, gap).unwrap();
    assert_ne!(a, c);
}

#[test]
fn a_missing_support_or_a_bad_gap_or_no_room_is_an_error() {
    let mut s = Scene::bundled("tabletop").unwrap();
    assert!(scatter_on(&mut s, "desk", 1, 0.02).is_err());
    assert!(scatter_on(&mut s, "red_cube", 1, 0.02).is_err());
    assert!(scatter_on(&mut s, "table", 1, f64::NAN).is_err());
    assert!(scatter_on(&mut s, "table", 1, -0.1).is_err());
    let e = scatter_on(&mut s, "table", 1, 0.3).unwrap_err();
    assert!(e.to_string().contains("table"), "{e}");
}
