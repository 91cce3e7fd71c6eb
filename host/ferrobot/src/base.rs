//! The mobile base: velocity commands, position goals, odometry. Poses are `[x, y, θ]` (m, m,
//! rad) in the odometry frame (x forward at the last odometry reset, y left, θ counter-
//! clockwise). A bumper, cliff or wheel-drop event aborts a motion with an error that names the
//! sensor.

use std::time::Duration;

use ferrobot_protocol::HostMsg;

use crate::base_control::{ilqr, Dwa, Limits, LqrTracker, NavField, Reference};
use crate::config::BaseController;
use crate::error::{check_finite, Error, Result};
use crate::validate;
pub use ferrobot_control::laws::{
    gains, CONTROL_PERIOD as BASE_CONTROL_PERIOD, FINISH_TOL_LATERAL, FINISH_TOL_TH, FINISH_TOL_XY,
};
use ferrobot_control::laws::{Finisher, Proportional, Tracking, FINISH_TIME};
use ferrobot_geometry::Pose2;

/// A relative base goal: finite, at most [`validate::MAX_BASE_GOAL_DISTANCE`] away, a turn
/// within ±[`validate::MAX_ANGLE`].
fn check_relative(delta: [f64; 3]) -> Result<()> {
    check_finite("base goal", &delta)?;
    validate::in_range(
        "base goal distance",
        delta[0].hypot(delta[1]),
        0.0,
        validate::MAX_BASE_GOAL_DISTANCE,
    )?;
    Ok(validate::angles("base goal heading", &delta[2..])?)
}
use crate::base_goals::{
    DwaGoal, LawGoal, TrackGoal, TrackThenFinish, VelocityGoal, BASE, DWA_PATH_MARGIN,
};
pub use crate::base_navigation::EXPLORE_TIMEOUT;
use crate::goals::Goal;
use crate::hub::Hub;
use crate::motion::Motion;
use crate::nav::{Circle, Obstacles, OccupancyGrid};
use crate::odometry_calibration::WheelGeometry;
use crate::robot::Robot;
use crate::slam_runner::Source;

/// The sample period of the references the LQR controllers track to a position goal, s
/// (PyRobot's 10 Hz base control rate).
pub const REFERENCE_DT: f64 = 0.1;

/// The smooth reference's Bézier control-point distance along the start and goal headings, m
/// ([`ferrobot_control::trajectory::Reference::smooth`]'s `arm`).
pub const SMOOTH_ARM: f64 = 0.8;

/// How a position goal is reached.
#[derive(Debug, Clone, PartialEq)]
pub struct GoalOptions {
    /// The controller; the configuration's default when `None`.
    pub controller: Option<BaseController>,
    /// LQR: a smooth (Bézier) reference instead of rotate-drive-rotate.
    pub smooth: bool,
    /// LQR: correct from odometry (true) or play the reference open loop.
    pub close_loop: bool,
    /// Circular obstacles `[x, y, r]` (m) in the odometry frame. With obstacles or a map and no
    /// explicit controller, the dynamic window approach is used.
    pub obstacles: Vec<Circle>,
    /// An occupancy-grid map (in the frame `frame` names). With a map the base is driven by
    /// the navigator ([`ferrobot_nav::Navigator`]: global plan, path following, re-planning,
    /// recovery), the round obstacles stamped into it. The navigator's robot radius is the
    /// base's footprint radius, or the arm's reach ([`crate::arm::Arm::reach`]) when the arm sticks
    /// out further: [`crate::arm::Arm::stow`] folds it in before a long drive.
    pub map: Option<OccupancyGrid>,
    /// The frame of the goal, the map and the obstacles: the odometry's, or SLAM's map (the
    /// base then steers by SLAM's pose; SLAM must be running, see
    /// [`crate::Robot::start_slam`]).
    pub frame: Source,
    /// Plan on SLAM's occupancy grid, refreshed as it grows (PyRobot's `use_map`): the frame
    /// is then SLAM's map, whatever `frame` says, and `map`, when given, is used instead.
    pub use_map: bool,
    /// With a map: avoid what the depth camera sees too (when the robot has a camera).
    pub live_obstacles: bool,
}

impl Default for GoalOptions {
    fn default() -> Self {
        GoalOptions {
            controller: None,
            smooth: false,
            close_loop: true,
            obstacles: Vec::new(),
            map: None,
            frame: Source::Odometry,
            use_map: false,
            live_obstacles: true,
        }
    }
}

/// The base of a [`Robot`]: a handle (clone of the robot's), so base motions run while other
/// components move.
#[derive(Clone, Debug)]
pub struct Base {
    pub(crate) robot: Robot,
}

impl Base {
    pub(crate) fn new(robot: Robot) -> Self {
        Base { robot }
    }

