//! Where to stand at a table, and how to get there without touching it: pure geometry in the
//! frame the robot looked from (`base_link` where it stood, x forward, y left, m and rad).
//!
//! The table is the axis-aligned rectangle `[lo, hi]` it was seen to cover (the table region's
//! bounds from the cloud, the robot facing its near edge `lo.x`). A [`Stance`] stands the
//! robot square to one of its four sides, a given distance from that side's edge, facing the
//! table. The route to it runs on the **ring**: the rectangle grown by a margin (the robot's
//! body radius plus a clearance), whose every point keeps the whole body clear of the table
//! at any heading. From the start (behind the near edge) the route backs or drives straight to
//! the ring's near side, then runs along the ring's sides, through its corners, to the
//! stance's point on the ring: every leg lies on the ring (a body on it keeps the margin) and
//! every turn is made on it.
//!
//! What the camera did not see of the table (a far edge or an end beyond the image) is not in
//! `[lo, hi]`: the robot looks again where it stands (the push skill), and the caller
//! bounds the table by what it saw.

/// A side of the table, named as seen from where the robot looked (facing the near side).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// The side the robot looked from (`lo.x`).
    Near,
    /// The robot's left end (`hi.y`).
    Left,
    /// The robot's right end (`lo.y`).
    Right,
    /// The side across the table (`hi.x`).
    Far,
}

impl Side {
    /// Every side, near first.
    pub const ALL: [Side; 4] = [Side::Near, Side::Left, Side::Right, Side::Far];

    /// Index in [`Side::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The heading of a robot facing the table from this side, rad from +x.
    pub fn facing(self) -> f64 {
        use std::f64::consts::{FRAC_PI_2, PI};
        match self {
            Side::Near => 0.0,
            Side::Left => -FRAC_PI_2,
            Side::Right => FRAC_PI_2,
            Side::Far => PI,
        }
    }

    /// The side's length, m, for the table `[lo, hi]`.
    pub fn length(self, lo: [f64; 2], hi: [f64; 2]) -> f64 {
        match self {
            Side::Near | Side::Far => hi[1] - lo[1],
            Side::Left | Side::Right => hi[0] - lo[0],
        }
    }

    /// The pose (x, y m, heading rad) `off` outside this side's edge of `[lo, hi]`, facing
    /// the table, `along` from the side's middle (positive to the robot's left as it faces
    /// the table).
    pub fn pose(self, lo: [f64; 2], hi: [f64; 2], off: f64, along: f64) -> [f64; 3] {
        let mid = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        let h = self.facing();
        let (s, c) = h.sin_cos();
        // Left of the heading: (-s, c).
        let [x, y] = match self {
            Side::Near => [lo[0] - off, mid[1]],
            Side::Far => [hi[0] + off, mid[1]],
            Side::Left => [mid[0], hi[1] + off],
            Side::Right => [mid[0], lo[1] - off],
        };
        [x - s * along, y + c * along, h]
    }
}

/// Where to stand: the side, the offset along it, and the route there.
#[derive(Debug, Clone, PartialEq)]
pub struct Stance {
    /// The side faced.
    pub side: Side,
    /// Offset from the side's middle, m (positive to the robot's left as it faces the table).
    pub along: f64,
    /// Waypoints (x, y m; heading rad on arrival, that of the next leg or, last, facing the
    /// table), from the start to the stance's point on the ring; each leg is straight.
    pub route: Vec<[f64; 3]>,
    /// The route's length, m (straight legs; turns in place add none).
    pub length: f64,
    /// The table's edges (in [`Side::ALL`]'s order) the route runs along or stops at: the
    /// near edge, the end it rounds to the far side, the side it stops at. Its clearance
    /// holds only if those are the table's real edges (see [`edges_seen`]).
    pub passes: [bool; 4],
}

