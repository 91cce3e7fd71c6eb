//! What a base must keep clear of: round obstacles and occupancy-grid maps, in the odometry
//! frame (m), behind one query, the clearance from a point to the nearest obstacle.

use crate::error::{Error, Result};
use ferrobot_geometry::validate;

/// A round obstacle `[x, y, r]` (m) in the odometry frame.
pub type Circle = [f64; 3];

/// An occupancy-grid map in the odometry frame: square cells of `resolution` m, cell `(i, j)`
/// centred at `origin + (i, j) · resolution`, x along i.
#[derive(Debug, Clone, PartialEq)]
pub struct OccupancyGrid {
    /// Centre of cell (0, 0), m.
    pub origin: [f64; 2],
    /// Cell size, m.
    pub resolution: f64,
    /// Cells along x.
    pub width: usize,
    /// Cells along y.
    pub height: usize,
    /// Occupancy, row by row with x fastest: cell `(i, j)` is `occupied[j * width + i]`.
    pub occupied: Vec<bool>,
}

impl OccupancyGrid {
    /// A free grid of `width` × `height` cells of `resolution` m, cell (0, 0) centred at
    /// `origin` (m).
    pub fn new(origin: [f64; 2], resolution: f64, width: usize, height: usize) -> Result<Self> {
        // Check the shape before allocating its cells.
        Self::check_shape(origin, resolution, width, height)?;
        let g = OccupancyGrid {
            origin,
            resolution,
            width,
            height,
            occupied: vec![false; width * height],
        };
        g.check()?;
        Ok(g)
    }

    /// Whether a grid of this shape is usable (see [`OccupancyGrid::check`]), before its
    /// cells exist.
    pub(crate) fn check_shape(
        origin: [f64; 2],
        resolution: f64,
        width: usize,
        height: usize,
    ) -> Result<()> {
        let bad = |why: String| Error::InvalidMap { why };
        let lim = validate::MAX_BASE_COORDINATE;
        if !(origin.iter().all(|x| x.is_finite() && x.abs() <= lim)) {
            return Err(bad(format!(
                "origin {origin:?} is not finite within ±{lim} m"
            )));
        }
        if !(1e-3..=10.0).contains(&resolution) {
            return Err(bad(format!(
                "resolution {resolution} m is not in [0.001, 10]"
            )));
        }
        let n = width.checked_mul(height);
        if !matches!(n, Some(1..=validate::MAX_GRID_CELLS)) {
            return Err(bad(format!(
                "{width} × {height} cells (must be 1 to {})",
                validate::MAX_GRID_CELLS
            )));
        }
        let far = [
            origin[0] + width as f64 * resolution,
            origin[1] + height as f64 * resolution,
        ];
        if far.iter().any(|x| x.abs() > lim) {
            return Err(bad(format!("the grid reaches {far:?}, beyond ±{lim} m")));
        }
        Ok(())
    }

    /// Whether the grid is usable: origin and extent within ±[`validate::MAX_BASE_COORDINATE`]
    /// m, resolution in [0.001, 10] m, 1 to [`validate::MAX_GRID_CELLS`] cells, and one
    /// occupancy value per cell.
    pub fn check(&self) -> Result<()> {
        let bad = |why: String| Error::InvalidMap { why };
        Self::check_shape(self.origin, self.resolution, self.width, self.height)?;
        let n = self.width.checked_mul(self.height);
        if n != Some(self.occupied.len()) {
            return Err(bad(format!(
                "{} occupancy values for {} × {} cells",
                self.occupied.len(),
                self.width,
                self.height
            )));
        }
        Ok(())
    }

    /// The centre of cell `(i, j)`, m.
    pub fn centre(&self, i: usize, j: usize) -> [f64; 2] {
        [
            self.origin[0] + i as f64 * self.resolution,
            self.origin[1] + j as f64 * self.resolution,
        ]
    }

