//! The navigator: a goal reached on a map as move_base reaches it, sans-IO. Fed with the time,
//! the base's pose in the map's frame and, when a camera sees, obstacle points; it answers
//! with the velocity to command.
//!
//! - **Global plan.** A* on the map with the live obstacles stamped in ([`GridAStar`], keeping
//!   a margin beyond the robot's radius where there is room), again every
//!   [`NavSettings::replan_period`] and at once when the way ahead is blocked.
//! - **Local control.** Regulated pure pursuit of the path (Macenski et al. 2023, Nav2's
//!   default for differential drives): the base turns in place towards the path when it faces
//!   away from it, otherwise follows an arc to a point a short way along it, slowed on tight
//!   arcs, near obstacles and before the goal. Every command's arc is simulated for
//!   [`NavSettings::check_time`] against the map and the live obstacles; one that would touch
//!   is not sent (the base stops and the path is planned again around what blocks it).
//! - **Recovery.** When the way to the goal does not shorten by [`PROGRESS_STEP`] within
//!   [`NavSettings::stall_time`], the base backs up (where the way behind is free) or turns a
//!   full circle in place (which lets the camera see all round), in turn, then plans again; after
//!   [`NavSettings::max_recoveries`] in a row (a row ends when the base gets
//!   [`STREAK_DISTANCE`] from where it began) the goal fails with [`Error::Stalled`]. A goal no path reaches fails with [`Error::NoPath`] once the live
//!   base has turned all round (so the camera has looked again at what it remembers: what has gone is cleared) and it still has none.
//!
//! Why a path follower and not the dynamic window: `docs/design/nav.md`.

use ferrobot_control::trajectory::{step, Limits};
use ferrobot_geometry::{validate, wrap};

use crate::error::{Error, Result};
use crate::global::GridAStar;
use crate::live::LiveObstacles;
pub use crate::live::Scan;
use crate::obstacles::{Obstacles, OccupancyGrid};

/// Progress that counts, m: the way left to the goal must shorten by this much.
pub const PROGRESS_STEP: f64 = 0.05;

/// Where the usual pursuit's arc would touch, the path is followed with the pursued point this
/// near, m.
const TIGHT_LOOKAHEAD: f64 = 0.12;

/// A streak of recoveries ends when the base gets this far from where it began, m.
pub const STREAK_DISTANCE: f64 = 0.5;
/// A recovery may take this much longer than it should before it is cut short, s.
pub const RECOVERY_SLACK: f64 = 3.0;

/// How a [`Navigator`] drives.
#[derive(Debug, Clone, PartialEq)]
pub struct NavSettings {
    /// The footprint's radius, m: nothing nearer the base's centre than this may be touched.
    pub radius: f64,
    /// Clearance the global path keeps beyond the radius where there is room, m.
    pub margin: f64,
    /// Speed and acceleration limits of the commands.
    pub limits: Limits,
    /// Control period, s.
    pub dt: f64,
    /// How far along the path the pursued point lies, m.
    pub lookahead: f64,
    /// The goal is reached when the base's centre is this near it, m.
    pub goal_tolerance: f64,
    /// The path is planned again this often, s.
    pub replan_period: f64,
    /// How long a command's arc is checked ahead for collisions, s.
    pub check_time: f64,
    /// How long without [`PROGRESS_STEP`] of progress before a recovery, s.
    pub stall_time: f64,
    /// Recoveries without progress before the goal fails.
    pub max_recoveries: u32,
    /// How far a back-up recovery reverses, m.
    pub backup: f64,
    /// Live obstacle points not seen again for this long are forgotten, s.
    pub live_memory: f64,
}