/// The stance on `side`, `along` from its middle, and the route there on the ring of `[lo,
/// hi]` grown by `margin` (m), from `from` (x, y; behind the near edge: `from.x + margin <=
/// lo.x` is not required, the first leg runs straight along x to the ring). `None` when
/// `along` lies beyond the side's ends (`|along| > length / 2`), the margin is not positive,
/// or `from` is not behind the near edge (`from.x >= lo.x`) or not within the table's width.
pub fn stance(
    lo: [f64; 2],
    hi: [f64; 2],
    margin: f64,
    from: [f64; 2],
    side: Side,
    along: f64,
) -> Option<Stance> {
    let ok = margin > 0.0
        && lo[0] < hi[0]
        && lo[1] < hi[1]
        && from[0] < lo[0]
        && (lo[1]..=hi[1]).contains(&from[1])
        && along.abs() <= side.length(lo, hi) / 2.0 + 1e-9;
    if !ok {
        return None;
    }
    let near = lo[0] - margin;
    let (left, right, far) = (hi[1] + margin, lo[1] - margin, hi[0] + margin);
    let end = side.pose(lo, hi, margin, along);
    let goal = [end[0], end[1]];
    // The ring's corners, each with the heading of the leg that leaves it.
    let mut pts: Vec<[f64; 2]> = vec![[near, from[1]]];
    let mut passes = [true, false, false, false];
    passes[side.index()] = true;
    match side {
        Side::Near => {}
        Side::Left => pts.push([near, left]),
        Side::Right => pts.push([near, right]),
        Side::Far => {
            // Round the nearer end of the table.
            let (y, end) = if goal[1] >= from[1] {
                (left, Side::Left)
            } else {
                (right, Side::Right)
            };
            passes[end.index()] = true;
            pts.push([near, y]);
            pts.push([far, y]);
        }
    }
    pts.push(goal);
    let mut route = Vec::with_capacity(pts.len());
    let mut length = (pts[0][0] - from[0]).abs();
    for k in 0..pts.len() {
        let heading = match pts.get(k + 1) {
            Some(n) if (n[0] - pts[k][0]).hypot(n[1] - pts[k][1]) > 1e-9 => {
                length += (n[0] - pts[k][0]).hypot(n[1] - pts[k][1]);
                (n[1] - pts[k][1]).atan2(n[0] - pts[k][0])
            }
            Some(_) => route.last().map_or(0.0, |r: &[f64; 3]| r[2]),
            None => end[2],
        };
        route.push([pts[k][0], pts[k][1], heading]);
    }
    Some(Stance {
        side,
        along,
        route,
        length,
        passes,
    })
}

