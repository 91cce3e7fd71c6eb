//! The base on a map: navigation to a goal with the global planner, live obstacles and
//! recovery ([`crate::navigate`]), and exploration with SLAM until no frontier is left.

use std::time::Duration;

use ferrobot_nav::{NavSettings, Navigator};

use crate::base::{Base, GoalOptions};
use crate::error::Result;
use crate::motion::Motion;
use crate::nav::{Obstacles, OccupancyGrid};
use crate::navigate::NavGoal;
use crate::slam_runner::Source;
use crate::validate;

impl Base {
    /// The robot's radius for the navigator, m: the base's footprint radius, or how far the arm
    /// reaches across the floor now ([`crate::Arm::reach`]) where it sticks out further.
    fn nav_radius(&self) -> Result<f64> {
        Ok(self.section().footprint_radius.max(self.robot.arm_reach()?))
    }

    /// A goal on a map, driven by the navigator (see [`GoalOptions::map`]).
    pub(crate) fn navigate(&self, goal: [f64; 3], opts: &GoalOptions) -> Result<Motion> {
        let slam = opts.use_map || opts.frame == Source::Slam;
        let here = self.get_state_from(if slam { Source::Slam } else { Source::Odometry })?;
        validate::base_goal(goal, here)?;
        let radius = self.nav_radius()?;
        let lim = self.tracking_limits();
        let grid = match (&opts.map, opts.use_map) {
            (Some(m), _) => m.clone(),
            (None, _) => match self.robot.slam_occupancy_map()? {
                Some(image) => image.to_grid(false)?,
                // Nothing mapped yet: all unknown, hence free.
                None => OccupancyGrid::new([here[0], here[1]], 0.02, 1, 1)?,
            },
        };
        // The map and the circles are checked before the circles are stamped into it.
        grid.check()?;
        Obstacles::new(opts.obstacles.clone(), None)?;
        let map = NavGoal::stamped(&grid, &opts.obstacles)?;
        let mut nav = Navigator::new(&map, [goal[0], goal[1]], NavSettings::new(radius, lim))?;
        let scans = opts.live_obstacles && self.robot.config().camera.is_some();
        if scans {
            // What the last goal's camera saw counts from the start.
            if let Some(live) = self.robot.lock_hub().sense.live_for(slam) {
                nav.set_live(&live)?;
            }
        }
        // A goal no path reaches (another room behind closed doors, an island) is a typed
        // error now, not a failure later: the navigator's first plan, made here. Beyond the
        // map's edge is unknown, so free (as move_base's allow_unknown). When what blocks the
        // way is only what the camera saw before, the navigator looks again first.
        let now = self.now().as_secs_f64();
        match nav.plan(now, [here[0], here[1]]) {
            Err(ferrobot_nav::Error::NoPath { .. }) if nav.live_cells() > 0 => {
                // Blocked by the map itself: refused now.
                let mut bare = nav.clone();
                bare.set_live(&ferrobot_nav::LiveObstacles::new(map.resolution)?)?;
                bare.plan(now, [here[0], here[1]])?;
            }
            r => r?,
        }
        if scans {
            let eyes = self.robot.eyes()?;
            self.robot.lock_hub().sense.camera = Some(eyes);
        }
        // The heading stage's controller within the window's (tracking) limits.
        let finish = self.proportional(goal).with_speed_limits(lim.v, lim.w);
        let g = NavGoal {
            nav,
            goal,
            slam,
            slam_grid: opts.use_map && opts.map.is_none(),
            circles: opts.obstacles.clone(),
            scans,
            seen: (0, 0),
            finish,
            finishing: false,
            lost_since: None,
            hold_ms: 250,
        };
        let dist = (goal[0] - here[0]).hypot(goal[1] - here[1]);
        // Room for detours and every recovery.
        let timeout = Duration::from_secs_f64(120.0 + 6.0 * dist / lim.v);
        self.start(Box::new(g), "base position goal (navigator)", timeout)
    }
}

/// Longest an exploration may take, s of the robot's clock.
pub const EXPLORE_TIMEOUT: Duration = Duration::from_secs(1800);

impl Base {
    /// Explores with SLAM until no reachable frontier is left (see [`crate::navigate`]): the
    /// base looks all round, then drives to the nearest frontier of SLAM's occupancy grid and
    /// faces it, again and again, avoiding what the depth camera sees. Needs SLAM running
    /// ([`crate::Robot::start_slam`]); the map is then [`crate::Robot::slam_occupancy_map`]. Fails
    /// after [`EXPLORE_TIMEOUT`], or when SLAM has no pose for [`crate::navigate::SLAM_PATIENCE`].
    pub fn explore_async(&self) -> Result<Motion> {
        // SLAM must run (its pose may come with the first frames).
        self.robot.slam_report()?;
        if self.robot.config().camera.is_none() {
            return Err(self.robot.missing("camera"));
        }
        let eyes = self.robot.eyes()?;
        self.robot.lock_hub().sense.camera = Some(eyes);
        let radius = self.nav_radius()?;
        let live = self.robot.lock_hub().sense.live_for(true);
        let g = crate::navigate::ExploreGoal::new(
            NavSettings::new(radius, self.tracking_limits()),
            ferrobot_nav::FrontierSettings::new(radius),
            ferrobot_slam::GridSettings::default().resolution,
            live,
        )?;
        self.start(Box::new(g), "exploration", EXPLORE_TIMEOUT)
    }

    /// As [`Base::explore_async`], waiting until it is done.
    pub fn explore(&self) -> Result<()> {
        self.explore_async()?.wait()
    }
}