impl NavSettings {
    /// Settings for a round base of `radius` m under `limits`: a 0.15 m margin, 0.1 s control
    /// period, 0.35 m lookahead, 0.1 m goal tolerance, re-planning every 2 s, arcs checked 1.5 s
    /// ahead, recovery after 6 s without progress, 4 recoveries, 0.15 m back-ups, live
    /// obstacles kept 60 s.
    pub fn new(radius: f64, limits: Limits) -> Self {
        NavSettings {
            radius,
            margin: 0.15,
            limits,
            dt: 0.1,
            lookahead: 0.35,
            goal_tolerance: 0.1,
            replan_period: 2.0,
            check_time: 1.5,
            stall_time: 6.0,
            max_recoveries: 4,
            backup: 0.15,
            live_memory: 60.0,
        }
    }

    /// Every value finite and in range.
    pub fn check(&self) -> Result<()> {
        validate::in_range(
            "navigator radius",
            self.radius,
            0.0,
            crate::global::MAX_RADIUS,
        )?;
        validate::in_range("navigator margin", self.margin, 0.0, 5.0)?;
        validate::in_range("navigator dt", self.dt, 0.01, 1.0)?;
        validate::in_range("navigator lookahead", self.lookahead, 0.05, 5.0)?;
        validate::in_range("goal tolerance", self.goal_tolerance, 0.001, 5.0)?;
        validate::in_range("re-planning period", self.replan_period, 0.1, 600.0)?;
        validate::in_range("collision check time", self.check_time, 0.1, 10.0)?;
        validate::in_range("stall time", self.stall_time, 0.5, 600.0)?;
        validate::in_range("back-up distance", self.backup, 0.0, 2.0)?;
        validate::in_range("live obstacle memory", self.live_memory, 0.0, 1e6)?;
        if self.max_recoveries > 100 {
            return Err(Error::InvalidMap {
                why: format!("{} recoveries (at most 100)", self.max_recoveries),
            });
        }
        self.limits.check().map_err(|e| Error::InvalidMap {
            why: format!("navigator limits: {e}"),
        })?;
        Ok(())
    }
}

/// What to command now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NavCommand {
    /// Drive at `v` m/s and `ω` rad/s until the next step.
    Drive(f64, f64),
    /// The goal's position is reached (within [`NavSettings::goal_tolerance`]); turning to a
    /// heading is the caller's.
    Arrived,
}

/// A recovery under way.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Recovery {
    /// Reverse straight until this far from where it began, m.
    BackUp { from: [f64; 2] },
    /// Turn in place until this much heading has been turned, rad.
    Turn { turned: f64, last: f64 },
}

/// A goal being reached on a map. See the module's documentation.
#[derive(Debug, Clone)]
pub struct Navigator {
    s: NavSettings,
    map: OccupancyGrid,
    known: Obstacles,
    live: LiveObstacles,
    goal: [f64; 2],
    path: Vec<[f64; 2]>,
    /// Index of the path segment the base was last nearest.
    along: usize,
    planned_at: Option<f64>,
    replan: bool,
    /// Least way left so far (m) and when it was last bettered by a [`PROGRESS_STEP`].
    progress: (f64, f64),
    recovering: Option<Recovery>,
    recoveries: u32,
    /// Where the present streak of recoveries began, m.
    streak_from: Option<[f64; 2]>,
    /// When the recovery under way must end, s.
    recovery_until: f64,
    /// Whether the base has turned all round since the last successful plan.
    looked_round: bool,
    last: (f64, f64),
    /// The command's time, when the last step sent one.
    stepped: Option<f64>,
}

impl Navigator {
    /// A navigator to `goal` (`[x, y]`, m, the map's frame) on `map` (beyond its edge is
    /// unknown, hence free: it is grown to hold the goal with 1 m to spare). Errors: settings
    /// out of range, a goal that is not finite, a map that cannot be used, a goal where the
    /// base would overlap an obstacle.
    pub fn new(map: &OccupancyGrid, goal: [f64; 2], settings: NavSettings) -> Result<Self> {
        settings.check()?;
        validate::finite("navigation goal", &goal)?;
        map.check()?;
        let map = map.grown_to(&[goal], 1.0)?;
        let known = Obstacles::new(Vec::new(), Some(&map))?;
        let clear = known.clearance(goal);
        if clear < settings.radius {
            return Err(Error::Blocked {
                what: "goal",
                at: goal,
                clearance: clear,
                radius: settings.radius,
            });
        }
        let live = LiveObstacles::new(map.resolution)?;
        Ok(Navigator {
            s: settings,
            map,
            known,
            live,
            goal,
            path: Vec::new(),
            along: 0,
            planned_at: None,
            replan: true,
            progress: (f64::INFINITY, 0.0),
            recovering: None,
            recoveries: 0,
            streak_from: None,
            recovery_until: 0.0,
            looked_round: false,
            last: (0.0, 0.0),
            stepped: None,
        })
    }

