//! Scripted drives: the simulated robot follows one of its scene's routes through the public
//! API (base goals, camera frames, telemetry), and every camera frame is handed on with the
//! odometry at its instant and the simulator's ground truth.

use ferrobot::slam::optimise::{planar, to_planar};
use ferrobot::{Backend, Frame, Robot};
use ferrobot_sim::scene::Route;
use nalgebra::{Isometry3, Point3};

/// One camera frame of a drive.
pub struct Sample {
    /// The frame (time, images, the camera's pose in `base_link`).
    pub frame: Frame,
    /// The wheel odometry `[x, y, θ]` at the frame's instant, in the odometry's own frame.
    pub odometry: [f64; 3],
    /// The base's true pose `[x, y, θ]` in the world.
    pub truth: [f64; 3],
    /// The optical frame's true pose in the world.
    pub camera_truth: Isometry3<f64>,
}

/// A robot in a scene, ready to drive a route.
pub struct Drive {
    /// The robot.
    pub bot: Robot,
    /// The route.
    pub route: Route,
    /// The base's true start pose in the world.
    pub start: [f64; 3],
    /// The odometry at the start.
    pub odometry_start: [f64; 3],
}

impl Drive {
    /// The simulated `robot` in `scene` (noise seeded by `seed`) with its head set for
    /// `route`.
    pub fn new(robot: &str, scene: &str, route: &str, seed: u64) -> ferrobot::Result<Self> {
        let b = super::common::robot_builder(robot);
        let bot = b
            .scene(scene)
            .backend(Backend::Sim {
                seed,
                realtime: false,
            })
            .build()?;
        let s = bot.scene();
        let route = s.route(route).cloned().ok_or_else(|| {
            let known: Vec<&str> = s.routes.iter().map(|r| r.name.as_str()).collect();
            ferrobot::Error::Usage(format!(
                "scene {} has no route {route:?} (its routes: {known:?})",
                s.name
            ))
        })?;
        bot.head()?.set_pan_tilt(0.0, route.head_tilt)?;
        let start = truth(&bot)?;
        let odometry_start = bot.base()?.get_state()?;
        Ok(Drive {
            bot,
            route,
            start,
            odometry_start,
        })
    }

    /// The odometry pose `o` in the world (the odometry's frame starts at the start pose).
    pub fn odometry_in_world(&self, o: [f64; 3]) -> Isometry3<f64> {
        planar(self.start) * planar(self.odometry_start).inverse() * planar(o)
    }

    /// Drives the route, then stays a second; `on_frame` sees every camera frame meanwhile.
    pub fn run(
        &self,
        mut on_frame: impl FnMut(&Sample) -> ferrobot::Result<()>,
    ) -> ferrobot::Result<()> {
        let camera = self.bot.camera()?;
        let base = self.bot.base()?;
        let optical = self
            .bot
            .config()
            .camera
            .as_ref()
            .map(|c| c.frame.clone())
            .ok_or_else(|| ferrobot::Error::Usage("the robot has no camera".into()))?;
        let mut step = || -> ferrobot::Result<()> {
            let frame = camera.get_frame()?;
            // The odometry at the frame's instant: the newest report, carried on by its speeds.
            let tel = self.bot.telemetry()?;
            let odometry = ferrobot::slam::odometry_at(&tel, frame.time.as_secs_f64());
            let sample = Sample {
                odometry,
                truth: truth(&self.bot)?,
                camera_truth: link_truth(&self.bot, &optical)?,
                frame,
            };
            on_frame(&sample)
        };
        // Waypoints are in the world; goals in the odometry's frame.
        let world_to_odo = planar(self.odometry_start) * planar(self.start).inverse();
        let turn = to_planar(&world_to_odo)[2];
        for w in &self.route.waypoints {
            let here = base.get_state()?;
            let p = world_to_odo * Point3::new(w.xy[0], w.xy[1], 0.0);
            let th = (p.y - here[1]).atan2(p.x - here[0]);
            let goals = [
                Some([p.x, p.y, th]),
                w.heading.map(|h| [p.x, p.y, h + turn]),
            ];
            for g in goals.into_iter().flatten() {
                let motion = base.go_to_absolute_async(g)?;
                while !motion.is_finished() {
                    step()?;
                }
                motion.wait()?;
            }
            let until = self.bot.time() + w.wait;
            while self.bot.time() < until {
                step()?;
            }
        }
        let until = self.bot.time() + 1.0;
        while self.bot.time() < until {
            step()?;
        }
        Ok(())
    }
}

/// The base's true pose `[x, y, θ]` in the world.
pub fn truth(bot: &Robot) -> ferrobot::Result<[f64; 3]> {
    bot.simulator()
        .and_then(|s| s.base_truth())
        .ok_or_else(|| ferrobot::Error::Usage("this needs the simulator's ground truth".into()))
}

/// Link `name`'s true pose in the world.
fn link_truth(bot: &Robot, name: &str) -> ferrobot::Result<Isometry3<f64>> {
    let sim = bot
        .simulator()
        .ok_or_else(|| ferrobot::Error::Usage("this needs the simulator".into()))?;
    let body = sim
        .body()
        .ok_or_else(|| ferrobot::Error::Usage("the simulated robot has no body".into()))?;
    let i = body
        .tree
        .link_index(name)
        .ok_or_else(|| ferrobot::Error::Usage(format!("the URDF has no link {name}")))?;
    Ok(sim.truth().links[i])
}