    /// Put a base goal under way (preempting a base motion under way).
    pub(crate) fn start(
        &self,
        goal: Box<dyn Goal>,
        what: &str,
        timeout: Duration,
    ) -> Result<Motion> {
        self.robot
            .start_motion(BASE, what, |_io: &mut Hub| Ok((goal, timeout)))
    }

    /// The backend's clock.
    pub(crate) fn now(&self) -> Duration {
        self.robot.lock_hub().link.now()
    }

    /// The limits the references of position goals and tracked trajectories are made under
    /// (PyRobot's 0.2 m/s and 0.5 rad/s, capped by the configuration's speeds): PyRobot's
    /// `MAX_ABS_FWD_SPEED` and `MAX_ABS_TURN_SPEED`.
    pub fn tracking_limits(&self) -> Limits {
        let s = self.section();
        Limits {
            v: Limits::TRACKING.v.min(s.max_linear),
            w: Limits::TRACKING.w.min(s.max_angular),
            ..Limits::TRACKING
        }
    }

    /// A proportional controller for `goal`, starting now.
    pub(crate) fn proportional(&self, goal: [f64; 3]) -> Proportional {
        let s = self.section();
        Proportional::new(
            goal,
            s.max_linear,
            s.max_angular,
            gains::MIN_WHEEL / (0.5 * s.track),
            s.translation_tolerance,
            s.rotation_tolerance,
        )
    }

    pub(crate) fn section(&self) -> &crate::config::BaseSection {
        // Present: `Robot::base` checks it.
        self.robot.cfg().base.as_ref().expect("base config")
    }

    /// Odometry pose `[x, y, θ]`.
    pub fn get_state(&self) -> Result<[f64; 3]> {
        Ok(crate::base_goals::odometry_pose(&self.robot.telemetry()?))
    }

    /// The geometry the odometry uses: the configuration's calibrated `[base] odometry`, or
    /// the last [`Base::set_odometry_geometry`], else the nominal wheel radius and track.
    pub fn odometry_geometry(&self) -> WheelGeometry {
        let s = self.section();
        self.robot
            .lock_hub()
            .base
            .odometry
            .or(ferrobot_profile::odometry_geometry(s))
            .unwrap_or_else(|| ferrobot_profile::nominal_geometry(s))
    }

    /// Make the firmware's odometry use a calibrated geometry (from
    /// [`crate::odometry_calibration::estimate`]); each value must be within 10 % of the
    /// nominal one. Takes effect from the next wheel sample; the pose is not reset.
    pub fn set_odometry_geometry(&self, g: WheelGeometry) -> Result<()> {
        if !g.near(&ferrobot_profile::nominal_geometry(self.section()), 0.1) {
            return Err(Error::Calibration {
                why: format!(
                    "{g:?} is not within 10 % of the nominal {:?}",
                    ferrobot_profile::nominal_geometry(self.section())
                ),
            });
        }
        let mut io = self.robot.lock_hub();
        io.link.command(
            &HostMsg::SetBaseGeometry {
                left_radius: g.left_radius as f32,
                right_radius: g.right_radius as f32,
                track: g.track as f32,
            },
            "odometry geometry",
        )?;
        io.base.odometry = Some(g);
        Ok(())
    }

    /// The accumulated wheel angles `[left, right]` (rad) since the firmware started.
    pub fn wheel_angles(&self) -> Result<[f64; 2]> {
        let w = self.robot.telemetry()?.wheels;
        Ok([w.left as f64, w.right as f64])
    }

    /// Start logging the wheel angles of every telemetry frame that motions see (for odometry
    /// calibration), beginning with the current ones; replaces an earlier log.
    pub fn start_wheel_log(&self) -> Result<()> {
        let mut io = self.robot.lock_hub();
        let t = io.link.telemetry()?;
        io.base.wheel_log = Some(Vec::new());
        io.base.log_wheels(&t);
        Ok(())
    }

    /// Stop logging and return the wheel angles `[left, right]` (rad) logged since
    /// [`Base::start_wheel_log`], ending with the current ones.
    pub fn take_wheel_log(&self) -> Result<Vec<[f64; 2]>> {
        let mut io = self.robot.lock_hub();
        let t = io.link.telemetry()?;
        io.base.log_wheels(&t);
        let log = io.base.wheel_log.take().unwrap_or_default();
        Ok(log.into_iter().map(|l| l.1).collect())
    }

    /// Zero the odometry pose.
    pub fn reset_odometry(&self) -> Result<()> {
        self.robot
            .lock_hub()
            .link
            .command(&HostMsg::ResetOdometry, "odometry reset")?;
        // Let the reset show in telemetry.
        self.robot.wait_for(Duration::from_millis(30));
        Ok(())
    }