    /// The goal, m.
    pub fn goal(&self) -> [f64; 2] {
        self.goal
    }

    /// The global path being followed (m, the map's frame); empty before the first step.
    pub fn path(&self) -> &[[f64; 2]] {
        &self.path
    }

    /// How many live obstacle cells are remembered.
    pub fn live_cells(&self) -> usize {
        self.live.len()
    }

    /// The live obstacles (to hand to the next navigator: [`Navigator::set_live`]).
    pub fn live(&self) -> &LiveObstacles {
        &self.live
    }

    /// Takes over live obstacles remembered elsewhere (another goal's navigator, or a layer
    /// kept while no goal ran), in place of its own; the path is planned again.
    pub fn set_live(&mut self, live: &LiveObstacles) -> Result<()> {
        self.live = live.resampled(self.live.resolution())?;
        self.replan = true;
        Ok(())
    }

    /// Replaces the map (a SLAM map that has grown, say), keeping the goal and the live
    /// obstacles; the path is planned again at the next step.
    pub fn set_map(&mut self, map: &OccupancyGrid) -> Result<()> {
        map.check()?;
        let map = map.grown_to(&[self.goal], 1.0)?;
        self.known = Obstacles::new(Vec::new(), Some(&map))?;
        self.map = map;
        self.replan = true;
        Ok(())
    }

    /// What a range sensor saw at time `now` (s) ([`Scan`]). Live cells inside its wedge (beyond
    /// `near`, nearer than `range`) that were not seen again are cleared; the seen ones are
    /// marked. Non-finite points are ignored; a scan whose pose or extent is not finite or out of
    /// range is an error.
    pub fn observe(&mut self, now: f64, scan: &Scan) -> Result<()> {
        let new = self
            .live
            .observe(now, scan, self.s.live_memory, Some(&self.map))?;
        if new.iter().any(|&p| self.path_blocked_by(p)) {
            self.replan = true;
        }
        Ok(())
    }

    /// Whether a live obstacle at `p` lies on the path ahead (within the radius).
    fn path_blocked_by(&self, p: [f64; 2]) -> bool {
        let from = self.along.min(self.path.len());
        self.path[from..]
            .windows(2)
            .any(|w| segment_distance(p, w[0], w[1]) < self.s.radius + 0.5 * self.map.resolution)
    }

    /// The clearance (m) of `p` from the map and the live obstacles (cells as squares' inner
    /// circles).
    pub fn clearance(&self, p: [f64; 2]) -> f64 {
        let r = self.live.resolution();
        let mut c = self.known.clearance(p);
        for q in self.live.centres() {
            c = c.min((q[0] - p[0]).hypot(q[1] - p[1]) - 0.5 * r);
        }
        c
    }

    /// The map with the live obstacles stamped in.
    fn costmap(&self) -> OccupancyGrid {
        let mut g = self.map.clone();
        let r = self.live.resolution();
        for q in self.live.centres() {
            g.fill_circle([q[0], q[1], 0.5 * r]);
        }
        g
    }

