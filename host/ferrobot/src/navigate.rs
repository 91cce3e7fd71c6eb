//! Goals on a map: the base driven by [`ferrobot_nav::Navigator`] (global plan, path
//! following, live obstacles from the depth camera, re-planning, recovery), steered by SLAM's
//! pose when the goal is in SLAM's map. The last few centimetres and the goal's heading are the
//! proportional controller's, in the odometry's frame.
//!
//! Exploration ([`crate::base::Base::explore`]): look all round, then again and again drive to the nearest
//! frontier of SLAM's growing map ([`ferrobot_nav::frontiers`]) and face it, until no frontier
//! the base can reach is left. A frontier seen from afar on the way is given up for the next;
//! one the navigator cannot reach is marked failed and not offered again.
//!
//! The live obstacles the camera saw outlive each navigator: exploration hands them from one
//! frontier's navigator to the next and keeps them while it looks about, and the robot keeps the
//! last goal's for the next goal in the same frame (an obstacle seen on the way in is still
//! there when the base, standing next to it and too near to see it, sets off again).

use std::time::Duration;

use ferrobot_geometry::Pose2;
use ferrobot_nav::{
    frontiers, Frontier, FrontierSettings, LiveObstacles, MapImage, NavCommand, NavSettings,
    Navigator, OccupancyGrid,
};

use crate::base::BASE_CONTROL_PERIOD;
use crate::base_goals::odometry_pose;
use crate::error::{Error, Result};
use crate::goals::{Goal, Step};
use ferrobot_control::laws::Proportional;

/// How long a SLAM-steered goal may go without a SLAM pose before it fails.
pub const SLAM_PATIENCE: Duration = Duration::from_secs(10);

/// Notes since when SLAM has had no pose (`lost_since`, cleared by the caller once it has
/// one); once that is longer than [`SLAM_PATIENCE`], stops the base and returns the error,
/// saying what cannot go on (`what`).
fn out_of_patience(
    lost_since: &mut Option<Duration>,
    s: &mut Step<'_>,
    what: &str,
) -> Option<Error> {
    let since = *lost_since.get_or_insert(s.now);
    (s.now.saturating_sub(since) > SLAM_PATIENCE).then(|| {
        crate::base_goals::stop_base(s.link);
        Error::Usage(format!(
            "SLAM has had no pose for {SLAM_PATIENCE:?}: {what}"
        ))
    })
}

/// A position goal on a map.
pub(crate) struct NavGoal {
    pub(crate) nav: Navigator,
    /// The goal `[x, y, θ]` in the map's frame.
    pub(crate) goal: [f64; 3],
    /// Whether poses come through SLAM's correction (the map is SLAM's).
    pub(crate) slam: bool,
    /// Whether the map is SLAM's growing occupancy grid (refreshed as it grows).
    pub(crate) slam_grid: bool,
    /// Round obstacles stamped into every map, `[x, y, r]` m.
    pub(crate) circles: Vec<[f64; 3]>,
    /// Whether the camera's obstacle scans are used.
    pub(crate) scans: bool,
    /// The last scan and grid taken in.
    pub(crate) seen: (u64, u64),
    /// The heading stage, once the position is reached (its goal in the odometry's frame).
    pub(crate) finish: Proportional,
    pub(crate) finishing: bool,
    /// Since when SLAM has had no pose.
    pub(crate) lost_since: Option<Duration>,
    pub(crate) hold_ms: u16,
}

impl NavGoal {
    /// `grid`, grown to hold every round obstacle (a circle beyond the map, or every circle
    /// before SLAM has mapped anything, was lost), with them stamped in.
    pub(crate) fn stamped(
        grid: &OccupancyGrid,
        circles: &[[f64; 3]],
    ) -> ferrobot_nav::Result<OccupancyGrid> {
        let corners: Vec<[f64; 2]> = circles
            .iter()
            .flat_map(|c| [[c[0] - c[2], c[1] - c[2]], [c[0] + c[2], c[1] + c[2]]])
            .collect();
        let mut g = grid.grown_to(&corners, 0.0)?;
        for &c in circles {
            g.fill_circle(c);
        }
        Ok(g)
    }

    fn drive(&mut self, s: &mut Step<'_>, v: f64, w: f64) -> Option<Result<()>> {
        crate::base_goals::send_logged(s, v, w, self.hold_ms)
    }
}

impl Goal for NavGoal {
    fn claim(&self) -> crate::goals::Claim {
        crate::base_goals::BASE
    }

    fn wants_scans(&self) -> bool {
        self.scans && !self.finishing
    }