    /// Stop now; a base motion under way ends ([`Error::Preempted`]).
    pub fn stop(&self) -> Result<()> {
        let mut io = self.robot.lock_hub();
        io.prepare(self.robot.cfg(), BASE);
        io.link.command(
            &HostMsg::BaseVelocity {
                v: 0.0,
                w: 0.0,
                duration_ms: 0,
            },
            "base stop",
        )
    }

    /// Start driving at `v` (m/s) and `w` (rad/s) for `duration` s (at most
    /// [`validate::MAX_DURATION_S`]).
    pub fn set_vel_async(&self, v: f64, w: f64, duration: f64) -> Result<Motion> {
        check_finite("base velocity", &[v, w])?;
        let duration = validate::seconds("base velocity duration", duration)?;
        let s = self.section();
        let speeds = [
            ("base forward speed", v, s.max_linear),
            ("base yaw rate", w, s.max_angular),
        ];
        for (what, value, max) in speeds {
            if value.abs() > max + 1e-9 {
                return Err(Error::OutOfLimits {
                    joint: what.into(),
                    value,
                    min: -max,
                    max,
                });
            }
        }
        let now = self.now();
        let until = now.saturating_add(duration);
        self.start(
            Box::new(VelocityGoal {
                v,
                w,
                until,
                next_send: now,
            }),
            "base velocity",
            duration + Duration::from_secs(1),
        )
    }

    /// Drive at `v` (m/s) and `w` (rad/s) for `duration` s, then stop.
    pub fn set_vel(&self, v: f64, w: f64, duration: f64) -> Result<()> {
        self.set_vel_async(v, w, duration)?.wait()
    }

    /// Start tracking `reference` (states and controls every `reference.dt`) with LQR from
    /// odometry, or open loop.
    pub fn track_trajectory_async(&self, reference: Reference, close_loop: bool) -> Result<Motion> {
        self.track(reference, close_loop, None)
    }

    /// Track `reference`; with `finish`, then correct the residual to that pose with
    /// [`Finish`].
    fn track(
        &self,
        reference: Reference,
        close_loop: bool,
        finish: Option<[f64; 3]>,
    ) -> Result<Motion> {
        reference.check()?;
        let limits = self.tracking_limits();
        let duration = reference.dt * reference.controls.len() as f64;
        let now = self.now();
        let tr = Tracking::new(
            LqrTracker::new(reference, [3.0, 3.0, 4.0], 0.2),
            close_loop,
            now,
            limits,
        );
        let timeout = Duration::from_secs_f64(duration + 5.0);
        if let Some(goal) = finish {
            // One encoder tick of one wheel turns the odometry by this much (rad).
            let fw = ferrobot_profile::firmware_profile(self.robot.cfg()).base;
            let tick = fw.rad_per_tick() as f64 * fw.wheel_radius as f64 / fw.track as f64;
            let s = self.section();
            let law = TrackThenFinish {
                track: tr,
                tracking: true,
                last: (0.0, 0.0),
                finish: Finisher::new(
                    goal,
                    s.min_wheel_speed,
                    s.min_wheel_speed / (0.5 * s.track),
                    tick,
                    limits,
                ),
            };
            return self.start(
                Box::new(LawGoal(Box::new(law))),
                "base position goal",
                timeout + FINISH_TIME,
            );
        }
        self.start(
            Box::new(TrackGoal(Box::new(tr))),
            "trajectory tracking",
            timeout,
        )
    }

    /// Track `reference` and wait (PyRobot's `track_trajectory`).
    pub fn track_trajectory(&self, reference: Reference, close_loop: bool) -> Result<()> {
        self.track_trajectory_async(reference, close_loop)?.wait()
    }