    /// Plans the path from `at` (m, the map's frame) at time `now` (s), as [`Navigator::step`]
    /// does when a plan is due; a caller may call it first to learn at once whether the goal
    /// can be reached ([`Error::NoPath`]). The start may be nearer an obstacle than the radius
    /// (a base pressed against something must still have its way out).
    pub fn plan(&mut self, now: f64, at: [f64; 2]) -> Result<()> {
        validate::finite("navigation start", &at)?;
        validate::finite("navigation time", &[now])?;
        let map = self.costmap().grown_to(&[at], 1.0)?;
        let field = Obstacles::new(Vec::new(), Some(&map))?;
        // The planner judges the start by its point and its cell's centre.
        let start_clear = map
            .cell(at)
            .map_or(0.0, |(i, j)| field.clearance(map.centre(i, j)))
            .min(field.clearance(at));
        let radius = self.s.radius.min(start_clear - 0.005).max(0.0);
        let planned = GridAStar.plan_with_margin(&map, at, self.goal, radius, self.s.margin);
        let path = match planned {
            Ok(p) => p,
            Err(Error::Blocked { what: "goal", .. }) => {
                return Err(Error::NoPath {
                    from: at,
                    to: self.goal,
                    radius: self.s.radius,
                })
            }
            Err(e) => return Err(e),
        };
        self.path = path.points;
        self.along = 0;
        self.planned_at = Some(now);
        self.replan = false;
        Ok(())
    }

    /// The way left along the path from the base's place, m, updating the segment it is at.
    fn way_left(&mut self, at: [f64; 2]) -> f64 {
        if self.path.len() < 2 {
            return (self.goal[0] - at[0]).hypot(self.goal[1] - at[1]);
        }
        // The nearest segment, searched a little way on from the last one (never back).
        let last = self.path.len() - 2;
        let mut best = (f64::INFINITY, self.along.min(last));
        for k in self.along.min(last)..=(self.along + 20).min(last) {
            let d = segment_distance(at, self.path[k], self.path[k + 1]);
            if d < best.0 - 1e-9 {
                best = (d, k);
            }
        }
        self.along = best.1;
        let k = self.along;
        let (a, b) = (self.path[k], self.path[k + 1]);
        let t = project(at, a, b);
        let mut left = (1.0 - t) * dist(a, b) + best.0;
        for w in self.path[k + 1..].windows(2) {
            left += dist(w[0], w[1]);
        }
        left
    }

    /// The point `ahead` m along the path from the base's projection on it.
    fn carrot(&self, at: [f64; 2], ahead: f64) -> [f64; 2] {
        if self.path.len() < 2 {
            return self.goal;
        }
        let k = self.along.min(self.path.len() - 2);
        let (a, b) = (self.path[k], self.path[k + 1]);
        let t = project(at, a, b);
        let mut from = lerp(a, b, t);
        let mut left = ahead;
        for w in self.path[k + 1..].iter() {
            let d = dist(from, *w);
            if d >= left {
                return lerp(from, *w, left / d);
            }
            left -= d;
            from = *w;
        }
        self.goal
    }

    /// Whether driving `(v, ω)` from `x` keeps the body clear for the check time or until it
    /// has gone its stopping distance and 0.1 m more, whichever comes first.
    fn arc_is_clear(&self, x: [f64; 3], v: f64, w: f64) -> bool {
        let h = 0.05;
        let n = (self.s.check_time / h).ceil() as usize;
        let reach = v * v / (2.0 * self.s.limits.accel_v) + 0.1;
        let mut p = x;
        let now = self.clearance([x[0], x[1]]);
        for k in 0..n {
            if v.abs() * h * k as f64 > reach {
                break;
            }
            p = step(p, [v, w], h);
            let c = self.clearance([p[0], p[1]]);
            // Moving nearer to something already inside the footprint is a touch; moving away
            // from it is the way out.
            if c < self.s.radius && c < now - 1e-4 {
                return false;
            }
        }
        true
    }

    /// `(v, ω)` bounded by the limits and by the accelerations from the last command.
    fn limited(&self, v: f64, w: f64) -> (f64, f64) {
        let l = &self.s.limits;
        let dt = self.s.dt;
        let v = v.clamp(-l.v, l.v);
        let w = w.clamp(-l.w, l.w);
        let v = self.last.0 + (v - self.last.0).clamp(-l.accel_v * dt, l.accel_v * dt);
        let w = self.last.1 + (w - self.last.1).clamp(-l.accel_w * dt, l.accel_w * dt);
        (v, w)
    }

