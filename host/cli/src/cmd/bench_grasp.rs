//! `ferrobot bench grasp ROBOT --scene tabletop --trials N --seed K`: PyRobot's grasping
//! example as a benchmark. Each trial places the scene's graspable objects at random on the
//! table (seed K + trial), starts the robot there, and runs [`ferrobot_skills::grasp::pick`] (look,
//! choose, plan to the pregrasp, descend, close, lift). Success is judged from the simulator's
//! ground truth, never from the robot's belief: some object rose at least [`LIFT`] above where
//! it lay, and is still that high [`HOLD_S`] later. Which objects are graspable:
//! `docs/design/cli.md`.

use ferrobot::perception::AnalyticScorer;
use ferrobot::scene::{Scene, SceneSource};
use ferrobot::{Backend, Robot};
use ferrobot_sim::placement::{scatter, standing_half_extents, Region};
use ferrobot_skills::grasp::{gripper_geometry, GraspOptions};
use serde::Serialize;

use super::bench_nav::{median, Median};
use super::common::{load, print_json, BackendArgs};

/// An object counts as lifted when it rose this far above where it lay, m.
pub const LIFT: f64 = 0.05;
/// And is still that high this long after the lift, s.
pub const HOLD_S: f64 = 2.0;
/// Objects are placed this far in from the table's edges, m.
const EDGE: f64 = 0.02;
/// Objects' centres lie within this distance of the robot's centre, m: where the LoCoBot's
/// arm, pointing down, reaches the pregrasp above a 6 cm object on the table (about 0.3 m
/// above `base_link`; at that height its top-down reach ends at 0.42-0.44 m).
pub const REACH: f64 = 0.42;
/// Objects are placed at least this far apart (between their footprints' circles), m.
const GAP: f64 = 0.02;
/// Most trials.
const MAX_TRIALS: usize = 10_000;

/// `ferrobot bench grasp`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Scene name or path (with a fixed body `table`).
    #[arg(long, default_value = "tabletop")]
    pub scene: String,
    /// Trials.
    #[arg(long, default_value_t = 10)]
    pub trials: usize,
    /// The backend; --seed seeds the placements (and the plants' noise on the sim).
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Print one JSON object: `{"failures", "objects", "success_rate", "time_s":
    /// {"median"}, "trials"}` (the failures' reasons, the objects placed).
    #[arg(long)]
    pub json: bool,
}

/// `bench grasp --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct GraspJson {
    failures: Vec<String>,
    objects: Vec<String>,
    success_rate: f64,
    time_s: Median,
    trials: usize,
}

/// The narrowest horizontal width and the height of a body standing as it does (its yaw
/// removed), m.
fn standing_size(body: &ferrobot::scene::Body) -> (f64, f64) {
    let h = standing_half_extents(body);
    (2.0 * h.x.min(h.y), 2.0 * h.z)
}

/// The scene with only its graspable movable bodies (see the module's text), and the region
/// of the table they are placed in.
fn trial_world(cfg: &ferrobot::RobotConfig, scene: &Scene) -> ferrobot::Result<(Scene, Region)> {
    let (g, _) = gripper_geometry(cfg)?;
    let scorer = AnalyticScorer::default();
    let opts = GraspOptions::default();
    let table = scene
        .bodies
        .iter()
        .find(|b| b.fixed && b.id == "table")
        .ok_or_else(|| {
            ferrobot::Error::Usage(format!(
                "scene {:?} has no fixed body \"table\" to place objects on",
                scene.name
            ))
        })?;
    let mut world = scene.clone();
    world.bodies.retain(|b| {
        let (width, height) = standing_size(b);
        b.fixed
            || (width <= g.opening - 2.0 * scorer.min_gap
                && height >= opts.params.table_gap + scorer.min_depth)
    });
    if world.bodies.iter().all(|b| b.fixed) {
        return Err(ferrobot::Error::Usage(format!(
            "scene {:?} has no object that fits the {:.3} m opening of {}'s gripper",
            scene.name, g.opening, cfg.name
        )));
    }
    let (lo, hi) = table.world_bounds();
    let [x0, y0, heading] = scene.robot_pose;
    if heading.abs() > 1e-9 {
        return Err(ferrobot::Error::Usage(
            "bench grasp needs the robot facing +x in the scene".into(),
        ));
    }
    let region = Region {
        x: [lo.x + EDGE, hi.x - EDGE],
        y: [lo.y + EDGE, hi.y - EDGE],
        within: Some([x0, y0, REACH]),
    };
    Ok((world, region))
}