    /// Start moving to `[x, y, θ]` in the odometry frame with the chosen controller. The goal
    /// must be at most [`validate::MAX_BASE_GOAL_DISTANCE`] from the current pose; every
    /// controller has a budget (its timeout, in the backend's time) and fails with
    /// [`Error::Timeout`] when it runs out.
    pub fn go_to_absolute_with(&self, goal: [f64; 3], opts: GoalOptions) -> Result<Motion> {
        check_finite("base goal", &goal)?;
        if opts.use_map || opts.map.is_some() {
            return self.navigate(goal, &opts);
        }
        let here = self.get_state()?;
        validate::base_goal(goal, here)?;
        let obstacles = Obstacles::new(opts.obstacles.clone(), None)?;
        let controller = opts.controller.unwrap_or(if obstacles.is_empty() {
            self.section().controller
        } else {
            BaseController::Dwa
        });
        let lim = self.tracking_limits();
        match controller {
            BaseController::Proportional => self.proportional_async(goal, here),
            BaseController::Lqr | BaseController::Ilqr => {
                let mut r = if opts.smooth {
                    Reference::smooth(here, goal, &lim, REFERENCE_DT, SMOOTH_ARM)?
                } else {
                    Reference::sharp(here, goal, &lim, REFERENCE_DT)?
                };
                if controller == BaseController::Ilqr {
                    r = ilqr(here, &r, [3.0, 3.0, 4.0], 0.2, &lim)?.reference;
                }
                // Hold the goal a little: the tracker settles while the reference rests; closed
                // loop, the finisher then removes what the wheels' deadband left.
                let finish = opts.close_loop.then_some(goal);
                self.track(r.hold(10)?, opts.close_loop, finish)
            }
            BaseController::Dwa => {
                let radius = self.section().footprint_radius;
                let clear = obstacles.clearance([goal[0], goal[1]]);
                if clear < radius {
                    return Err(Error::Unreachable {
                        why: format!(
                            "the base ({radius} m footprint radius) at the goal would overlap an obstacle ({clear:.3} m from the goal)"
                        ),
                    });
                }
                let nav = NavField::new(
                    [here[0], here[1]],
                    [goal[0], goal[1]],
                    &obstacles,
                    radius + DWA_PATH_MARGIN,
                )?;
                let dwa = Dwa {
                    path: nav.path([here[0], here[1]]),
                    nav,
                    goal: [goal[0], goal[1]],
                    obstacles,
                    radius,
                    limits: lim,
                    dt: 0.1,
                    horizon: 2.0,
                };
                let dist = (goal[0] - here[0]).hypot(goal[1] - here[1]);
                // Room for a detour of half the distance again, at half speed.
                let timeout = Duration::from_secs_f64(15.0 + 3.0 * dist / lim.v);
                // The last stretch stays within the window's (tracking) limits too.
                let finish = self.proportional(goal).with_speed_limits(lim.v, lim.w);
                let now = self.now();
                let g = DwaGoal {
                    dwa,
                    finish,
                    reached: false,
                    next: now,
                    last: (0.0, 0.0),
                    progress: (f64::INFINITY, now),
                };
                self.start(
                    Box::new(LawGoal(Box::new(g))),
                    "base position goal (DWA)",
                    timeout,
                )
            }
        }
    }

    /// The odometry-frame goal `delta` (`[x, y, θ]` in the current pose's frame) names.
    fn relative_goal(&self, delta: [f64; 3]) -> Result<[f64; 3]> {
        check_relative(delta)?;
        let here = Pose2::from(self.get_state()?);
        Ok(here.compose(&Pose2::from(delta)).to_array())
    }

    /// Start moving by `[x, y, θ]` relative to the current pose with the chosen controller.
    pub fn go_to_relative_with(&self, delta: [f64; 3], opts: GoalOptions) -> Result<Motion> {
        check_relative(delta)?;
        let goal = self.relative_goal(delta)?;
        self.go_to_absolute_with(goal, opts)
    }

    /// Start moving to `[x, y, θ]` in the odometry frame with the configuration's controller.
    pub fn go_to_absolute_async(&self, goal: [f64; 3]) -> Result<Motion> {
        self.go_to_absolute_with(goal, GoalOptions::default())
    }

    /// Start the proportional controller from `here` towards `[x, y, θ]` (a goal
    /// [`Base::go_to_absolute_with`] has validated) in the odometry frame.
    fn proportional_async(&self, goal: [f64; 3], here: [f64; 3]) -> Result<Motion> {
        let s = self.section().clone();
        let now = self.now();
        let dist = (goal[0] - here[0]).hypot(goal[1] - here[1]);
        let turn = std::f64::consts::TAU;
        let timeout =
            Duration::from_secs_f64(10.0 + 3.0 * (dist / s.max_linear + turn / s.max_angular));
        let g = self.proportional(goal).starting_at(now);
        self.start(
            Box::new(LawGoal(Box::new(g))),
            "base position goal",
            timeout,
        )
    }

    /// Move to `[x, y, θ]` in the odometry frame with the configuration's controller and wait.
    pub fn go_to_absolute(&self, goal: [f64; 3]) -> Result<()> {
        self.go_to_absolute_async(goal)?.wait()
    }

    /// Start moving by `[x, y, θ]` relative to the current pose (x forward, y left).
    pub fn go_to_relative_async(&self, delta: [f64; 3]) -> Result<Motion> {
        check_relative(delta)?;
        let goal = self.relative_goal(delta)?;
        self.go_to_absolute_async(goal)
    }

    /// Move by `[x, y, θ]` relative to the current pose and wait.
    pub fn go_to_relative(&self, delta: [f64; 3]) -> Result<()> {
        self.go_to_relative_async(delta)?.wait()
    }
}