    /// One control step at time `now` (s) with the base at `x` (`[x, y, θ]`, m and rad, the
    /// map's frame). Steps closer together than the control period repeat the last command.
    /// Errors: no path to the goal ([`Error::NoPath`]), no progress after every recovery
    /// ([`Error::Stalled`]), a pose or time that is not finite.
    pub fn step(&mut self, now: f64, x: [f64; 3]) -> Result<NavCommand> {
        validate::finite("navigation pose", &x)?;
        validate::finite("navigation time", &[now])?;
        if let Some(t) = self.stepped {
            if now < t + self.s.dt - 1e-9 && now >= t {
                return Ok(NavCommand::Drive(self.last.0, self.last.1));
            }
        }
        self.stepped = Some(now);
        let at = [x[0], x[1]];
        if dist(at, self.goal) < self.s.goal_tolerance {
            self.last = (0.0, 0.0);
            return Ok(NavCommand::Arrived);
        }
        if self.progress.0.is_infinite() {
            self.progress.1 = now;
        }
        // A streak of recoveries ends once the base has got well away from where it began (as
        // move_base's oscillation distance): backing up and coming back is no way out.
        if self
            .streak_from
            .is_some_and(|p| dist(p, at) >= STREAK_DISTANCE)
        {
            self.streak_from = None;
            self.recoveries = 0;
        }
        if let Some(r) = self.recovering {
            if let Some(u) = self.recover(r, x, now) {
                return Ok(self.send(u));
            }
            self.recovering = None;
            self.replan = true;
            self.progress.1 = now;
        }
        if self.replan
            || self
                .planned_at
                .is_none_or(|t| now - t >= self.s.replan_period)
        {
            match self.plan(now, at) {
                Ok(()) => self.looked_round = false,
                // Blocked by what the camera saw: look all round once (what has gone is
                // cleared as it comes into view), then judge again.
                Err(Error::NoPath { .. }) if !self.looked_round && self.live_cells() > 0 => {
                    self.looked_round = true;
                    let r = Recovery::Turn {
                        turned: 0.0,
                        last: x[2],
                    };
                    self.start_recovery(r, now);
                    if let Some(u) = self.recover(r, x, now) {
                        return Ok(self.send(u));
                    }
                }
                Err(e) => return Err(e),
            }
        }
        let left = self.way_left(at);
        if left < self.progress.0 - PROGRESS_STEP {
            self.progress = (left, now);
        } else if now - self.progress.1 > self.s.stall_time {
            if self.recoveries >= self.s.max_recoveries {
                return Err(Error::Stalled {
                    at,
                    left,
                    recoveries: self.recoveries,
                });
            }
            self.recoveries += 1;
            self.streak_from.get_or_insert(at);
            self.progress = (left, now);
            // Back up first when the way behind is clear, then turn all round, in turn.
            let r = if self.recoveries % 2 == 1 && self.arc_is_clear(x, -0.1, 0.0) {
                Recovery::BackUp { from: at }
            } else {
                Recovery::Turn {
                    turned: 0.0,
                    last: x[2],
                }
            };
            self.start_recovery(r, now);
            if let Some(u) = self.recover(r, x, now) {
                return Ok(self.send(u));
            }
        }
        // The path pursued as usual; where that arc would touch (it cuts a corner the path
        // turns close by), the path followed tightly.
        for (ahead, turn) in [(self.s.lookahead, 0.6), (TIGHT_LOOKAHEAD, 0.3)] {
            let u = self.pursue(x, ahead, turn);
            if self.arc_is_clear(x, u.0, u.1) {
                return Ok(self.send(u));
            }
        }
        // Blocked ahead: stop, turning in place along the path (which a round base may always
        // do), and plan anew.
        self.replan = true;
        let u = self.pursue(x, TIGHT_LOOKAHEAD, 0.0);
        self.last = (0.0, u.1);
        Ok(NavCommand::Drive(0.0, u.1))
    }