    /// The cell holding `p` (m), if inside the grid.
    pub fn cell(&self, p: [f64; 2]) -> Option<(usize, usize)> {
        let i = ((p[0] - self.origin[0]) / self.resolution).round();
        let j = ((p[1] - self.origin[1]) / self.resolution).round();
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.width && (j as usize) < self.height)
            .then_some((i as usize, j as usize))
    }

    /// The grid grown with free cells (the same cells, resolution and alignment) until it
    /// holds every point of `points` (m) with `margin` m to spare; an error when the result
    /// would be too large (see [`OccupancyGrid::check`]).
    pub fn grown_to(&self, points: &[[f64; 2]], margin: f64) -> Result<OccupancyGrid> {
        let r = self.resolution;
        let (mut lo, mut hi) = ([0i64, 0], [self.width as i64 - 1, self.height as i64 - 1]);
        for p in points {
            validate::finite("map point", p)?;
            for k in 0..2 {
                let a = ((p[k] - margin - self.origin[k]) / r).floor();
                let b = ((p[k] + margin - self.origin[k]) / r).ceil();
                if !(a.abs() < 1e9 && b.abs() < 1e9) {
                    return Err(Error::InvalidMap {
                        why: format!("point {p:?} m is too far from the map"),
                    });
                }
                lo[k] = lo[k].min(a as i64);
                hi[k] = hi[k].max(b as i64);
            }
        }
        let (w, h) = ((hi[0] - lo[0] + 1) as usize, (hi[1] - lo[1] + 1) as usize);
        let origin = [
            self.origin[0] + lo[0] as f64 * r,
            self.origin[1] + lo[1] as f64 * r,
        ];
        Self::check_shape(origin, r, w, h)?;
        let mut g = OccupancyGrid::new(origin, r, w, h)?;
        for j in 0..self.height {
            for i in 0..self.width {
                let (gi, gj) = ((i as i64 - lo[0]) as usize, (j as i64 - lo[1]) as usize);
                g.occupied[gj * w + gi] = self.occupied[j * self.width + i];
            }
        }
        Ok(g)
    }

    /// Whether the cell holding `p` is occupied (outside the grid: free).
    pub fn is_occupied(&self, p: [f64; 2]) -> bool {
        self.cell(p)
            .is_some_and(|(i, j)| self.occupied[j * self.width + i])
    }

    /// Mark every cell the circle `[x, y, r]` (m) overlaps occupied: the disc meets the cell's
    /// square in more than its edge (a cell only touched stays as it was). A post thinner than
    /// a cell marks the cells it stands in, wherever it stands; a cell-sized disc centred on a
    /// cell marks that cell alone, and one centred on a corner the four around it. The part
    /// of the circle outside the grid is not marked ([`OccupancyGrid::grown_to`] first).
    pub fn fill_circle(&mut self, c: Circle) {
        let r = c[2].max(0.0);
        let h = 0.5 * self.resolution;
        // Touching along an edge or at a corner, within rounding, is not overlapping.
        let reach = r - 1e-9 * self.resolution;
        let lo = self.cell_clamped([c[0] - r, c[1] - r], f64::floor);
        let hi = self.cell_clamped([c[0] + r, c[1] + r], f64::ceil);
        for j in lo.1..=hi.1 {
            for i in lo.0..=hi.0 {
                let [x, y] = self.centre(i, j);
                let dx = ((x - c[0]).abs() - h).max(0.0);
                let dy = ((y - c[1]).abs() - h).max(0.0);
                if dx.hypot(dy) < reach {
                    self.occupied[j * self.width + i] = true;
                }
            }
        }
    }

    /// The cell indices of `p` rounded by `round` (`f64::floor` or `f64::ceil`), clamped to
    /// the grid.
    fn cell_clamped(&self, p: [f64; 2], round: fn(f64) -> f64) -> (usize, usize) {
        let f = |x: f64, o: f64, n: usize| {
            (round((x - o) / self.resolution).max(0.0) as usize).min(n - 1)
        };
        (
            f(p[0], self.origin[0], self.width),
            f(p[1], self.origin[1], self.height),
        )
    }
}

/// The 4-connected neighbours' offsets of a grid cell.
pub const NEIGHBOURS_4: [(i64, i64); 4] = [(1, 0), (-1, 0), (0, 1), (0, -1)];
/// The 8-connected neighbours' offsets of a grid cell, the 4-connected ones first.
pub const NEIGHBOURS_8: [(i64, i64); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
];

/// The cells on the straight line from cell `a` to cell `b`, both included, in order
/// (Bresenham's line).
pub fn grid_line(a: (i64, i64), b: (i64, i64)) -> impl Iterator<Item = (i64, i64)> {
    let (dx, dy) = ((b.0 - a.0).abs(), -(b.1 - a.1).abs());
    let (sx, sy) = (
        if a.0 < b.0 { 1 } else { -1 },
        if a.1 < b.1 { 1 } else { -1 },
    );
    let mut at = Some((a, dx + dy));
    std::iter::from_fn(move || {
        let ((x, y), err) = at?;
        at = ((x, y) != b).then(|| {
            let (mut x, mut y, mut err2) = (x, y, err);
            let e2 = 2 * err;
            if e2 >= dy {
                err2 += dy;
                x += sx;
            }
            if e2 <= dx {
                err2 += dx;
                y += sy;
            }
            ((x, y), err2)
        });
        Some((x, y))
    })
}

