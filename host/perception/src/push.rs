//! Where to push an object on a table: PyRobot's pushing example's choice made deliberate.
//! From the objects found on the table ([`crate::segment_objects`]) and the table's region,
//! every object is tried in [`PushParams::directions`] directions in the table's plane; a push
//! is a straight stroke of a pusher (a gripper pointing down, its fingers closed) that starts
//! [`PushParams::gap`] before the object's near side and drives it
//! [`PushParams::distance`] on. A candidate is kept when
//!
//! * the pusher's path lies within the arm's reach ([`PushParams::reach`]),
//! * the corridor swept by the pusher and by the object (grown by
//!   [`PushParams::clearance`]) holds no point of another object, and
//! * the object stays on the table;
//!
//! and the kept candidate with the most **room** (the free run ahead of the object, to the
//! next object in its corridor or the table's edge) is chosen: the push least likely to
//! disturb anything else, and the one that leaves a rolling object the longest run.
//!
//! Pure geometry: points and planes in, a [`PushPlan`] out, in the cloud's frame, which must
//! have z up with the table about level (a robot's base frame). Units m and rad.

use nalgebra::{Point3, Vector2};

use crate::error::{PerceptionError, Result};
use crate::segment::{SegmentedObject, TableRegion};

/// How a push is chosen (see the module).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PushParams {
    /// How far the object is to be driven, m: in (0, 0.5].
    pub distance: f64,
    /// Free run before the pusher meets the object, m: in [0, 0.2].
    pub gap: f64,
    /// The pusher's footprint across the push, m (the LoCoBot's gripper body: 0.07): in
    /// (0, 0.3].
    pub pusher_width: f64,
    /// The pusher's footprint along the push, m (the gripper body: 0.05): in (0, 0.3].
    pub pusher_depth: f64,
    /// Half the depth of the pusher's lowest part (the closed fingers, which meet low objects
    /// first), m: in [0, pusher_depth / 2].
    pub contact_offset: f64,
    /// Distance kept between the corridor and other objects' points, m: in [0, 0.2].
    pub clearance: f64,
    /// Horizontal distance of the pusher from the arm's vertical axis (`reach_centre`) that the
    /// arm reaches pointing down at pushing height, m: `[min, max]`, 0 <= min < max <= 2.
    pub reach: [f64; 2],
    /// Where the arm's first (vertical) joint axis meets the frame's x-y plane, m: within
    /// ±2 m.
    pub reach_centre: [f64; 2],
    /// Directions tried, evenly spaced from the frame's +x: 1 to 360.
    pub directions: usize,
    /// Where the camera that saw the cloud stands (x, y, m), if known: an object's far side
    /// is unseen (it may reach further than its points), so pushes start only on the side
    /// the camera saw (directions within 90° of the ray from the camera to the object).
    pub viewpoint: Option<[f64; 2]>,
    /// An object has a flat top when, of its points within `flat_band[1]` of its highest,
    /// at least this share lie within `flat_band[0]` (a box's top face holds most of them; a
    /// ball's or a lying cylinder's curved top spreads them over the band). One without rolls
    /// on when pushed, so it is chosen only when no flat-topped object can be pushed. In
    /// [0, 1].
    pub flat_share: f64,
    /// The two bands for `flat_share`, m: 0 < thin < thick <= 0.05.
    pub flat_band: [f64; 2],
    /// Height of the pusher's tip above the table as a fraction of the object's height, then
    /// clamped to `tip_height` : in (0, 1].
    pub height_fraction: f64,
    /// Lowest and highest tip height above the table, m: 0 <= low <= high <= 0.2.
    pub tip_height: [f64; 2],
    /// An object lower than `low[0]` (m) is driven `low[1]` (m) instead of `distance`: only
    /// the closed fingers reach down to a flat one, and it turns off them on the way. In
    /// [0, 0.2] and (0, 0.5].
    pub low: [f64; 2],
    /// A rolling object (no flat top) elongated along its principal axis (the axis's variance
    /// at least [`ELONGATED`] times the next) is pushed only within this angle of that axis,
    /// rad: across it, it rolls on. In [0, π/2].
    pub along_axis: f64,
}