    /// Records and returns a command.
    fn send(&mut self, u: (f64, f64)) -> NavCommand {
        self.last = u;
        NavCommand::Drive(u.0, u.1)
    }

    /// Starts recovery `r` at `now`: it gets as long as it should take and
    /// [`RECOVERY_SLACK`] more (a base that cannot move does not hold it for ever).
    fn start_recovery(&mut self, r: Recovery, now: f64) {
        let l = &self.s.limits;
        let takes = match r {
            Recovery::BackUp { .. } => self.s.backup / 0.1f64.min(l.v),
            Recovery::Turn { .. } => 2.0 * std::f64::consts::PI / l.w,
        };
        self.recovering = Some(r);
        self.recovery_until = now + takes + RECOVERY_SLACK;
    }

    /// The recovery's next command at `now`, `None` once it is done.
    fn recover(&mut self, r: Recovery, x: [f64; 3], now: f64) -> Option<(f64, f64)> {
        if now >= self.recovery_until {
            return None;
        }
        match r {
            Recovery::BackUp { from } => {
                let gone = dist(from, [x[0], x[1]]);
                let u = self.limited(-0.1f64.min(self.s.limits.v), 0.0);
                (gone < self.s.backup && self.arc_is_clear(x, u.0, 0.0)).then_some(u)
            }
            Recovery::Turn { turned, last } => {
                // Signed: a pose's jitter cancels out.
                let turned = turned + wrap(x[2] - last);
                self.recovering = Some(Recovery::Turn { turned, last: x[2] });
                (turned.abs() < 2.0 * std::f64::consts::PI)
                    .then(|| self.limited(0.0, self.s.limits.w))
            }
        }
    }

    /// Regulated pure pursuit of the path from `x`.
    /// The point pursued lies `lookahead` m along the path; facing more than `turn` rad away
    /// from it, the base turns in place.
    fn pursue(&self, x: [f64; 3], lookahead: f64, turn: f64) -> (f64, f64) {
        let l = &self.s.limits;
        let at = [x[0], x[1]];
        let to_goal = dist(at, self.goal);
        let ahead = lookahead.min(to_goal);
        let c = self.carrot(at, ahead);
        let (dx, dy) = (c[0] - x[0], c[1] - x[1]);
        let alpha = wrap(dy.atan2(dx) - x[2]);
        // Facing away: turn in place towards the path.
        if alpha.abs() > turn {
            let w = (1.5 * alpha).clamp(-l.w, l.w);
            return self.limited(0.0, w);
        }
        let ld = dx.hypot(dy).max(1e-3);
        let kappa = 2.0 * alpha.sin() / ld;
        let mut v = l.v;
        // Tight arcs slow down (radius under 0.5 m).
        if kappa.abs() > 2.0 {
            v *= 2.0 / kappa.abs();
        }
        // Near obstacles slow down.
        let room = self.clearance(at) - self.s.radius;
        if room < 0.15 {
            v *= (room / 0.15).clamp(0.4, 1.0);
        }
        // Able to stop at the goal.
        v = v.min((2.0 * l.accel_v * to_goal).sqrt()).max(0.03);
        let mut w = v * kappa;
        if w.abs() > l.w {
            v *= l.w / w.abs();
            w = w.signum() * l.w;
        }
        self.limited(v, w)
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

fn lerp(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
}

/// Where `p` projects on segment `ab`, as a fraction of it in [0, 1].
fn project(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (ux, uy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = ux * ux + uy * uy;
    if len2 <= 1e-18 {
        return 0.0;
    }
    (((p[0] - a[0]) * ux + (p[1] - a[1]) * uy) / len2).clamp(0.0, 1.0)
}

/// Distance from `p` to segment `ab`, m.
fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    dist(p, lerp(a, b, project(p, a, b)))
}