/// The cells at `offsets` from cell `(i, j)` that lie inside a grid of `width` × `height`
/// cells, with their offset.
pub fn neighbours(
    (i, j): (usize, usize),
    width: usize,
    height: usize,
    offsets: &[(i64, i64)],
) -> impl Iterator<Item = ((usize, usize), (i64, i64))> + '_ {
    offsets.iter().filter_map(move |&(di, dj)| {
        let (a, b) = (i as i64 + di, j as i64 + dj);
        (a >= 0 && b >= 0 && (a as usize) < width && (b as usize) < height)
            .then_some(((a as usize, b as usize), (di, dj)))
    })
}

/// Exact Euclidean distance transform of a grid (Felzenszwalb and Huttenlocher, "Distance
/// transforms of sampled functions", 2012): for every cell, the distance (m) between its centre
/// and the nearest occupied cell's centre; infinite when nothing is occupied. Written here:
/// the two 1-D lower-envelope passes are 40 lines, and the crates that offer it pull image
/// libraries in.
#[derive(Debug, Clone, PartialEq)]
struct DistanceField {
    origin: [f64; 2],
    resolution: f64,
    width: usize,
    height: usize,
    dist: Vec<f64>,
}

/// One 1-D pass: `f` holds squared distances (or ∞) along a line; returns the squared
/// distance transform of it (unit spacing).
fn edt_1d(f: &[f64]) -> Vec<f64> {
    let n = f.len();
    let mut d = vec![f64::INFINITY; n];
    // Parabolas of the lower envelope: their vertices and the boundaries between them.
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0usize;
    let Some(first) = f.iter().position(|x| x.is_finite()) else {
        return d;
    };
    v[0] = first;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in first + 1..n {
        if !f[q].is_finite() {
            continue;
        }
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64);
            if s <= z[k] && k > 0 {
                k -= 1;
            } else {
                k += 1;
                v[k] = q;
                z[k] = s;
                z[k + 1] = f64::INFINITY;
                break;
            }
        }
    }
    let mut k = 0usize;
    for (q, out) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let dq = q as f64 - p as f64;
        *out = dq * dq + f[p];
    }
    d
}

impl DistanceField {
    fn new(g: &OccupancyGrid) -> Self {
        let (w, h) = (g.width, g.height);
        let mut sq: Vec<f64> = g
            .occupied
            .iter()
            .map(|&o| if o { 0.0 } else { f64::INFINITY })
            .collect();
        // Columns, then rows.
        for i in 0..w {
            let col: Vec<f64> = (0..h).map(|j| sq[j * w + i]).collect();
            for (j, x) in edt_1d(&col).into_iter().enumerate() {
                sq[j * w + i] = x;
            }
        }
        for j in 0..h {
            let row = edt_1d(&sq[j * w..(j + 1) * w]);
            sq[j * w..(j + 1) * w].copy_from_slice(&row);
        }
        DistanceField {
            origin: g.origin,
            resolution: g.resolution,
            width: w,
            height: h,
            dist: sq.into_iter().map(|x| x.sqrt() * g.resolution).collect(),
        }
    }

    /// Distance (m) from `p` to the nearest occupied cell, taken as the disc inscribed in its
    /// square: the field of distances between centres bilinearly interpolated (a distance
    /// field is 1-Lipschitz), less half a cell. Towards a square's corner this is up to
    /// (√2 − 1)/2 ≈ 0.21 of a cell more than the distance to the square itself. Outside the
    /// grid, the nearest edge value plus the distance to the edge (the outside counts as
    /// free).
    fn clearance(&self, p: [f64; 2]) -> f64 {
        let fx = (p[0] - self.origin[0]) / self.resolution;
        let fy = (p[1] - self.origin[1]) / self.resolution;
        let cx = fx.clamp(0.0, (self.width - 1) as f64);
        let cy = fy.clamp(0.0, (self.height - 1) as f64);
        let outside = self.resolution * (fx - cx).hypot(fy - cy);
        let i = (cx.floor() as usize).min(self.width.saturating_sub(2));
        let j = (cy.floor() as usize).min(self.height.saturating_sub(2));
        let (tx, ty) = ((cx - i as f64).min(1.0), (cy - j as f64).min(1.0));
        let at = |a: usize, b: usize| {
            self.dist[b.min(self.height - 1) * self.width + a.min(self.width - 1)]
        };
        let d = at(i, j) * (1.0 - tx) * (1.0 - ty)
            + at(i + 1, j) * tx * (1.0 - ty)
            + at(i, j + 1) * (1.0 - tx) * ty
            + at(i + 1, j + 1) * tx * ty;
        d - 0.5 * self.resolution + outside
    }
}