    fn wants_grid(&self) -> bool {
        self.slam_grid && !self.finishing
    }

    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>> {
        let odometry = odometry_pose(s.telemetry);
        if self.finishing {
            return match self.finish.step(s.now, odometry_pose(s.telemetry)) {
                Some((v, w)) => self.drive(s, v, w),
                None => {
                    crate::base_goals::stop_base(s.link);
                    Some(Ok(()))
                }
            };
        }
        let Some(pose) = s.sense.in_map(odometry, self.slam) else {
            // No SLAM pose: stand still and wait for one.
            if let Some(e) = out_of_patience(
                &mut self.lost_since,
                s,
                "the goal in its map cannot be steered to",
            ) {
                return Some(Err(e));
            }
            return self.drive(s, 0.0, 0.0);
        };
        self.lost_since = None;
        if self.slam_grid {
            if let Some((n, g)) = &s.sense.grid {
                if *n != self.seen.1 {
                    self.seen.1 = *n;
                    let set = g
                        .to_grid(false)
                        .and_then(|g| Self::stamped(&g, &self.circles))
                        .and_then(|m| self.nav.set_map(&m));
                    if let Err(e) = set {
                        return Some(Err(e.into()));
                    }
                }
            }
        }
        if self.scans {
            if let Some((n, t, scan)) = &s.sense.scan {
                if *n != self.seen.0 {
                    self.seen.0 = *n;
                    // A scan in the map's frame; one that cannot be taken in is skipped.
                    let _ = self.nav.observe(*t, scan);
                }
            }
        }
        match self.nav.step(s.now.as_secs_f64(), pose.to_array()) {
            Ok(NavCommand::Drive(v, w)) => self.drive(s, v, w),
            Ok(NavCommand::Arrived) => {
                if self.scans {
                    s.sense.keep_live(self.slam, self.nav.live());
                }
                // The last stretch and the heading in the odometry's frame, where the wheels
                // are: the goal carried there by the present correction.
                let to_odom = pose.compose(&Pose2::from(odometry).inverse()).inverse();
                self.finish
                    .retarget(to_odom.compose(&Pose2::from(self.goal)).to_array(), s.now);
                self.finishing = true;
                self.step(s)
            }
            Err(e) => {
                if self.scans {
                    s.sense.keep_live(self.slam, self.nav.live());
                }
                crate::base_goals::stop_base(s.link);
                Some(Err(e.into()))
            }
        }
    }

    fn halt(&mut self, link: &mut dyn crate::backend::Link) {
        crate::base_goals::stop_base(link);
    }
}

/// Turning speed while looking about, rad/s: slow enough for SLAM to track (a degree a frame
/// at 30 frames a second).
const LOOK_RATE: f64 = 0.4;
/// Largest number of frontiers visited before exploration stops.
pub const MAX_FRONTIERS: usize = 200;

/// What exploration is doing.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Explore {
    /// Turning all round where it stands: `turned` rad so far, the heading last seen.
    Look { turned: f64, last: f64 },
    /// Waiting for a grid newer than this, then choosing the nearest frontier.
    Choose { after: u64 },
    /// Driving to a frontier's view point.
    Go,
    /// Turning to face the frontier (rad).
    Face { heading: f64 },
}

/// Frontier-based exploration on SLAM's growing map (see [`crate::base::Base::explore`]).
pub(crate) struct ExploreGoal {
    pub(crate) settings: NavSettings,
    pub(crate) frontier: FrontierSettings,
    state: Explore,
    nav: Option<Navigator>,
    /// The live obstacles while no navigator holds them (between frontiers, looking about).
    live: LiveObstacles,
    target: Option<Frontier>,
    seen: (u64, u64),
    visited: usize,
    /// Frontiers looked at: their centroid and how often.
    looked: Vec<([f64; 2], u32)>,
    last: (f64, f64),
    /// When exploration's own next command is due (between, the last is sent again).
    next: Duration,
    lost_since: Option<Duration>,
}

impl ExploreGoal {
    /// Exploration with the navigator's `settings`, frontiers chosen by `frontier`, live
    /// obstacles kept in cells of `resolution` m (SLAM's grid's), starting from those an earlier
    /// goal saw (`live`).
    pub(crate) fn new(
        settings: NavSettings,
        frontier: FrontierSettings,
        resolution: f64,
        live: Option<LiveObstacles>,
    ) -> Result<Self> {
        let live = match live {
            Some(l) => l.resampled(resolution)?,
            None => LiveObstacles::new(resolution)?,
        };
        Ok(ExploreGoal {
            settings,
            frontier,
            state: Explore::Look {
                turned: 0.0,
                last: f64::NAN,
            },
            nav: None,
            live,
            target: None,
            seen: (0, 0),
            visited: 0,
            looked: Vec::new(),
            last: (0.0, 0.0),
            next: Duration::ZERO,
            lost_since: None,
        })
    }

