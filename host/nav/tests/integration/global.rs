//! The global planner on occupancy grids: near the exact shortest path around a wall, clear
//! of obstacles by its stated tolerance, typed errors for bad ends and no way through, and
//! no panic on hostile values.

use ferrobot_nav::{Error, GlobalPlanner, GridAStar, Obstacles, OccupancyGrid};
use proptest::prelude::*;

/// A 4 m × 4 m grid of 2 cm cells (centres 0.01 … 3.99 m) with a wall: the cells whose centres
/// have x ≤ `end` and |y − 2| ≤ 0.05, except x in `gap`.
fn walled(end: f64, gap: Option<(f64, f64)>) -> OccupancyGrid {
    let mut g = OccupancyGrid::new([0.01, 0.01], 0.02, 200, 200).expect("grid");
    for j in 0..g.height {
        for i in 0..g.width {
            let (x, y) = (0.01 + 0.02 * i as f64, 0.01 + 0.02 * j as f64);
            let in_gap = gap.is_some_and(|(a, b)| x > a && x < b);
            if x <= end && (y - 2.0).abs() <= 0.05 + 1e-9 && !in_gap {
                g.occupied[j * g.width + i] = true;
            }
        }
    }
    g
}

/// The smallest clearance along the path, sampled every millimetre.
fn min_clearance(map: &OccupancyGrid, points: &[[f64; 2]]) -> f64 {
    let field = Obstacles::new(Vec::new(), Some(map)).expect("field");
    let mut least = f64::INFINITY;
    for w in points.windows(2) {
        let len = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        let n = (len / 0.001).ceil().max(1.0) as usize;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let p = [
                w[0][0] + (w[1][0] - w[0][0]) * t,
                w[0][1] + (w[1][1] - w[0][1]) * t,
            ];
            least = least.min(field.clearance(p));
        }
    }
    least
}

/// Around the end of a wall, the path is within 1.5 cells of the exact shortest path of a
/// disc of the robot's radius (two tangents, two arcs around the wall's corners and the
/// wall's thickness between), and keeps the stated clearance. An 8-connected grid path
/// without pulling is about 8 % longer here, so the check needs the taut path.
#[test]
fn a_path_around_a_wall_is_near_the_exact_shortest() {
    let map = walled(2.0, None);
    let (start, goal, r) = ([1.0, 1.0], [1.0, 3.0], 0.2);
    let path = GridAStar.plan(&map, start, goal, r).expect("path");
    assert_eq!(path.points.first(), Some(&start));
    assert_eq!(path.points.last(), Some(&goal));
    // The wall's cells span x ∈ [0, 2.00], y ∈ [1.94, 2.06]; the corners the disc turns
    // around are (2.00, 1.94) and (2.00, 2.06).
    let c = [2.0, 1.94];
    let (dx, dy) = (start[0] - c[0], start[1] - c[1]);
    let d = dx.hypot(dy);
    let tangent = (d * d - r * r).sqrt();
    // The tangent point's angle around the corner, on the wall's open side (x > 2).
    let phi = dy.atan2(dx) + (r / d).acos();
    let arc = r * (0.0 - phi).abs();
    let exact = 2.0 * (tangent + arc) + 0.12;
    assert!(
        (path.length - exact).abs() <= 1.5 * map.resolution,
        "length {} m, exact {exact} m",
        path.length
    );
    let least = min_clearance(&map, &path.points);
    assert!(
        least >= r - 0.71 * map.resolution,
        "clearance {least} m, radius {r} m"
    );
}

/// A gap narrower than the robot: no path (a typed error that is not the input's fault); a
/// smaller robot goes through it.
#[test]
fn a_gap_narrower_than_the_robot_has_no_path() {
    let map = walled(4.0, Some((1.8, 2.2)));
    let e = GridAStar
        .plan(&map, [1.0, 1.0], [1.0, 3.0], 0.25)
        .expect_err("too wide");
    assert!(matches!(e, Error::NoPath { .. }) && !e.is_input(), "{e}");
    let path = GridAStar
        .plan(&map, [1.0, 1.0], [1.0, 3.0], 0.1)
        .expect("narrow enough");
    // It crosses the wall's line inside the gap.
    let crossing = path
        .points
        .windows(2)
        .find(|w| (w[0][1] - 2.0) * (w[1][1] - 2.0) <= 0.0)
        .expect("crosses y = 2");
    let t = (2.0 - crossing[0][1]) / (crossing[1][1] - crossing[0][1]);
    let x = crossing[0][0] + (crossing[1][0] - crossing[0][0]) * t;
    assert!((1.8..2.2).contains(&x), "crosses at x = {x}");
    assert!(min_clearance(&map, &path.points) >= 0.1 - 0.71 * map.resolution);
}

