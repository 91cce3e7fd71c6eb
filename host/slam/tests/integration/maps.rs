//! The judges of explored maps: the part of a floor plan a robot can map, and the agreement of
//! a map with it.

use ferrobot_nav::{Cell, MapImage};
use ferrobot_slam::{map_iou, map_iou_seen, reachable_part};

/// A 20 x 12 cell room (0.1 m cells): outer walls one cell thick, a 4 x 3 cell bed at cells
/// 4..8 x 4..7, and beyond the right wall (x = 15) a closed 4-cell-wide strip.
fn plan() -> MapImage {
    let (w, h) = (20, 12);
    let mut occ = vec![false; w * h];
    for j in 0..h {
        for i in 0..w {
            let wall = i == 0 || j == 0 || j == h - 1 || i == 15 || i == w - 1;
            let bed = (4..8).contains(&i) && (4..7).contains(&j);
            occ[j * w + i] = wall || bed;
        }
    }
    MapImage::from_occupied([0.0, 0.0], 0.1, w, h, &occ)
}

fn set(m: &mut MapImage, i: usize, j: usize, c: Cell) {
    let w = m.width;
    m.cells[j * w + i] = c;
}

#[test]
fn the_reachable_part_keeps_the_floor_and_the_faces_round_it() {
    let plan = plan();
    let part = reachable_part(&plan, [0.25, 0.25]).expect("part");
    let at = |i: usize, j: usize| part.cells[j * part.width + i];
    // Floor of the room, the walls' and the bed's faces.
    assert_eq!(at(2, 2), Cell::Free);
    assert_eq!(at(0, 5), Cell::Occupied);
    assert_eq!(at(4, 4), Cell::Occupied);
    // The bed's inside and the closed strip beyond the wall are not the robot's to map.
    assert_eq!(at(5, 5), Cell::Unknown);
    assert_eq!(at(17, 5), Cell::Unknown);
    let free = part.cells.iter().filter(|&&c| c == Cell::Free).count();
    // 14 x 10 floor cells less the 12 of the bed.
    assert_eq!(free, 14 * 10 - 12);
    // A start in a wall or outside the map is refused.
    assert!(reachable_part(&plan, [0.05, 0.5]).is_err());
    assert!(reachable_part(&plan, [-1.0, 0.5]).is_err());
}

#[test]
fn a_bed_seen_from_above_is_right_and_an_obstacle_in_the_open_is_wrong() {
    let plan = plan();
    let part = reachable_part(&plan, [0.25, 0.25]).expect("part");
    // A perfect map of the part scores 1.
    let perfect = map_iou(&part, &part, 0).expect("iou");
    assert_eq!((perfect.free, perfect.occupied), (1.0, 1.0));
    // The bed's top seen from above: its inner cells occupied too.
    let mut top = part.clone();
    for i in 5..7 {
        set(&mut top, i, 5, Cell::Occupied);
    }
    let occupied_in_part = part.cells.iter().filter(|&&c| c == Cell::Occupied).count();
    let only_part = map_iou(&top, &part, 0).expect("iou");
    let expect = occupied_in_part as f64 / (occupied_in_part + 2) as f64;
    assert!((only_part.occupied - expect).abs() < 1e-12, "{only_part:?}");
    let seen = map_iou_seen(&top, &part, &plan, 0).expect("iou");
    assert_eq!(seen.occupied, 1.0, "{seen:?}");
    // An obstacle in the open floor is wrong under both judges.
    let mut ghost = top.clone();
    set(&mut ghost, 10, 8, Cell::Occupied);
    let g = map_iou_seen(&ghost, &part, &plan, 0).expect("iou");
    let expect = (occupied_in_part + 2) as f64 / (occupied_in_part + 3) as f64;
    assert!((g.occupied - expect).abs() < 1e-12, "{g:?}");
    // The ghost's cell is no longer free either.
    assert!(g.free < 1.0);
    // Truths on different grids are refused.
    let other = MapImage::from_occupied([0.1, 0.0], 0.1, 20, 12, &[false; 240]);
    assert!(map_iou_seen(&top, &part, &other, 0).is_err());
    // A map whose cells do not fill it (a panic before), a NaN resolution, and a slack whose
    // window would take billions of lookups a cell are errors.
    let mut short = top.clone();
    short.cells.truncate(10);
    assert!(map_iou_seen(&short, &part, &plan, 0).is_err());
    let mut nan = top.clone();
    nan.resolution = f64::NAN;
    assert!(map_iou_seen(&nan, &part, &plan, 0).is_err());
    assert!(map_iou_seen(&top, &part, &plan, 10_000).is_err());
    assert!(map_iou(&top, &part, ferrobot_slam::MAX_SLACK).is_ok());
}
