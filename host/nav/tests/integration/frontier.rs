//! Frontiers on small maps whose answer is known: a room open to unknown space through a door,
//! a room fully seen, a frontier behind a wall, and failed places avoided.

use ferrobot_nav::{frontiers, Cell, FrontierSettings, MapImage};

/// A 4 m x 3 m map, 5 cm cells: a walled room x in [0, 2] fully seen free, unknown beyond
/// x = 2 except the wall, which has a 0.9 m door at y in [1.05, 1.95] when `door`.
fn room(door: bool) -> MapImage {
    let (w, h) = (80, 60);
    let r = 0.05;
    let mut cells = vec![Cell::Unknown; w * h];
    for j in 0..h {
        for i in 0..w {
            let (x, y) = ((i as f64 + 0.5) * r, (j as f64 + 0.5) * r);
            let wall = x < 0.1 || !(0.1..=2.9).contains(&y) || (x > 2.0 && x < 2.1);
            let opening = door && (x > 2.0 && x < 2.1) && (1.05..1.95).contains(&y);
            cells[j * w + i] = if wall && !opening {
                Cell::Occupied
            } else if x < 2.1 {
                Cell::Free
            } else {
                Cell::Unknown
            };
        }
    }
    MapImage {
        origin: [0.0, 0.0],
        resolution: r,
        width: w,
        height: h,
        cells,
    }
}

#[test]
fn a_door_to_unknown_space_is_the_frontier_and_its_view_point_is_reached() {
    let s = FrontierSettings::new(0.18);
    let f = frontiers(&room(true), [0.3, 0.5], &s).expect("frontiers");
    assert_eq!(f.len(), 1, "{f:?}");
    let f = &f[0];
    // The door's cells: x just inside 2.1, y over the opening.
    assert!((f.centroid[0] - 2.075).abs() < 0.05, "{f:?}");
    assert!((f.centroid[1] - 1.5).abs() < 0.05, "{f:?}");
    assert!(f.cells >= 15, "{f:?}");
    // The view point is 0.7-1.5 m from the door (the door's half width aside), reached, the
    // nearest such place to the robot, and faces the door.
    let d = (f.view_point[0] - f.centroid[0]).hypot(f.view_point[1] - f.centroid[1]);
    assert!((0.65..=1.5 + 0.45).contains(&d), "{f:?}");
    let direct = (f.view_point[0] - 0.3).hypot(f.view_point[1] - 0.5);
    assert!(f.distance >= direct - 1e-9 && f.distance < 1.2, "{f:?}");
    assert!(f.heading.abs() < 1.2, "{f:?}");
    // From nearer the door than the least view distance, the view point is back from it.
    let g = frontiers(&room(true), [1.8, 1.5], &s).expect("frontiers");
    let d = (g[0].view_point[0] - g[0].centroid[0]).hypot(g[0].view_point[1] - g[0].centroid[1]);
    assert!(d >= 0.65, "{g:?}");
}

#[test]
fn a_room_fully_seen_or_walled_off_has_no_frontier_to_reach() {
    let s = FrontierSettings::new(0.18);
    // Without the door: the unknown beyond the wall touches no free cell the robot reaches.
    assert!(frontiers(&room(false), [0.8, 1.5], &s)
        .expect("frontiers")
        .is_empty());
    // Everything known.
    let mut m = room(true);
    for c in &mut m.cells {
        if *c == Cell::Unknown {
            *c = Cell::Free;
        }
    }
    assert!(frontiers(&m, [0.8, 1.5], &s).expect("frontiers").is_empty());
    // A robot too big for the door reaches no view point of it beyond its own room, but it
    // sees the door from inside: still offered, from this side.
    let big = FrontierSettings::new(0.5);
    let f = frontiers(&room(true), [0.8, 1.5], &big).expect("frontiers");
    assert!(f.iter().all(|f| f.view_point[0] < 2.0), "{f:?}");
}

#[test]
fn failed_places_are_not_offered_again_and_bad_input_is_refused() {
    let mut s = FrontierSettings::new(0.18);
    let first = frontiers(&room(true), [0.8, 1.5], &s).expect("frontiers");
    s.failed = vec![first[0].view_point];
    s.avoid = 2.0;
    let again = frontiers(&room(true), [0.8, 1.5], &s).expect("frontiers");
    assert!(
        again.iter().all(|f| {
            (f.view_point[0] - first[0].view_point[0])
                .hypot(f.view_point[1] - first[0].view_point[1])
                >= 2.0
        }),
        "{again:?}"
    );
    let s = FrontierSettings::new(0.18);
    assert!(frontiers(&room(true), [f64::NAN, 1.0], &s).is_err());
    assert!(frontiers(&room(true), [50.0, 1.0], &s).is_err());
    let mut bad = room(true);
    bad.cells.truncate(3);
    assert!(frontiers(&bad, [0.8, 1.5], &s).is_err());
    let mut bad = FrontierSettings::new(0.18);
    bad.view = f64::INFINITY;
    assert!(frontiers(&room(true), [0.8, 1.5], &bad).is_err());
}

/// The room with its door, and beyond it a closet x in [2.1, 3.9] walled at x = 3.9, seen
/// but for its lower part: y below 0.8 unknown (behind the wall beside the door, seen from
/// the room).
fn room_and_closet() -> MapImage {
    let mut m = room(true);
    let r = m.resolution;
    for j in 0..m.height {
        for i in 0..m.width {
            let (x, y) = ((i as f64 + 0.5) * r, (j as f64 + 0.5) * r);
            let c = &mut m.cells[j * m.width + i];
            if x >= 3.9 && *c != Cell::Occupied {
                *c = Cell::Occupied;
            } else if x > 2.1 && (0.8..2.9).contains(&y) {
                *c = Cell::Free;
            }
        }
    }
    m
}

#[test]
fn a_frontier_round_the_door_s_corner_is_viewed_from_where_it_can_be_seen() {
    let s = FrontierSettings::new(0.18);
    let f = frontiers(&room_and_closet(), [0.5, 0.5], &s).expect("frontiers");
    // The closet's unseen lower part, round the corner of the wall beside the door.
    assert_eq!(f.len(), 1, "{f:?}");
    let corner = &f[0];
    assert!((corner.centroid[1] - 0.8).abs() < 0.06, "{corner:?}");
    let v = corner.view_point;
    // Seen from the closet, or through the door: where the line of sight crosses the wall
    // (x = 2.05) it is within the opening.
    let c = corner.centroid;
    let through_door = v[0] < 2.0 && {
        let t = (2.05 - v[0]) / (c[0] - v[0]);
        let y = v[1] + t * (c[1] - v[1]);
        (1.05..1.95).contains(&y)
    };
    assert!(v[0] > 2.1 || through_door, "{corner:?}");
}