/// Obstacles for the base's planners: round ones and, optionally, an occupancy-grid map.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Obstacles {
    /// Round obstacles.
    pub circles: Vec<Circle>,
    field: Option<DistanceField>,
    bounds: Option<([f64; 2], [f64; 2])>,
}

impl Obstacles {
    /// Obstacles from `circles` (at most [`validate::MAX_OBSTACLES`], centres within
    /// ±[`validate::MAX_BASE_COORDINATE`] m, radii in [0, 100] m) and a `map` (checked with
    /// [`OccupancyGrid::check`]).
    pub fn new(circles: Vec<Circle>, map: Option<&OccupancyGrid>) -> Result<Self> {
        validate::count("obstacles", circles.len(), 0..=validate::MAX_OBSTACLES)?;
        for c in &circles {
            if !(c.iter().all(|x| x.is_finite()) && c[2] >= 0.0) {
                return Err(ferrobot_geometry::ValueError::NotFinite {
                    what: format!("obstacle {c:?} (needs finite x, y and r ≥ 0)"),
                    value: c[2],
                }
                .into());
            }
            let lim = validate::MAX_BASE_COORDINATE;
            validate::all_in_range("obstacle centre", &c[..2], -lim, lim)?;
            validate::in_range("obstacle radius", c[2], 0.0, 100.0)?;
        }
        let mut bounds: Option<([f64; 2], [f64; 2])> = None;
        let mut grow = |lo: [f64; 2], hi: [f64; 2]| {
            bounds = Some(match bounds {
                None => (lo, hi),
                Some((a, b)) => (
                    [a[0].min(lo[0]), a[1].min(lo[1])],
                    [b[0].max(hi[0]), b[1].max(hi[1])],
                ),
            });
        };
        for c in &circles {
            grow([c[0] - c[2], c[1] - c[2]], [c[0] + c[2], c[1] + c[2]]);
        }
        let field = match map {
            Some(g) => {
                g.check()?;
                let r = g.resolution;
                grow(
                    [g.origin[0] - 0.5 * r, g.origin[1] - 0.5 * r],
                    [
                        g.origin[0] + (g.width as f64 - 0.5) * r,
                        g.origin[1] + (g.height as f64 - 0.5) * r,
                    ],
                );
                g.occupied.iter().any(|&o| o).then(|| DistanceField::new(g))
            }
            None => None,
        };
        Ok(Obstacles {
            circles,
            field,
            bounds,
        })
    }

    /// Whether there is nothing to avoid.
    pub fn is_empty(&self) -> bool {
        self.circles.is_empty() && self.field.is_none()
    }

    /// The box `(min, max)` (m) holding every obstacle and the map, if any.
    pub fn bounds(&self) -> Option<([f64; 2], [f64; 2])> {
        self.bounds
    }