    /// Ends exploration with `result`: the base stops, the live obstacles are kept for the
    /// goals that follow.
    fn end(&mut self, s: &mut Step<'_>, result: Result<()>) -> Option<Result<()>> {
        self.drop_nav();
        s.sense.keep_live(true, &self.live);
        crate::base_goals::stop_base(s.link);
        Some(result)
    }

    /// Ends the navigator under way, keeping what it remembers of the live obstacles.
    fn drop_nav(&mut self) {
        if let Some(nav) = self.nav.take() {
            self.live = nav.live().clone();
        }
    }

    /// `(v, ω)` under the limits' accelerations from the last command (one control period
    /// before), sent.
    fn send(&mut self, s: &mut Step<'_>, v: f64, w: f64) -> Option<Result<()>> {
        let l = &self.settings.limits;
        let dt = BASE_CONTROL_PERIOD.as_secs_f64();
        self.next = s.now + BASE_CONTROL_PERIOD;
        let v = self.last.0 + (v - self.last.0).clamp(-l.accel_v * dt, l.accel_v * dt);
        let w = self.last.1 + (w - self.last.1).clamp(-l.accel_w * dt, l.accel_w * dt);
        self.last = (v, w);
        crate::base_goals::send_logged(s, v, w, 250)
    }

    /// The nearest frontier on `map` from `at`, with a navigator to its view point; `None`
    /// when no frontier is left. Frontiers whose view point the navigator refuses are marked
    /// failed and the next is taken.
    fn choose(&mut self, map: &MapImage, at: [f64; 2]) -> Result<Option<(Frontier, Navigator)>> {
        let grid = map.to_grid(false)?;
        loop {
            let Some(f) = frontiers(map, at, &self.frontier)?.into_iter().next() else {
                return Ok(None);
            };
            match Navigator::new(&grid, f.view_point, self.settings.clone()) {
                Ok(n) => return Ok(Some((f, n))),
                Err(_) => self.frontier.failed.push(f.view_point),
            }
        }
    }
}

impl ExploreGoal {
    /// What the camera sees goes to the navigator under way, else to the layer kept.
    fn take_scan(&mut self, s: &mut Step<'_>) {
        if let Some((n, t, scan)) = &s.sense.scan {
            if *n != self.seen.0 {
                self.seen.0 = *n;
                let _ = match self.nav.as_mut() {
                    Some(nav) => nav.observe(*t, scan),
                    None => self
                        .live
                        .observe(*t, scan, self.settings.live_memory, None)
                        .map(|_| ()),
                };
            }
        }
    }

    /// Turning in place once round, looking.
    fn look(
        &mut self,
        s: &mut Step<'_>,
        turned: f64,
        last: f64,
        x: [f64; 3],
    ) -> Option<Result<()>> {
        // Signed: the pose's jitter cancels out.
        let turned = if last.is_nan() {
            0.0
        } else {
            turned + ferrobot_geometry::wrap(x[2] - last)
        };
        if turned.abs() >= 2.0 * std::f64::consts::PI {
            self.state = Explore::Choose {
                after: s.sense.grid.as_ref().map_or(0, |g| g.0),
            };
            return self.send(s, 0.0, 0.0);
        }
        self.state = Explore::Look { turned, last: x[2] };
        self.send(s, 0.0, LOOK_RATE.min(self.settings.limits.w))
    }

    /// Choosing the next frontier once SLAM's grid is newer than `after`.
    fn choose_next(&mut self, s: &mut Step<'_>, after: u64, x: [f64; 3]) -> Option<Result<()>> {
        let Some((n, map)) = s.sense.grid.as_ref().filter(|g| g.0 > after) else {
            return self.send(s, 0.0, 0.0);
        };
        self.seen.1 = *n;
        let map = map.clone();
        if self.visited >= MAX_FRONTIERS {
            return self.end(s, Ok(()));
        }
        match self.choose(&map, [x[0], x[1]]) {
            Ok(Some((f, mut nav))) => {
                if let Err(e) = nav.set_live(&self.live) {
                    return self.end(s, Err(e.into()));
                }
                self.target = Some(f);
                self.nav = Some(nav);
                self.state = Explore::Go;
                self.send(s, 0.0, 0.0)
            }
            // Nothing left to see: done.
            Ok(None) => self.end(s, Ok(())),
            Err(e) => self.end(s, Err(e)),
        }
    }