/// Ratio of an object's largest to second variance from which a rolling object is elongated
/// ([`PushParams::along_axis`]): a lying 3 x 7 cm capsule seen from above is about 5, a ball 1.
pub const ELONGATED: f64 = 3.0;

impl Default for PushParams {
    /// Drive 8 cm (the goal is 5), start 4 cm short, the LoCoBot's gripper as the pusher,
    /// 2 cm clearance, the LoCoBot's reach pointing down a
    /// few centimetres above its table (0.12-0.39 m from the shoulder's axis, 0.097 m ahead of
    /// `base_link`'s origin; its pitch-roll IK reaches 0.393 m there), 24 directions, the tip at a fifth of the object's height within 5-20
    /// mm of the table; flat tops: of the points in the top 12 mm, 55 % in the top 3 mm
    /// (a box about 80 %, a lying cylinder about 40 %, a ball 25 %); objects under 12 mm driven
    /// 12 cm; elongated rolling ones pushed within 20° of their axis.
    fn default() -> Self {
        PushParams {
            distance: 0.08,
            gap: 0.04,
            pusher_width: 0.07,
            pusher_depth: 0.05,
            contact_offset: 0.01,
            clearance: 0.02,
            reach: [0.12, 0.39],
            reach_centre: [0.097, 0.0],
            directions: 36,
            viewpoint: None,
            flat_share: 0.55,
            flat_band: [0.003, 0.012],
            height_fraction: 0.2,
            tip_height: [0.005, 0.02],
            low: [0.012, 0.12],
            along_axis: 0.35,
        }
    }
}

impl PushParams {
    /// Checks the ranges (see each field).
    pub fn check(&self) -> Result<()> {
        self.check_stroke()?;
        self.check_reach()?;
        self.check_objects()
    }

    /// The stroke and the pusher: distances, sizes, clearance.
    fn check_stroke(&self) -> Result<()> {
        if !(within(self.distance, 0.0, 0.5) && self.distance > 0.0) {
            return bad("distance", self.distance, "a finite distance in (0, 0.5] m");
        }
        if !within(self.gap, 0.0, 0.2) {
            return bad("gap", self.gap, "a finite distance in [0, 0.2] m");
        }
        if !(within(self.pusher_width, 0.0, 0.3) && self.pusher_width > 0.0) {
            return bad(
                "pusher_width",
                self.pusher_width,
                "a finite width in (0, 0.3] m",
            );
        }
        if !(within(self.pusher_depth, 0.0, 0.3) && self.pusher_depth > 0.0) {
            return bad(
                "pusher_depth",
                self.pusher_depth,
                "a finite depth in (0, 0.3] m",
            );
        }
        if !within(self.contact_offset, 0.0, self.pusher_depth / 2.0) {
            return bad(
                "contact_offset",
                self.contact_offset,
                "a finite distance in [0, pusher_depth / 2] m",
            );
        }
        if !within(self.clearance, 0.0, 0.2) {
            return bad(
                "clearance",
                self.clearance,
                "a finite distance in [0, 0.2] m",
            );
        }
        Ok(())
    }

    /// Where the arm reaches, the directions, the tip's height fraction and the viewpoint.
    fn check_reach(&self) -> Result<()> {
        let [lo, hi] = self.reach;
        if !(within(lo, 0.0, 2.0) && within(hi, 0.0, 2.0) && lo < hi) {
            return bad("reach", hi, "finite [min, max] with 0 <= min < max <= 2 m");
        }
        if let Some(&v) = self
            .reach_centre
            .iter()
            .find(|v| !within(v.abs(), 0.0, 2.0))
        {
            return bad("reach_centre", v, "finite coordinates within +-2 m");
        }
        if !(1..=360).contains(&self.directions) {
            return bad("directions", self.directions as f64, "1 to 360");
        }
        if !(within(self.height_fraction, 0.0, 1.0) && self.height_fraction > 0.0) {
            return bad(
                "height_fraction",
                self.height_fraction,
                "a finite fraction in (0, 1]",
            );
        }
        if let Some(&v) = self
            .viewpoint
            .iter()
            .flatten()
            .find(|v| !within(v.abs(), 0.0, 1e3))
        {
            return bad("viewpoint", v, "finite coordinates within +-1 km");
        }
        Ok(())
    }

