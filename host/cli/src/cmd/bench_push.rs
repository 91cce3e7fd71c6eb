//! `ferrobot bench push ROBOT --scene tabletop --trials N --seed K [--backend ...]`: PyRobot's
//! pushing example, measured. Trial k places the scene's objects at random on the table (seed
//! K + k; `ferrobot_sim::placement::scatter_on`), starts the robot [`APPROACH`] back from its
//! start pose and drives it up, then pushes one object with [`ferrobot::Robot::push_object`].
//! Judged by the simulated world's ground truth, never by what the robot believes: a trial
//! succeeds when the target moved at least [`GOAL_MOVE`] along the push and no other object
//! more than [`OTHERS_STILL`] (m).

use ferrobot::scene::{Scene, SceneSource};
use ferrobot::Robot;
use ferrobot_skills::{PushOptions, Skills};
use nalgebra::{Isometry3, Point3, Vector3};
use serde::Serialize;

use super::bench_nav::{median, Median};
use super::common::{print_json, robot_builder, BackendArgs};

/// `ferrobot bench push`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Scene name or path (movable objects on a static body `table`).
    #[arg(long, default_value = "tabletop")]
    pub scene: String,
    /// Trials.
    #[arg(long, default_value_t = 10)]
    pub trials: usize,
    /// Where the robot runs; --seed is the first trial's (placement and plants).
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Print one JSON object: `{"others_moved", "per_trial": [...], "pushes",
    /// "success_rate", "success_rate_of_pushes", "target_moved_m": {"median", "min"},
    /// "time_s": {"median"}, "trials"}`.
    #[arg(long)]
    pub json: bool,
}

/// The robot starts this far behind the scene's start pose and drives up to it, m.
pub const APPROACH: f64 = 0.4;
/// The target must move at least this far along the push, m (the goal).
pub const GOAL_MOVE: f64 = 0.05;
/// Every other object must move less than this, m.
pub const OTHERS_STILL: f64 = 0.01;
/// Gap between the placed objects' footprints and from the table's edges, m.
const PLACEMENT_GAP: f64 = 0.03;
/// The world is at rest when no body moved more than this in [`REST_WINDOW_S`], m.
const REST_MOTION: f64 = 1e-4;
/// Window of the rest test, s (simulated).
const REST_WINDOW_S: f64 = 0.1;
/// Longest wait for the world to come to rest after a push, s (simulated).
const REST_TIMEOUT_S: f64 = 10.0;

/// One trial, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize, Clone)]
struct Trial {
    /// How the base moved before the push (forward, left), m, as the robot reports it.
    base_move_m: [f64; 2],
    /// Why the push failed, if it did.
    error: Option<String>,
    /// The farthest another object moved, m (ground truth).
    others_max_moved_m: f64,
    /// Whether another object moved more than [`OTHERS_STILL`].
    others_moved: bool,
    seed: u64,
    /// The side of the table pushed from (as seen from the start), if a push was made.
    side: Option<ferrobot::stance::Side>,
    success: bool,
    /// The scene body pushed (the one nearest the chosen object's centroid).
    target: Option<String>,
    /// How far the target moved along the intended direction, m (ground truth).
    target_moved_m: f64,
    /// Simulated time of the push (look, choose, move), s.
    time_s: f64,
}

/// `bench push --json`, fields in alphabetical order.
#[derive(Serialize)]
struct PushJson {
    /// Trials in which another object moved more than [`OTHERS_STILL`].
    others_moved: usize,
    per_trial: Vec<Trial>,
    /// Trials in which the robot pushed (it found an object it could push within reach).
    pushes: usize,
    success_rate: f64,
    /// Successes among the trials in which the robot pushed.
    success_rate_of_pushes: f64,
    target_moved_m: MinMedian,
    time_s: Median,
    trials: usize,
}

#[derive(Serialize)]
struct MinMedian {
    median: f64,
    min: f64,
}

/// Run the benchmark and print it.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    ferrobot::validate::count("trials", a.trials, 1..=10_000)?;
    // Input errors before any trial: the robot, the scene, the backend.
    let base_scene = Scene::load(&SceneSource::from_arg(&a.scene))?;
    a.backend.backend()?;
    let mut trials = Vec::with_capacity(a.trials);
    for k in 0..a.trials {
        let seed = a.backend.seed.wrapping_add(k as u64);
        let t = trial(a, &base_scene, seed)?;
        if !a.json {
            say!(
                "trial {k:>3} seed {seed}: {} {:?} moved {:.3} m along the push, others at most {:.4} m, {:.1} s{}",
                if t.success { "ok  " } else { "FAIL" },
                t.target.as_deref().unwrap_or("-"),
                t.target_moved_m,
                t.others_max_moved_m,
                t.time_s,
                t.error.as_deref().map(|e| format!(" ({e})")).unwrap_or_default()
            );
        }
        trials.push(t);
    }
    let n = trials.len();
    let ok = trials.iter().filter(|t| t.success).count();
    let moved: Vec<f64> = trials.iter().map(|t| t.target_moved_m).collect();
    let pushes = trials.iter().filter(|t| t.target.is_some()).count();
    let out = PushJson {
        others_moved: trials.iter().filter(|t| t.others_moved).count(),
        pushes,
        success_rate: ok as f64 / n as f64,
        success_rate_of_pushes: ok as f64 / pushes.max(1) as f64,
        target_moved_m: MinMedian {
            median: median(moved.clone()),
            min: moved.iter().copied().fold(f64::INFINITY, f64::min),
        },
        time_s: Median {
            median: median(trials.iter().map(|t| t.time_s).collect()),
        },
        trials: n,
        per_trial: trials,
    };
    if a.json {
        print_json(&out);
    } else {
        say!(
            "push: {ok}/{n} trials succeeded ({:.0} %; {ok}/{pushes} of the pushes made): target moved {:.3} m along the push (median, min {:.3}), another object moved > {OTHERS_STILL} m in {} trials, {:.1} s per push (median)",
            100.0 * out.success_rate,
            out.target_moved_m.median,
            out.target_moved_m.min,
            out.others_moved,
            out.time_s.median
        );
    }
    Ok(())
}