    /// Distance (m) from `p` to the nearest obstacle's boundary; negative inside a round one;
    /// infinite when there is none.
    pub fn clearance(&self, p: [f64; 2]) -> f64 {
        let mut d = self
            .field
            .as_ref()
            .map_or(f64::INFINITY, |f| f.clearance(p));
        for c in &self.circles {
            d = d.min((p[0] - c[0]).hypot(p[1] - c[1]) - c[2]);
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A circle marks the cells it overlaps (cell (i, j) is the square of side `resolution`
    /// about its centre): a 4 mm post off its cell's centre marks that cell (none before, when
    /// only centres inside the circle counted); a cell-sized disc at a cell's centre marks that
    /// cell alone, at a corner the four around it; one only touching a cell's edge leaves it.
    #[test]
    fn circles_mark_the_cells_they_overlap() {
        let count = |g: &OccupancyGrid| g.occupied.iter().filter(|&&o| o).count();
        let fresh = || OccupancyGrid::new([0.0, 0.0], 0.02, 10, 10).expect("grid");
        let mut g = fresh();
        g.fill_circle([0.055, 0.056, 0.004]);
        assert_eq!(count(&g), 1);
        assert!(g.is_occupied([0.06, 0.06]));
        let mut g = fresh();
        g.fill_circle([0.06, 0.06, 0.01]);
        assert_eq!(count(&g), 1);
        let mut g = fresh();
        g.fill_circle([0.05, 0.05, 0.01]);
        assert_eq!(count(&g), 4);
        // Touching the edge x = 0.07 of the cells of column 3.
        let mut g = fresh();
        g.fill_circle([0.08, 0.06, 0.01]);
        assert_eq!(count(&g), 1);
        assert!(g.is_occupied([0.08, 0.06]));
    }

    #[test]
    fn a_grid_line_runs_from_end_to_end_in_steps_of_one_cell() {
        let line: Vec<_> = grid_line((0, 0), (5, 2)).collect();
        assert_eq!(line, [(0, 0), (1, 0), (2, 1), (3, 1), (4, 2), (5, 2)]);
        for (a, b) in [((3, -4), (-6, 1)), ((2, 2), (2, 2)), ((0, 7), (0, -3))] {
            let l: Vec<_> = grid_line(a, b).collect();
            assert_eq!((l[0], *l.last().unwrap()), (a, b));
            let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()) as usize;
            assert_eq!(l.len(), steps + 1);
            assert!(l
                .windows(2)
                .all(|w| (w[1].0 - w[0].0).abs() <= 1 && (w[1].1 - w[0].1).abs() <= 1));
        }
    }

    /// The transform equals brute force on a scattered grid, cell by cell.
    #[test]
    fn the_distance_transform_is_exact() {
        let mut g = OccupancyGrid::new([-1.0, 2.0], 0.1, 37, 23).expect("grid");
        let mut s = 12345u64;
        for o in g.occupied.iter_mut() {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *o = (s >> 33).is_multiple_of(29);
        }
        let f = DistanceField::new(&g);
        let occ: Vec<(usize, usize)> = (0..g.height)
            .flat_map(|j| (0..g.width).map(move |i| (i, j)))
            .filter(|&(i, j)| g.occupied[j * g.width + i])
            .collect();
        assert!(occ.len() > 5);
        for j in 0..g.height {
            for i in 0..g.width {
                let brute = occ
                    .iter()
                    .map(|&(a, b)| (a as f64 - i as f64).hypot(b as f64 - j as f64) * 0.1)
                    .fold(f64::INFINITY, f64::min);
                let d = f.dist[j * g.width + i];
                assert!((d - brute).abs() < 1e-9, "({i}, {j}): {d} vs {brute}");
            }
        }
    }

    #[test]
    fn clearance_combines_circles_and_the_map() {
        let mut g = OccupancyGrid::new([0.0, 0.0], 0.05, 60, 60).expect("grid");
        g.fill_circle([1.5, 1.5, 0.2]);
        assert!(g.is_occupied([1.5, 1.5]) && !g.is_occupied([1.0, 1.0]));
        let o = Obstacles::new(vec![[0.5, 0.5, 0.1]], Some(&g)).expect("obstacles");
        // 0.7 m from the disc's centre: 0.5 m from its edge, within a cell of the grid.
        let d = o.clearance([2.2, 1.5]);
        assert!((d - 0.5).abs() < 0.05, "{d}");
        // The circle is nearer here; inside it the clearance is negative.
        assert!((o.clearance([0.5, 0.8]) - 0.2).abs() < 1e-9);
        assert!(o.clearance([0.5, 0.5]) < 0.0);
        // Outside the grid, the distance grows with the distance to the edge.
        assert!(o.clearance([5.0, 1.5]) > 3.0);
        assert_eq!(o.bounds().map(|b| b.0), Some([-0.025, -0.025]));
    }

    #[test]
    fn bad_maps_and_obstacles_are_refused() {
        assert!(OccupancyGrid::new([0.0, f64::NAN], 0.05, 10, 10).is_err());
        assert!(OccupancyGrid::new([0.0, 0.0], 0.0, 10, 10).is_err());
        assert!(OccupancyGrid::new([0.0, 0.0], 0.05, 0, 10).is_err());
        let mut g = OccupancyGrid::new([0.0, 0.0], 0.05, 10, 10).expect("grid");
        g.occupied.pop();
        let e = Obstacles::new(Vec::new(), Some(&g)).expect_err("short");
        assert!(e.to_string().contains("99 occupancy values"), "{e}");
        assert!(Obstacles::new(vec![[0.0, 0.0, -1.0]], None).is_err());
        assert!(Obstacles::new(vec![[0.0, f64::INFINITY, 1.0]], None).is_err());
    }
}