    /// How objects are told apart: flat tops, tip heights, low and elongated objects.
    fn check_objects(&self) -> Result<()> {
        if !within(self.flat_share, 0.0, 1.0) {
            return bad("flat_share", self.flat_share, "a finite share in [0, 1]");
        }
        let [thin, thick] = self.flat_band;
        if !(within(thin, 0.0, 0.05) && within(thick, thin, 0.05) && thin > 0.0 && thick > thin) {
            return bad(
                "flat_band",
                thick,
                "finite bands with 0 < thin < thick <= 0.05 m",
            );
        }
        let [a, b] = self.tip_height;
        if !(within(a, 0.0, 0.2) && within(b, a, 0.2)) {
            return bad(
                "tip_height",
                b,
                "finite [low, high] with 0 <= low <= high <= 0.2 m",
            );
        }
        let [h, d] = self.low;
        if !(within(h, 0.0, 0.2) && within(d, 0.0, 0.5) && d > 0.0) {
            return bad(
                "low",
                d,
                "a height in [0, 0.2] m and a distance in (0, 0.5] m",
            );
        }
        if !within(self.along_axis, 0.0, std::f64::consts::FRAC_PI_2) {
            return bad(
                "along_axis",
                self.along_axis,
                "a finite angle in [0, pi/2] rad",
            );
        }
        Ok(())
    }
}

/// Whether `v` is finite and within `[lo, hi]`.
fn within(v: f64, lo: f64, hi: f64) -> bool {
    v.is_finite() && v >= lo && v <= hi
}

/// Parameter `name`'s `value` is out of its `range`.
fn bad(name: &'static str, value: f64, range: &'static str) -> Result<()> {
    Err(PerceptionError::Parameter { name, value, range })
}

/// The push chosen: which object, which way, and the pusher's stroke, in the cloud's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct PushPlan {
    /// Index of the object pushed in the objects given.
    pub target: usize,
    /// Unit direction of the push in the frame's x-y plane.
    pub direction: [f64; 2],
    /// The push's heading, rad from +x about z.
    pub heading: f64,
    /// Where the pusher's tip (its lowest point, centred) starts the stroke, m.
    pub start: Point3<f64>,
    /// Where it ends, m: `start + (gap + distance) * direction`.
    pub end: Point3<f64>,
    /// Free run ahead of the object before the push, m (to the next object in its corridor or
    /// the table's edge; capped at 1 m).
    pub room: f64,
    /// Candidates (object and direction) that passed every test.
    pub feasible: usize,
    /// Whether the target has a flat top (see [`PushParams::flat_share`]): one without rolls.
    pub flat: bool,
}

/// Step of the march to the table's edge, m.
const EDGE_STEP: f64 = 0.005;

/// The longest run looked at, m.
const MAX_ROOM: f64 = 1.0;

/// The push to make (see the module): the first of [`rank_pushes`].
pub fn plan_push(
    points: &[Point3<f64>],
    objects: &[SegmentedObject],
    table: &TableRegion,
    params: &PushParams,
) -> Result<PushPlan> {
    Ok(rank_pushes(points, objects, table, params)?.swap_remove(0))
}