/// The heights of the movable bodies in the world now, m (`None` off the simulator).
fn heights(bot: &Robot, scene: &Scene) -> ferrobot::Result<Vec<(String, f64)>> {
    let truth = bot.truth()?;
    Ok(scene
        .bodies
        .iter()
        .zip(&truth.bodies)
        .filter(|(b, _)| !b.fixed)
        .map(|(b, p)| (b.id.clone(), p.translation.z))
        .collect())
}

/// One trial: `Ok(Some(simulated seconds))` on success, `Ok(None)` with the reason pushed
/// into `why` on failure.
fn trial(
    args: &Args,
    backend: Backend,
    world: Scene,
    why: &mut String,
) -> ferrobot::Result<Option<f64>> {
    let bot = Robot::builder(&args.robot)
        .with_scene(world.clone())
        .backend(backend)
        .build()?;
    let before = heights(&bot, &world)?;
    let t0 = bot.time();
    let picked = ferrobot_skills::grasp::pick(&bot, &GraspOptions::default());
    let t = bot.time() - t0;
    let lifted = heights(&bot, &world)?;
    bot.wait(HOLD_S)?;
    let held = heights(&bot, &world)?;
    let rise = |now: &[(String, f64)]| -> Vec<f64> {
        now.iter().zip(&before).map(|(a, b)| a.1 - b.1).collect()
    };
    let (r1, r2) = (rise(&lifted), rise(&held));
    let ok = r1
        .iter()
        .zip(&r2)
        .position(|(a, b)| *a >= LIFT && *b >= LIFT);
    match (&picked, ok) {
        (Ok(_), Some(_)) => return Ok(Some(t)),
        (Err(e), _) => *why = e.to_string(),
        (Ok(g), None) => {
            let best = r1.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            *why = format!(
                "the grasp at ({:.3}, {:.3}) m lifted nothing {LIFT} m for {HOLD_S} s (highest rise {best:.3} m)",
                g.grasp.position.x, g.grasp.position.y
            );
        }
    }
    Ok(None)
}

/// Run the bench.
pub fn run(args: &Args) -> ferrobot::Result<()> {
    ferrobot::validate::count("trials", args.trials, 1..=MAX_TRIALS)?;
    let backend = args.backend.backend()?;
    let scene = Scene::load(&SceneSource::from_arg(&args.scene))?;
    let seed = args.backend.seed;
    let mut times = Vec::new();
    let mut failures = Vec::new();
    let (world, region) = trial_world(&load(&args.robot)?, &scene)?;
    for k in 0..args.trials {
        let s = seed.wrapping_add(k as u64);
        let placed = scatter(&world, &[], region, s, GAP)?;
        let backend = match &backend {
            Backend::Sim { realtime, .. } => Backend::Sim {
                seed: s,
                realtime: *realtime,
            },
            other => other.clone(),
        };
        let mut why = String::new();
        match trial(args, backend, placed, &mut why)? {
            Some(t) => times.push(t),
            None => failures.push(format!("trial {k} (seed {s}): {why}")),
        }
        if !args.json {
            eprintln!(
                "trial {k}: {}",
                if why.is_empty() {
                    "lifted"
                } else {
                    why.as_str()
                }
            );
        }
    }
    let out = GraspJson {
        success_rate: times.len() as f64 / args.trials as f64,
        time_s: Median {
            median: median(times.clone()),
        },
        trials: args.trials,
        failures,
        objects: world
            .bodies
            .iter()
            .filter(|b| !b.fixed)
            .map(|b| b.id.clone())
            .collect(),
    };
    if args.json {
        print_json(&out);
    } else {
        say!(
            "{} in {}: {}/{} objects lifted {LIFT} m and held {HOLD_S} s ({:.0} %), median {:.1} s (simulated) per grasp",
            args.robot,
            args.scene,
            times.len(),
            args.trials,
            100.0 * out.success_rate,
            out.time_s.median
        );
        say!("  objects placed: {}", out.objects.join(", "));
        for f in &out.failures {
            say!("  {f}");
        }
    }
    Ok(())
}