/// Bad ends and values: each its own typed error, all the input's fault.
#[test]
fn bad_ends_and_values_are_refused() {
    let map = walled(2.0, None);
    let plan = |s: [f64; 2], g: [f64; 2], r: f64| GridAStar.plan(&map, s, g, r).expect_err("bad");
    let e = plan([-1.0, 1.0], [1.0, 3.0], 0.2);
    assert!(matches!(e, Error::OutsideMap { what: "start", .. }), "{e}");
    let e = plan([1.0, 1.0], [1.0, 2.0], 0.2);
    assert!(matches!(e, Error::Blocked { what: "goal", .. }), "{e}");
    assert!(
        e.to_string()
            .contains("nearer than the robot's radius 0.2 m"),
        "{e}"
    );
    // 0.15 m from the wall's face: blocked for 0.2 m, fine for 0.1 m.
    let e = plan([1.0, 1.79], [1.0, 3.0], 0.2);
    assert!(matches!(e, Error::Blocked { what: "start", .. }), "{e}");
    assert!(GridAStar.plan(&map, [1.0, 1.79], [1.0, 3.0], 0.1).is_ok());
    for e in [
        plan([f64::NAN, 1.0], [1.0, 3.0], 0.2),
        plan([1.0, 1.0], [1.0, f64::INFINITY], 0.2),
        plan([1.0, 1.0], [1.0, 3.0], -0.1),
        plan([1.0, 1.0], [1.0, 3.0], 1e9),
        plan([1.0, 1.0], [1.0, 3.0], f64::NAN),
    ] {
        assert!(matches!(e, Error::Value(_)) && e.is_input(), "{e}");
    }
    let mut broken = map.clone();
    broken.occupied.pop();
    let e = GridAStar
        .plan(&broken, [1.0, 1.0], [1.0, 3.0], 0.2)
        .expect_err("short");
    assert!(matches!(e, Error::InvalidMap { .. }), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Hostile ends and radii on a small cluttered map: never a panic; a path, when there is
    /// one, runs from the start to the goal and keeps the stated clearance.
    #[test]
    fn hostile_values_never_panic(
        seed in any::<u64>(),
        s in prop::array::uniform2(prop_oneof![-1.0..3.0f64, Just(f64::NAN), Just(f64::INFINITY), Just(-1e300)]),
        g in prop::array::uniform2(prop_oneof![-1.0..3.0f64, Just(f64::NAN), Just(1e300)]),
        r in prop_oneof![0.0..0.3f64, Just(-1.0), Just(f64::NAN), Just(1e12), Just(0.0)],
    ) {
        let mut map = OccupancyGrid::new([0.025, 0.025], 0.05, 40, 40).expect("grid");
        let mut x = seed | 1;
        for o in map.occupied.iter_mut() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            *o = x % 9 == 0;
        }
        if let Ok(path) = GridAStar.plan(&map, s, g, r) {
            prop_assert_eq!(path.points.first(), Some(&s));
            prop_assert_eq!(path.points.last(), Some(&g));
            prop_assert!(path.length.is_finite());
            prop_assert!(min_clearance(&map, &path.points) >= r - 0.71 * map.resolution - 1e-9);
        }
    }
}

#[test]
fn a_grid_grows_with_free_cells_to_hold_far_points_and_keeps_its_own() {
    let mut g = OccupancyGrid::new([0.0, 0.0], 0.1, 5, 4).expect("grid");
    g.occupied[2 * 5 + 3] = true;
    let grown = g.grown_to(&[[-1.0, 0.2], [0.3, 2.0]], 0.5).expect("grown");
    // Aligned with the old cells: the occupied one is at the same place.
    assert!(grown.is_occupied(g.centre(3, 2)));
    assert_eq!(grown.occupied.iter().filter(|&&o| o).count(), 1);
    // Holds both points with the margin.
    for p in [[-1.5, 0.2], [0.3, 2.5], [-1.0, 0.2]] {
        assert!(grown.cell(p).is_some(), "{p:?}");
    }
    // Points already inside change nothing.
    assert_eq!(g.grown_to(&[[0.1, 0.1]], 0.0).expect("same"), g);
    // Far or non-finite points are refused.
    assert!(g.grown_to(&[[1e12, 0.0]], 0.0).is_err());
    assert!(g.grown_to(&[[f64::NAN, 0.0]], 0.0).is_err());
    assert!(g.grown_to(&[[1e5, 1e5]], 0.0).is_err());
}