/// Every push that passes the tests (see the module) for `objects` found in `points` (m, z
/// up) on `table`, best first: flat-topped objects before rolling ones, then by room.
/// Errors: bad parameters, no object on the table ([`PerceptionError::NoObjectOnTable`]),
/// object indices outside the cloud, or no candidate passing the tests
/// ([`PerceptionError::NoPush`]); the list is never empty.
pub fn rank_pushes(
    points: &[Point3<f64>],
    objects: &[SegmentedObject],
    table: &TableRegion,
    params: &PushParams,
) -> Result<Vec<PushPlan>> {
    params.check()?;
    if objects.is_empty() {
        return Err(PerceptionError::NoObjectOnTable);
    }
    let mut owner = vec![usize::MAX; points.len()];
    for (k, o) in objects.iter().enumerate() {
        for &i in &o.indices {
            *owner.get_mut(i).ok_or(PerceptionError::Parameter {
                name: "object point index",
                value: i as f64,
                range: "an index into the cloud",
            })? = k;
        }
    }
    let mut plans = Vec::new();
    for (k, o) in objects.iter().enumerate() {
        let heights: Vec<f64> = o
            .indices
            .iter()
            .map(|&i| table.plane.signed_distance(&points[i]))
            .collect();
        let height = heights.iter().copied().fold(0.0, f64::max);
        let within = |band: f64| heights.iter().filter(|&&h| h >= height - band).count();
        let [thin, thick] = params.flat_band;
        let flat = within(thin) as f64 >= params.flat_share * within(thick) as f64;
        let tip =
            (params.height_fraction * height).clamp(params.tip_height[0], params.tip_height[1]);
        // On the plane's normal at `tip` above it, below (x, y).
        let at = |xy: Vector2<f64>| {
            let n = table.plane.normal;
            let z = (table.plane.offset + tip - n.x * xy.x - n.y * xy.y) / n.z;
            Point3::new(xy.x, xy.y, z)
        };
        let mut own = *params;
        if height < params.low[0] {
            own.distance = params.low[1];
        }
        let v = o.features.variances;
        let axis = Vector2::new(o.features.principal_axis.x, o.features.principal_axis.y);
        let roller_axis = (!flat && v[0] >= ELONGATED * v[1])
            .then(|| axis.try_normalize(1e-9))
            .flatten();
        for j in 0..params.directions {
            let heading = std::f64::consts::TAU * j as f64 / params.directions as f64;
            let d = Vector2::new(heading.cos(), heading.sin());
            if roller_axis.is_some_and(|a| a.dot(&d).abs() < params.along_axis.cos()) {
                continue;
            }
            if let Some(c) = candidate(points, &owner, k, o, table, &own, d, flat) {
                plans.push(PushPlan {
                    target: k,
                    direction: [d.x, d.y],
                    heading,
                    start: at(c.start),
                    end: at(c.end),
                    room: c.room,
                    feasible: 0,
                    flat,
                });
            }
        }
    }
    if plans.is_empty() {
        return Err(PerceptionError::NoPush {
            objects: objects.len(),
        });
    }
    let n = plans.len();
    plans.sort_by(|a, b| b.flat.cmp(&a.flat).then(b.room.total_cmp(&a.room)));
    for p in &mut plans {
        p.feasible = n;
    }
    Ok(plans)
}

/// One candidate's stroke (pusher centre, x-y) and room.
struct Candidate {
    start: Vector2<f64>,
    end: Vector2<f64>,
    room: f64,
}