/// Which of the rectangle `[lo, hi]`'s edges (in [`Side::ALL`]'s order) a look from `eye`
/// shows to be the table's real edges. `points` and `eye` are (x, y, height above the table's
/// plane), m. A point at least `drop` below the plane (the floor) was seen past the table: the
/// camera's ray to it crossed the table top's height where there is no table. An edge is seen
/// when such a crossing lies at most `band` beyond it, within its span: the table ends within
/// `band` of it there. An edge without one may be where the camera's view ended, and the table
/// may reach further.
pub fn edges_seen(
    points: &[[f64; 3]],
    eye: [f64; 3],
    lo: [f64; 2],
    hi: [f64; 2],
    band: f64,
    drop: f64,
) -> [bool; 4] {
    let mut seen = [false; 4];
    if eye[2] <= 0.0 {
        return seen;
    }
    for &[x, y, h] in points {
        if h > -drop {
            continue;
        }
        let t = eye[2] / (eye[2] - h);
        let (x, y) = (eye[0] + t * (x - eye[0]), eye[1] + t * (y - eye[1]));
        let in_x = (lo[0]..=hi[0]).contains(&x);
        let in_y = (lo[1]..=hi[1]).contains(&y);
        seen[0] |= in_y && x < lo[0] && x >= lo[0] - band;
        seen[1] |= in_x && y > hi[1] && y <= hi[1] + band;
        seen[2] |= in_x && y < lo[1] && y >= lo[1] - band;
        seen[3] |= in_y && x > hi[0] && x <= hi[0] + band;
    }
    seen
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The least distance from the point `p` to the rectangle `[lo, hi]` (0 inside), m.
    fn distance_to_rect(p: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> f64 {
        let dx = (lo[0] - p[0]).max(p[0] - hi[0]).max(0.0);
        let dy = (lo[1] - p[1]).max(p[1] - hi[1]).max(0.0);
        dx.hypot(dy)
    }

    /// The least distance from the segment `a`-`b` to the rectangle `[lo, hi]`, m, sampled every
    /// millimetre (exact enough for a clearance check).
    fn segment_distance_to_rect(a: [f64; 2], b: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> f64 {
        let n = ((b[0] - a[0]).hypot(b[1] - a[1]) / 1e-3).ceil().max(1.0) as usize;
        (0..=n)
            .map(|k| {
                let t = k as f64 / n as f64;
                let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                distance_to_rect(p, lo, hi)
            })
            .fold(f64::INFINITY, f64::min)
    }

    const LO: [f64; 2] = [0.28, -0.4];
    const HI: [f64; 2] = [0.73, 0.4];

    #[test]
    fn every_route_keeps_the_margin_and_ends_facing_the_table() {
        let margin = 0.33;
        for side in [Side::Left, Side::Right, Side::Far] {
            for along in [0.0, 0.2, -0.2] {
                let s = stance(LO, HI, margin, [0.0, 0.0], side, along).unwrap();
                let last = *s.route.last().unwrap();
                assert!((last[2] - side.facing()).abs() < 1e-12, "{side:?}");
                // The stance point is the margin out from its side.
                assert!((distance_to_rect([last[0], last[1]], LO, HI) - margin).abs() < 1e-9);
                // Every leg after the first (straight back from the start) keeps the margin.
                for w in s.route.windows(2) {
                    let d =
                        segment_distance_to_rect([w[0][0], w[0][1]], [w[1][0], w[1][1]], LO, HI);
                    assert!(
                        d >= margin - 1e-9,
                        "{side:?} {along}: leg {d} m from the table"
                    );
                    // Each leg leaves in the heading its start point says.
                    let h = (w[1][1] - w[0][1]).atan2(w[1][0] - w[0][0]);
                    assert!((h - w[0][2]).abs() < 1e-9);
                }
                // The first leg is straight back along x.
                assert_eq!(s.route[0][1], 0.0);
                assert!((s.route[0][0] - (LO[0] - margin)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn the_far_side_is_reached_round_the_nearer_end() {
        let s = stance(LO, HI, 0.3, [0.0, 0.0], Side::Far, -0.2).unwrap();
        // Facing -x the robot's left is -y: along -0.2 is y = +0.2, so round the left end.
        assert_eq!(s.route.len(), 4);
        assert!((s.route[1][1] - 0.7).abs() < 1e-12);
        assert!((s.route[3][1] - 0.2).abs() < 1e-12);
        assert!((s.route[3][0] - 1.03).abs() < 1e-12);
        // 0.02 back, 0.7 left, 0.75 across, 0.5 back to y 0.2.
        assert!(
            (s.length - (0.02 + 0.7 + 1.05 + 0.5)).abs() < 1e-9,
            "{}",
            s.length
        );
        assert_eq!(s.passes, [true, true, false, true]);
    }

    #[test]
    fn stances_beyond_the_side_or_from_odd_starts_are_refused() {
        assert!(stance(LO, HI, 0.3, [0.0, 0.0], Side::Left, 0.3).is_none());
        assert!(stance(LO, HI, 0.3, [0.5, 0.0], Side::Left, 0.0).is_none());
        assert!(stance(LO, HI, 0.0, [0.0, 0.0], Side::Left, 0.0).is_none());
        assert!(stance(LO, HI, 0.3, [0.0, 0.0], Side::Left, 0.2).is_some());
    }

    #[test]
    fn an_edge_is_seen_where_the_floor_shows_past_it() {
        // The eye 0.4 m above the top, straight above (0.5, 0): a floor point 0.1 m below the
        // top is crossed at the top's height 4/5 of the way out.
        let eye = [0.5, 0.0, 0.4];
        let floor = |x: f64, y: f64| [x, y, -0.1];
        let pts = [
            // Past the near edge: crossed at x 0.276, 4 mm past it.
            floor(0.22, 0.0),
            // Past the right end: crossed at y -0.44.
            floor(0.5, -0.55),
            // Past the left end but crossed 0.12 m beyond it: the table may go on to there.
            floor(0.5, 0.65),
            // Level with the top past the far edge: the table goes on.
            [0.76, 0.0, 0.0],
        ];
        assert_eq!(
            edges_seen(&pts, eye, LO, HI, 0.05, 0.05),
            [true, false, true, false]
        );
    }

    #[test]
    fn poses_face_the_table_from_outside() {
        let p = Side::Right.pose(LO, HI, 0.3, 0.1);
        // Facing +y, its left is -x.
        assert!((p[0] - 0.405).abs() < 1e-12 && (p[1] + 0.7).abs() < 1e-12);
        let p = Side::Left.pose(LO, HI, 0.3, 0.1);
        assert!((p[0] - 0.605).abs() < 1e-12 && (p[1] - 0.7).abs() < 1e-12);
    }
}