    /// Driving to the frontier's view point with the navigator, following newer maps.
    fn go(&mut self, s: &mut Step<'_>, x: [f64; 3], now: f64) -> Option<Result<()>> {
        let (Some(nav), Some(target)) = (self.nav.as_mut(), self.target.clone()) else {
            self.state = Explore::Choose { after: 0 };
            return self.send(s, 0.0, 0.0);
        };
        // A newer map: follow it, and give the frontier up when it is seen already.
        if let Some((n, map)) = &s.sense.grid {
            if *n != self.seen.1 {
                self.seen.1 = *n;
                let still = frontiers(map, [x[0], x[1]], &self.frontier)
                    .map(|fs| {
                        fs.iter().any(|f| {
                            (f.centroid[0] - target.centroid[0])
                                .hypot(f.centroid[1] - target.centroid[1])
                                < 0.5
                        })
                    })
                    .unwrap_or(false);
                if !still {
                    self.drop_nav();
                    self.state = Explore::Choose { after: *n - 1 };
                    return self.send(s, 0.0, 0.0);
                }
                if let Ok(g) = map.to_grid(false) {
                    let _ = nav.set_map(&g);
                }
            }
        }
        match nav.step(now, x) {
            Ok(NavCommand::Drive(v, w)) => {
                // The navigator limits its own commands.
                self.last = (v, w);
                crate::base_goals::send_logged(s, v, w, 250)
            }
            Ok(NavCommand::Arrived) => {
                self.visited += 1;
                self.drop_nav();
                self.state = Explore::Face {
                    heading: target.heading,
                };
                self.send(s, 0.0, 0.0)
            }
            Err(_) => {
                // This frontier cannot be reached from here: the next one.
                self.frontier.failed.push(target.view_point);
                self.drop_nav();
                self.state = Explore::Choose { after: 0 };
                self.send(s, 0.0, 0.0)
            }
        }
    }

    /// Facing the frontier from its view point, then choosing again.
    fn face(&mut self, s: &mut Step<'_>, heading: f64, x: [f64; 3]) -> Option<Result<()>> {
        let e = ferrobot_geometry::wrap(heading - x[2]);
        if e.abs() < 0.1 {
            // Looked: what the camera sees now enters the map. A frontier looked at
            // three times and still there (beyond what the camera can tell) is left.
            s.sense.want_keyframe.set(true);
            if let Some(t) = &self.target {
                self.frontier.failed.push(t.view_point);
                let c = t.centroid;
                match self
                    .looked
                    .iter_mut()
                    .find(|(p, _)| (p[0] - c[0]).hypot(p[1] - c[1]) < 0.5)
                {
                    Some((_, n)) => {
                        *n += 1;
                        if *n >= 3 {
                            self.frontier.done.push(c);
                        }
                    }
                    None => self.looked.push((c, 1)),
                }
            }
            self.state = Explore::Choose {
                after: s.sense.grid.as_ref().map_or(0, |g| g.0),
            };
            return self.send(s, 0.0, 0.0);
        }
        let w = (1.5 * e).clamp(-LOOK_RATE, LOOK_RATE);
        self.send(s, 0.0, w)
    }
}

impl Goal for ExploreGoal {
    fn claim(&self) -> crate::goals::Claim {
        crate::base_goals::BASE
    }

    fn wants_scans(&self) -> bool {
        true
    }

    fn wants_grid(&self) -> bool {
        true
    }

    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>> {
        // Between control periods the last command holds (the navigator keeps its own).
        if s.now < self.next && self.nav.is_none() {
            return crate::base_goals::send_logged(s, self.last.0, self.last.1, 250);
        }
        let odometry = odometry_pose(s.telemetry);
        let Some(pose) = s.sense.in_map(odometry, true) else {
            if let Some(e) = out_of_patience(&mut self.lost_since, s, "exploration cannot go on") {
                return Some(Err(e));
            }
            return self.send(s, 0.0, 0.0);
        };
        self.lost_since = None;
        let x = pose.to_array();
        let now = s.now.as_secs_f64();
        self.take_scan(s);
        match self.state {
            Explore::Look { turned, last } => self.look(s, turned, last, x),
            Explore::Choose { after } => self.choose_next(s, after, x),
            Explore::Go => self.go(s, x, now),
            Explore::Face { heading } => self.face(s, heading, x),
        }
    }

    fn halt(&mut self, link: &mut dyn crate::backend::Link) {
        crate::base_goals::stop_base(link);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Round obstacles beyond the map (or on the one-cell map used before SLAM has mapped
    /// anything) are kept: the map grows to hold them (they were clipped away before).
    #[test]
    fn circles_beyond_the_map_grow_it() {
        let tiny = OccupancyGrid::new([0.0, 0.0], 0.02, 1, 1).expect("grid");
        let map = NavGoal::stamped(&tiny, &[[1.0, 0.5, 0.1], [-0.6, -0.2, 0.05]]).expect("grown");
        assert!(map.is_occupied([1.0, 0.5]) && map.is_occupied([-0.6, -0.2]));
        assert!(!map.is_occupied([0.5, 0.5]));
        assert_eq!(map.resolution, 0.02);
        // Far beyond any map: an error, not a grid of 10¹⁸ cells.
        assert!(NavGoal::stamped(&tiny, &[[1e12, 0.0, 0.1]]).is_err());
    }
}