/// Object `k` (`flat`-topped or not) pushed along `d`, or `None` when a test fails.
#[allow(clippy::too_many_arguments)]
fn candidate(
    points: &[Point3<f64>],
    owner: &[usize],
    k: usize,
    o: &SegmentedObject,
    table: &TableRegion,
    params: &PushParams,
    d: Vector2<f64>,
    flat: bool,
) -> Option<Candidate> {
    let n = Vector2::new(-d.y, d.x);
    let xy = |i: usize| Vector2::new(points[i].x, points[i].y);
    let (mut s0, mut s1, mut t0, mut t1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &i in &o.indices {
        let p = xy(i);
        s0 = s0.min(p.dot(&d));
        s1 = s1.max(p.dot(&d));
        t0 = t0.min(p.dot(&n));
        t1 = t1.max(p.dot(&n));
    }
    let c = Vector2::new(o.features.centroid.x, o.features.centroid.y);
    let tc = c.dot(&n);
    // No start on the side away from the camera: the object may reach further than seen.
    if let Some(v) = params.viewpoint {
        let ray = (c - Vector2::from(v)).try_normalize(1e-9).unwrap_or(d);
        if d.dot(&ray) < 0.0 {
            return None;
        }
    }
    // The pusher's centre: its contact (the fingers) `gap` before the object, then on.
    let a = s0 - params.gap - params.contact_offset;
    let b = a + params.gap + params.distance;
    let stroke = Stroke {
        d,
        n,
        extent: [s0, s1, t0, t1],
        run: [a, b],
        tc,
    };
    let (start, end) = (d * a + n * tc, d * b + n * tc);
    if stroke.out_of_reach(params, start, end) {
        return None;
    }
    let mut room = stroke.room(points, owner, k, params)?;
    let e = edge_run(table, o, c, d);
    let front = s1 - c.dot(&d);
    let edge = e - front;
    // An object that rolls runs on after the push: its whole lane to the edge must be free.
    if !flat && room < edge {
        return None;
    }
    room = room.min(edge);
    (room >= params.distance + params.clearance).then_some(Candidate { start, end, room })
}

/// One object pushed one way, in the push's coordinates (m): along the unit direction `d` and
/// across it along `n`.
struct Stroke {
    d: Vector2<f64>,
    n: Vector2<f64>,
    /// The object's extent: from `s0` to `s1` along, from `t0` to `t1` across.
    extent: [f64; 4],
    /// The pusher centre's run along, from its start to its end ...
    run: [f64; 2],
    /// ... at this offset across (the object's centroid's).
    tc: f64,
}

impl Stroke {
    /// Whether the pusher's path from `start` to `end` leaves the arm's reach.
    fn out_of_reach(&self, params: &PushParams, start: Vector2<f64>, end: Vector2<f64>) -> bool {
        let d = self.d;
        // Reach: the farthest point of a segment from the axis is an end, the nearest may lie
        // between.
        let [rmin, rmax] = params.reach;
        let axis = Vector2::from(params.reach_centre);
        let (from, to) = (start - axis, end - axis);
        let nearest = {
            let len = (to - from).norm();
            let u = ((-from).dot(&d)).clamp(0.0, len);
            (from + d * u).norm()
        };
        from.norm() > rmax || to.norm() > rmax || nearest < rmin
    }

    /// The free run ahead of object `k` (to the nearest point of another object in its lane
    /// beyond its front, at most [`MAX_ROOM`]), or `None` when another object's point lies in
    /// the corridor the pusher and the object sweep.
    fn room(
        &self,
        points: &[Point3<f64>],
        owner: &[usize],
        k: usize,
        params: &PushParams,
    ) -> Option<f64> {
        let (d, n, tc) = (self.d, self.n, self.tc);
        let [s0, s1, t0, t1] = self.extent;
        let [a, b] = self.run;
        let xy = |i: usize| Vector2::new(points[i].x, points[i].y);
        // The swept corridor: the pusher's (from its back at the start to its front at the
        // end) and the object's (from its back to its front driven on), grown by the
        // clearance.
        let w = params.pusher_width / 2.0 + params.clearance;
        let pusher = (
            a - params.pusher_depth / 2.0 - params.clearance,
            b + params.pusher_depth / 2.0 + params.clearance,
            tc - w,
            tc + w,
        );
        let object = (
            s0 - params.clearance,
            s1 + params.distance + params.clearance,
            t0 - params.clearance,
            t1 + params.clearance,
        );
        let inside =
            |r: &(f64, f64, f64, f64), s: f64, t: f64| s >= r.0 && s <= r.1 && t >= r.2 && t <= r.3;
        // The run ahead: the nearest other point in the object's lane beyond its front.
        let lane = (
            t0.min(tc - w + params.clearance),
            t1.max(tc + w - params.clearance),
        );
        let mut room = MAX_ROOM;
        for (i, &who) in owner.iter().enumerate() {
            if who == usize::MAX || who == k {
                continue;
            }
            let p = xy(i);
            let (s, t) = (p.dot(&d), p.dot(&n));
            if inside(&pusher, s, t) || inside(&object, s, t) {
                return None;
            }
            if t >= lane.0 - params.clearance && t <= lane.1 + params.clearance && s > s1 {
                room = room.min(s - s1 - params.clearance);
            }
        }
        Some(room)
    }
}

/// How far object `o`'s centroid `c` (x, y) marches along `d` and stays on the table, in steps
/// of [`EDGE_STEP`] up to [`MAX_ROOM`], m.
fn edge_run(table: &TableRegion, o: &SegmentedObject, c: Vector2<f64>, d: Vector2<f64>) -> f64 {
    // The table's edge ahead of the object's front (its centre marched out).
    let z = o.features.centroid.z;
    let mut e = 0.0;
    while e < MAX_ROOM {
        let q = c + d * (e + EDGE_STEP);
        if !table.contains(&Point3::new(q.x, q.y, z), 0.0) {
            break;
        }
        e += EDGE_STEP;
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::Dbscan;
    use crate::plane::{fit_plane, RansacParams};
    use crate::segment::{segment_objects, SegmentParams};
    use crate::synthetic::{sample_rectangle, sample_solid, Solid};
    use nalgebra::Vector3;

    /// A 0.45 x 0.8 m table top at 0.09 m (the tabletop scene in the LoCoBot's base frame)
    /// with boxes `(x, y, size)` on it; the cloud, the objects and the table's region.
    fn table_with(
        boxes: &[([f64; 2], [f64; 3])],
    ) -> (Vec<Point3<f64>>, Vec<SegmentedObject>, TableRegion) {
        let h = 0.09;
        let solids: Vec<Solid> = boxes
            .iter()
            .map(|&(c, s)| Solid::Box {
                centre: Point3::new(c[0], c[1], h + s[2] / 2.0),
                size: Vector3::new(s[0], s[1], s[2]),
                yaw: 0.0,
            })
            .collect();
        let mut pts = sample_rectangle(
            1,
            Point3::new(0.505, 0.0, h),
            Vector3::x(),
            Vector3::y(),
            [0.45, 0.8],
            40_000.0,
            0.001,
            &solids,
            0.0,
        );
        for (k, b) in solids.iter().enumerate() {
            pts.extend(sample_solid(10 + k as u64, b, 400_000.0));
        }
        let fit = fit_plane(
            &pts,
            &RansacParams {
                threshold: 0.005,
                up: Some(Vector3::z()),
                ..Default::default()
            },
        )
        .unwrap();
        let objects = segment_objects(
            &pts,
            &fit,
            &SegmentParams::default(),
            &Dbscan::new(0.02, 15).unwrap(),
        )
        .unwrap();
        assert_eq!(objects.len(), boxes.len());
        let region = TableRegion::new(&pts, &fit).unwrap();
        (pts, objects, region)
    }

    /// Of two boxes side by side, one in reach, the push drives the reachable one away from
    /// the other, its stroke within reach and starting the gap short of its near side, the
    /// tip at its share of the height.
    #[test]
    fn the_push_leaves_the_neighbour_alone_and_stays_in_reach() {
        let (pts, objects, table) = table_with(&[
            ([0.36, 0.0], [0.04, 0.04, 0.04]),
            ([0.36, 0.09], [0.04, 0.04, 0.04]),
        ]);
        let p = PushParams::default();
        let plan = plan_push(&pts, &objects, &table, &p).unwrap();
        let target = &objects[plan.target].features;
        let other = &objects[1 - plan.target].features;
        let d = Vector2::from(plan.direction);
        let away = Vector2::new(
            target.centroid.x - other.centroid.x,
            target.centroid.y - other.centroid.y,
        );
        assert!(d.dot(&away) > 0.0, "pushed towards the other: {plan:?}");
        for q in [plan.start, plan.end] {
            let r = (q.coords.xy() - Vector2::from(p.reach_centre)).norm();
            assert!(r >= p.reach[0] && r <= p.reach[1], "{q} out of reach");
            let tip = (p.height_fraction * 0.04).clamp(p.tip_height[0], p.tip_height[1]);
            assert!((q.z - (0.09 + tip)).abs() < 0.002, "tip at {}", q.z);
        }
        let stroke = (plan.end - plan.start).xy().norm();
        assert!((stroke - (p.gap + p.distance)).abs() < 1e-9);
        assert!(plan.room >= p.distance + p.clearance && plan.feasible > 0);
    }

    /// An 11 mm block is driven `low[1]`, not `distance`; an elongated object without a flat
    /// top (here a bar whose top band counts as curved) is pushed only along its long axis.
    #[test]
    fn low_objects_go_further_and_rollers_go_along_their_axis() {
        let p = PushParams::default();
        let (pts, objects, table) = table_with(&[([0.36, 0.0], [0.02, 0.04, 0.011])]);
        let plan = plan_push(&pts, &objects, &table, &p).unwrap();
        let stroke = (plan.end - plan.start).xy().norm();
        assert!(
            (stroke - (p.gap + p.low[1])).abs() < 1e-9,
            "stroke {stroke}"
        );
        let (pts, objects, table) = table_with(&[([0.36, 0.0], [0.08, 0.02, 0.02])]);
        let curved = PushParams {
            flat_share: 1.0,
            flat_band: [0.0005, 0.05],
            ..p
        };
        let plans = rank_pushes(&pts, &objects, &table, &curved).unwrap();
        assert!(!plans[0].flat);
        for q in &plans {
            assert!(
                q.direction[0].abs() >= p.along_axis.cos() - 1e-9,
                "across the bar: {q:?}"
            );
        }
        let any = PushParams {
            along_axis: std::f64::consts::FRAC_PI_2,
            ..curved
        };
        let all = rank_pushes(&pts, &objects, &table, &any).unwrap();
        assert!(all.len() > plans.len(), "{} vs {}", all.len(), plans.len());
    }

    /// An empty table, an object out of reach, or one boxed in by its neighbours: typed
    /// errors.
    #[test]
    fn nothing_to_push_is_a_typed_error() {
        let (pts, objects, table) = table_with(&[([0.36, 0.0], [0.04, 0.04, 0.04])]);
        let e = plan_push(&pts, &[], &table, &PushParams::default()).unwrap_err();
        assert!(
            matches!(e, PerceptionError::NoObjectOnTable) && !e.is_input(),
            "{e}"
        );
        let far = PushParams {
            reach: [0.0, 0.2],
            ..Default::default()
        };
        let e = plan_push(&pts, &objects, &table, &far).unwrap_err();
        assert!(matches!(e, PerceptionError::NoPush { objects: 1 }), "{e}");
        let (pts, objects, table) = table_with(&[
            ([0.40, 0.0], [0.03, 0.03, 0.03]),
            ([0.40, 0.06], [0.03, 0.03, 0.03]),
            ([0.40, -0.06], [0.03, 0.03, 0.03]),
            ([0.46, 0.0], [0.03, 0.03, 0.03]),
            ([0.34, 0.0], [0.03, 0.03, 0.03]),
        ]);
        let tight = PushParams {
            reach: [0.38, 0.42],
            ..Default::default()
        };
        let e = plan_push(&pts, &objects, &table, &tight).unwrap_err();
        assert!(matches!(e, PerceptionError::NoPush { objects: 5 }), "{e}");
        for bad in [
            PushParams {
                distance: f64::NAN,
                ..Default::default()
            },
            PushParams {
                distance: 0.0,
                ..Default::default()
            },
            PushParams {
                reach: [0.5, 0.2],
                ..Default::default()
            },
            PushParams {
                directions: 0,
                ..Default::default()
            },
            PushParams {
                tip_height: [0.02, 0.01],
                ..Default::default()
            },
            PushParams {
                clearance: f64::INFINITY,
                ..Default::default()
            },
        ] {
            let e = plan_push(&pts, &objects, &table, &bad).unwrap_err();
            assert!(
                matches!(e, PerceptionError::Parameter { .. }) && e.is_input(),
                "{e}"
            );
        }
    }
}