/// One trial with seed `seed`. Errors: only the input's and the robot's start (a failed push
/// is a failed trial).
fn trial(a: &Args, base_scene: &Scene, seed: u64) -> ferrobot::Result<Trial> {
    let mut scene = base_scene.clone();
    ferrobot_sim::placement::scatter_on(&mut scene, "table", seed, PLACEMENT_GAP)?;
    let start = scene.robot_pose;
    let (s, c) = start[2].sin_cos();
    let mut backend = a.backend.clone();
    backend.seed = seed;
    let bot = robot_builder(&a.robot)
        .with_scene(scene)
        .start_pose([start[0] - APPROACH * c, start[1] - APPROACH * s, start[2]])
        .backend(backend.backend()?)
        .build()?;
    let mut t = Trial {
        base_move_m: [0.0; 2],
        error: None,
        others_max_moved_m: 0.0,
        others_moved: false,
        seed,
        side: None,
        success: false,
        target: None,
        target_moved_m: 0.0,
        time_s: 0.0,
    };
    if let Err(e) = bot
        .base()
        .and_then(|b| b.go_to_relative([APPROACH, 0.0, 0.0]))
    {
        t.error = Some(format!("approach: {e}"));
        return Ok(t);
    }
    let before = bot.truth()?;
    let t0 = bot.time();
    let pushed = bot.push_object(&PushOptions::default());
    t.time_s = bot.time() - t0;
    let after = settled(&bot)?;
    let scene = bot.scene();
    let movable: Vec<usize> = (0..scene.bodies.len())
        .filter(|&i| !scene.bodies[i].fixed)
        .collect();
    let moved = |i: usize| after.bodies[i].translation.vector - before.bodies[i].translation.vector;
    let target = match &pushed {
        Ok(p) => {
            t.base_move_m = p.base_move;
            t.side = Some(p.side);
            // The plan is in `base_link` where the base stood for the push (it may have
            // moved first; the push itself moves only the arm).
            let c = p.objects[p.plan.target].centroid;
            let w = world_point(&after.root, &c);
            movable
                .iter()
                .copied()
                .min_by(|&i, &j| {
                    let d = |k: usize| (before.bodies[k].translation.vector - w).xy().norm();
                    d(i).total_cmp(&d(j))
                })
                .map(|i| {
                    let dir = after.root.rotation
                        * Vector3::new(p.plan.direction[0], p.plan.direction[1], 0.0);
                    (i, moved(i).dot(&dir))
                })
        }
        Err(e) => {
            t.error = Some(e.to_string());
            None
        }
    };
    if let Some((i, along)) = target {
        t.target = Some(scene.bodies[i].id.clone());
        t.target_moved_m = along;
    }
    t.others_max_moved_m = movable
        .iter()
        .filter(|&&i| Some(i) != target.map(|x| x.0))
        .map(|&i| moved(i).norm())
        .fold(0.0, f64::max);
    t.others_moved = t.others_max_moved_m > OTHERS_STILL;
    t.success = target.is_some() && t.target_moved_m >= GOAL_MOVE && !t.others_moved;
    Ok(t)
}

/// A point of the robot's root frame in the world.
fn world_point(root: &Isometry3<f64>, p: &Point3<f64>) -> Vector3<f64> {
    (root * p).coords
}

/// The world's ground truth once no body moves more than [`REST_MOTION`] in
/// [`REST_WINDOW_S`] (simulated time), or after [`REST_TIMEOUT_S`].
fn settled(bot: &Robot) -> ferrobot::Result<ferrobot_sim::lockstep::Truth> {
    let mut last = bot.truth()?;
    let until = bot.time() + REST_TIMEOUT_S;
    while bot.time() < until {
        bot.wait(REST_WINDOW_S)?;
        let now = bot.truth()?;
        let still = now
            .bodies
            .iter()
            .zip(&last.bodies)
            .all(|(a, b)| (a.translation.vector - b.translation.vector).norm() < REST_MOTION);
        last = now;
        if still {
            break;
        }
    }
    Ok(last)
}
