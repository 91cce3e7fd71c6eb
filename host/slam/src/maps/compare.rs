//! How well an occupancy grid agrees with a ground-truth one: the intersection over union of
//! free and occupied cells ([`map_iou`], [`map_iou_seen`]), and the part of a floor plan a
//! robot can map ([`reachable_part`]). Grids share a resolution, m per cell.

use ferrobot_nav::{neighbours, Cell, MapImage, NEIGHBOURS_8};

use crate::error::{Error, Result};

/// Agreement of two maps of the same resolution: the intersection over union of their free
/// cells and of their occupied cells, over the cells of `truth` (cells of `estimate` outside it,
/// or `Unknown`, count as not free and not occupied). Occupied cells match within `slack`
/// cells (a wall drawn one cell off still counts), at most [`MAX_SLACK`].
pub fn map_iou(estimate: &MapImage, truth: &MapImage, slack: usize) -> Result<MapIou> {
    map_iou_seen(estimate, truth, truth, slack)
}

/// Largest `slack` of [`map_iou`] and [`map_iou_seen`], cells: each occupied cell looks at
/// (2·slack + 1)² cells.
pub const MAX_SLACK: usize = 100;

/// As [`map_iou`] against `must`, the part of the truth a map must hold (say the
/// [`reachable_part`] of a floor plan: floor the robot can reach and the faces next to it),
/// where an occupied cell of `estimate` that `must` leaves unknown is judged against the whole
/// truth `all`: right (in both maps) when `all` has an obstacle within `slack` cells of it (the
/// top of a bed seen from above is the bed), wrong otherwise. Both truths share one grid.
pub fn map_iou_seen(
    estimate: &MapImage,
    must: &MapImage,
    all: &MapImage,
    slack: usize,
) -> Result<MapIou> {
    let truth = must;
    for (what, m) in [
        ("estimate", estimate),
        ("truth", must),
        ("whole truth", all),
    ] {
        m.check().map_err(|e| Error::Trajectory {
            why: format!("{what} map: {e}"),
        })?;
    }
    if slack > MAX_SLACK {
        return Err(Error::Trajectory {
            why: format!("a slack of {slack} cells is more than {MAX_SLACK}"),
        });
    }
    for m in [estimate, all] {
        if (m.resolution - truth.resolution).abs() > 1e-9 {
            return Err(Error::Trajectory {
                why: format!(
                    "maps of resolution {} and {} m",
                    m.resolution, truth.resolution
                ),
            });
        }
    }
    if all.width != truth.width || all.height != truth.height || all.origin != truth.origin {
        return Err(Error::Trajectory {
            why: "the two truths are not on one grid".into(),
        });
    }
    let r = truth.resolution;
    let at = |m: &MapImage, x: f64, y: f64| -> Cell {
        let i = ((x - m.origin[0]) / r).floor();
        let j = ((y - m.origin[1]) / r).floor();
        if i < 0.0 || j < 0.0 || i >= m.width as f64 || j >= m.height as f64 {
            return Cell::Unknown;
        }
        m.cells[j as usize * m.width + i as usize]
    };
    let near_occupied = |m: &MapImage, x: f64, y: f64| -> bool {
        let s = slack as i64;
        (-s..=s).any(|di| {
            (-s..=s).any(|dj| at(m, x + di as f64 * r, y + dj as f64 * r) == Cell::Occupied)
        })
    };
    let (mut fi, mut fu, mut oi, mut ou) = (0usize, 0usize, 0usize, 0usize);
    for j in 0..truth.height {
        for i in 0..truth.width {
            let x = truth.origin[0] + (i as f64 + 0.5) * r;
            let y = truth.origin[1] + (j as f64 + 0.5) * r;
            let t = truth.cells[j * truth.width + i];
            let e = at(estimate, x, y);
            let (tf, ef) = (t == Cell::Free, e == Cell::Free);
            fi += (tf && ef) as usize;
            fu += (tf || ef) as usize;
            let (to, eo) = (t == Cell::Occupied, e == Cell::Occupied);
            if to || eo {
                ou += 1;
                let hit = if to {
                    near_occupied(estimate, x, y)
                } else {
                    near_occupied(all, x, y)
                };
                oi += hit as usize;
            }
        }
    }
    let ratio = |a: usize, b: usize| if b == 0 { 1.0 } else { a as f64 / b as f64 };
    Ok(MapIou {
        free: ratio(fi, fu),
        occupied: ratio(oi, ou),
        cells: ratio(fi + oi, fu + ou),
    })
}

/// The part of a ground-truth map that a robot starting at `from` (m) can map: the free cells
/// joined to its cell through free cells (8-connected) and the occupied cells within one cell
/// of them (the surfaces it can see); the rest is unknown: the inside of furniture and walls,
/// and what lies beyond the outer walls. An error when `from` is outside the map or not on a
/// free cell.
pub fn reachable_part(truth: &MapImage, from: [f64; 2]) -> Result<MapImage> {
    truth.check().map_err(|e| Error::Trajectory {
        why: format!("ground-truth map: {e}"),
    })?;
    let r = truth.resolution;
    let (w, h) = (truth.width, truth.height);
    let i = ((from[0] - truth.origin[0]) / r).floor();
    let j = ((from[1] - truth.origin[1]) / r).floor();
    if !(i >= 0.0 && j >= 0.0 && i < w as f64 && j < h as f64) {
        return Err(Error::Trajectory {
            why: format!("the start {from:?} m is outside the map"),
        });
    }
    let start = (i as usize, j as usize);
    if truth.cells[start.1 * w + start.0] != Cell::Free {
        return Err(Error::Trajectory {
            why: format!("the start {from:?} m is not on a free cell"),
        });
    }
    let mut reached = vec![false; w * h];
    reached[start.1 * w + start.0] = true;
    let mut queue = std::collections::VecDeque::from([start]);
    while let Some(c) = queue.pop_front() {
        for ((x, y), _) in neighbours(c, w, h, &NEIGHBOURS_8) {
            let k = y * w + x;
            if !reached[k] && truth.cells[k] == Cell::Free {
                reached[k] = true;
                queue.push_back((x, y));
            }
        }
    }
    let mut cells = vec![Cell::Unknown; w * h];
    for b in 0..h {
        for a in 0..w {
            let k = b * w + a;
            cells[k] = match truth.cells[k] {
                Cell::Free if reached[k] => Cell::Free,
                Cell::Occupied => {
                    // Next to a reached cell (an occupied cell is never reached itself).
                    let seen = neighbours((a, b), w, h, &NEIGHBOURS_8)
                        .any(|((x, y), _)| reached[y * w + x]);
                    if seen {
                        Cell::Occupied
                    } else {
                        Cell::Unknown
                    }
                }
                _ => Cell::Unknown,
            };
        }
    }
    Ok(MapImage {
        cells,
        ..truth.clone()
    })
}

/// The agreement [`map_iou`] measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapIou {
    /// Intersection over union of the free cells.
    pub free: f64,
    /// Intersection over union of the occupied cells, within the slack.
    pub occupied: f64,
    /// Cells labelled alike (free, or occupied within the slack) over cells either map labels
    /// free or occupied: the two classes together.
    pub cells: f64,
}
