//! `ferrobot bench nav ROBOT --scene SCENE --goals N --seed K`: the simulated robot drives to
//! N random reachable goals with `go_to_absolute_with` on the scene's ground-truth floor plan
//! (PyRobot's 2 cm map, obstacles 0.1-0.8 m above the floor). Per goal: success (the base
//! truly within [`GOAL_TOLERANCE`] of the goal), bumper hits, the true path's length against
//! the shortest path on the floor plan (A*, the robot's radius), and the time taken. Missed
//! goals and the frames of `--localise`: `docs/design/cli.md`.

use ferrobot::nav::{GlobalPlanner, GridAStar, MapImage, Obstacles, OccupancyGrid};
use ferrobot::slam::optimise::{planar, to_planar};
use ferrobot::slam::Stamped;
use ferrobot::{Backend, GoalOptions, Source};
use ferrobot_sim::floor_plan::OBSTACLE_BAND;
use nalgebra::Point3;
use serde::Serialize;

use super::common::print_json;
use super::route::truth;

/// A goal is reached when the base's true position is this near it, m (PyRobot's move_base
/// tolerance is 0.1-0.2 m).
pub const GOAL_TOLERANCE: f64 = 0.2;
/// Goals keep this much clearance beyond the robot's radius, m.
const GOAL_CLEARANCE: f64 = 0.15;
/// Goals lie at least this far from where the robot is, m.
const MIN_GOAL_DISTANCE: f64 = 1.0;

/// A median, as the benches' JSON gives it (`{"median": ...}`).
#[derive(Serialize)]
pub struct Median {
    /// The median.
    pub median: f64,
}

/// `bench nav --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct NavJson {
    bumper_hits: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    exploration: Option<ExploreJson>,
    goals: usize,
    path_length_ratio: Median,
    success_rate: f64,
    time_s: Median,
}

/// The median of `v` (NaN when empty).
pub fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// SplitMix64: the goals' seeded stream.
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `world` resampled (nearest cell) into the frame whose pose in the world is `frame`
/// (`[x, y, θ]`): the same resolution, covering the world grid's corners.
fn resample(world: &OccupancyGrid, frame: [f64; 3]) -> ferrobot::Result<OccupancyGrid> {
    let to_frame = planar(frame).inverse();
    let r = world.resolution;
    let corners = [
        world.centre(0, 0),
        world.centre(world.width - 1, 0),
        world.centre(0, world.height - 1),
        world.centre(world.width - 1, world.height - 1),
    ];
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for c in corners {
        let p = to_frame * Point3::new(c[0], c[1], 0.0);
        for (k, v) in [p.x, p.y].into_iter().enumerate() {
            lo[k] = lo[k].min(v);
            hi[k] = hi[k].max(v);
        }
    }
    let w = ((hi[0] - lo[0]) / r).ceil() as usize + 1;
    let h = ((hi[1] - lo[1]) / r).ceil() as usize + 1;
    let mut g = OccupancyGrid::new(lo, r, w, h)?;
    let to_world = planar(frame);
    for j in 0..h {
        for i in 0..w {
            let c = g.centre(i, j);
            let p = to_world * Point3::new(c[0], c[1], 0.0);
            g.occupied[j * w + i] = world.is_occupied([p.x, p.y]);
        }
    }
    Ok(g)
}

/// `ferrobot bench nav`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Scene name or path.
    #[arg(long, default_value = "apartment")]
    pub scene: String,
    /// Goals.
    #[arg(long, default_value_t = 50)]
    pub goals: usize,
    /// Seed of the goals and the plants' noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Where the base's pose comes from: `slam` (SLAM beside the robot, started at the
    /// true start on the floor plan's frame) or `odometry` (the wheels alone).
    #[arg(long, default_value = "slam")]
    pub localise: String,
    /// One line per goal on standard error.
    #[arg(long)]
    pub trace: bool,
    /// Explore the scene first (SLAM, frontiers), then drive to the goals on SLAM's map;
    /// the JSON gains `exploration`: `{"bumper_hits", "distance_m", "occupancy_iou",
    /// "occupancy_iou_free", "occupancy_iou_occupied", "time_s"}`.
    #[arg(long)]
    pub explore: bool,
    /// With --explore: write the explored map (`map.yaml`, `map.png`), the part of the
    /// floor plan it is judged against (`truth.yaml`, `truth.png`) and a picture of the
    /// map with the SLAM, true and wheel-odometry paths (`exploration.png`) here.
    #[arg(long)]
    pub out: Option<std::path::PathBuf>,
    /// Print one JSON object: `{"bumper_hits", "goals", "path_length_ratio": {"median"},
    /// "success_rate", "time_s": {"median"}}`.
    #[arg(long)]
    pub json: bool,
}

/// `bench nav --explore --json`'s `exploration`: how exploring went and how good its map is
/// against the part of the floor plan the robot can reach and see
/// ([`ferrobot::slam::reachable_part`]): intersection over union of free cells, of occupied
/// cells (within one cell; an occupied cell the part leaves out, such as the top of a bed, is
/// judged against the whole floor plan: [`ferrobot::slam::map_iou_seen`]), and of both.
#[derive(Serialize)]
struct ExploreJson {
    bumper_hits: usize,
    distance_m: f64,
    occupancy_iou: f64,
    occupancy_iou_free: f64,
    occupancy_iou_occupied: f64,
    time_s: f64,
}

/// Explores with SLAM until no frontier is left; measures the map against the reachable part
/// of the floor plan; writes the map when asked.
fn explore(
    bot: &ferrobot::Robot,
    plan: &MapImage,
    start: [f64; 3],
    out: Option<&std::path::Path>,
    trace: bool,
) -> ferrobot::Result<ExploreJson> {
    let base = bot.base()?;
    let t0 = bot.time();
    // The odometry's frame in the map's (the floor plan's): the start pose.
    let odo0 = planar(start) * planar(base.get_state()?).inverse();
    let mut motion = base.explore_async()?;
    let mut travelled = 0.0;
    let mut last = truth(bot)?;
    let (mut est, mut gt, mut odo) = (Vec::new(), Vec::new(), Vec::new());
    let mut next_sample = t0;
    let result = loop {
        if motion.poll().is_some() {
            break motion.wait();
        }
        let now = truth(bot)?;
        travelled += (now[0] - last[0]).hypot(now[1] - last[1]);
        last = now;
        let t = bot.time();
        if t >= next_sample {
            next_sample = t + 0.5;
            let stamp = |pose| Stamped { time: t, pose };
            gt.push(stamp(planar(now)));
            odo.push(stamp(odo0 * planar(base.get_state()?)));
            if let Ok(p) = base.get_state_from(Source::Slam) {
                est.push(stamp(planar(p)));
            }
        }
    };
    let time = bot.time() - t0;
    if trace {
        eprintln!(
            "exploration: {result:?} after {time:.1} s, {travelled:.1} m, truly at {:.3?}, SLAM says {:.3?}",
            truth(bot)?,
            base.get_state_from(ferrobot::Source::Slam).ok()
        );
    }
    result?;
    let bumps = bot
        .take_faults()
        .iter()
        .filter(|f| f.kind == ferrobot::FaultKind::Bumper)
        .count();
    let map = bot
        .slam_occupancy_map()?
        .ok_or_else(|| ferrobot::Error::Usage("exploration mapped nothing".into()))?;
    let truth_part = ferrobot::slam::reachable_part(plan, [start[0], start[1]])?;
    let iou = ferrobot::slam::map_iou_seen(&map, &truth_part, plan, 1)?;
    if let Some(dir) = out {
        std::fs::create_dir_all(dir)
            .map_err(|e| ferrobot::Error::Usage(format!("cannot make {}: {e}", dir.display())))?;
        map.save(&dir.join("map.yaml"))?;
        truth_part.save(&dir.join("truth.yaml"))?;
        let caption = format!(
            "exploring: {time:.0} s, {travelled:.1} m; free-cell IoU {:.2} against the reachable floor plan",
            iou.free
        );
        super::slam::draw(
            &map,
            &est,
            &gt,
            &odo,
            &caption,
            &dir.join("exploration.png"),
        )?;
    }
    Ok(ExploreJson {
        bumper_hits: bumps,
        distance_m: travelled,
        occupancy_iou: iou.cells,
        occupancy_iou_free: iou.free,
        occupancy_iou_occupied: iou.occupied,
        time_s: time,
    })
}

/// The course the goals are driven on: the robot, the floor plan, and the frame of the goals.
struct Course {
    bot: ferrobot::Robot,
    /// The floor plan as a grid, the world's frame.
    world: OccupancyGrid,
    /// Clearance on the floor plan.
    clear: Obstacles,
    /// The robot's footprint radius, m.
    radius: f64,
    /// The goals' frame in the world `[x, y, θ]`.
    frame: [f64; 3],
    /// How the base drives to a goal.
    opts: GoalOptions,
    /// One line per goal on standard error.
    trace: bool,
}

/// The goals driven: reached, bumper hits, path length ratios and times of those reached.
#[derive(Default)]
struct Tally {
    ok: usize,
    hits: usize,
    ratios: Vec<f64>,
    times: Vec<f64>,
}

/// Drive to the goals and print the figures.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let (robot, scene, goals, json) = (a.robot.as_str(), a.scene.as_str(), a.goals, a.json);
    let slam = check(a)?;
    let (course, exploration) = set_up(a, slam)?;
    let mut rng = Rng(a.seed ^ 0x6E61_765F_6265_6E63);
    let mut tally = Tally::default();
    for _ in 0..goals {
        // None: the robot is stuck where no path leaves (a failed goal left it against an
        // obstacle); the goals left count as missed.
        if !course.next_goal(&mut rng, &mut tally)? {
            break;
        }
    }
    let Tally {
        ok,
        hits,
        ratios,
        times,
    } = tally;
    let out = NavJson {
        bumper_hits: hits + exploration.as_ref().map_or(0, |e| e.bumper_hits),
        exploration,
        goals,
        path_length_ratio: Median {
            median: median(ratios),
        },
        success_rate: ok as f64 / goals as f64,
        time_s: Median {
            median: median(times),
        },
    };
    if json {
        print_json(&out);
    } else {
        say!(
            "{robot} in {scene}: {ok}/{goals} goals reached ({:.0} %), {hits} bumper hits, median path {:.3}x the shortest, median {:.1} s per goal",
            100.0 * out.success_rate,
            out.path_length_ratio.median,
            out.time_s.median
        );
    }
    Ok(())
}

/// The robot in the scene, localised by SLAM (`slam`) or odometry, on the floor plan; the
/// exploration first with `--explore`.
fn set_up(a: &Args, slam: bool) -> ferrobot::Result<(Course, Option<ExploreJson>)> {
    let b = super::common::robot_builder(&a.robot);
    let bot = b
        .scene(&a.scene)
        .use_camera(slam)
        .backend(Backend::Sim {
            seed: a.seed,
            realtime: false,
        })
        .build()?;
    let base = bot.base()?;
    let radius = bot
        .config()
        .base
        .as_ref()
        .map_or(0.2, |b| b.footprint_radius);
    let plan = bot.scene().floor_plan(0.02, OBSTACLE_BAND, false)?;
    let plan_image = MapImage::from_occupied(
        plan.origin,
        plan.resolution,
        plan.width,
        plan.height,
        &plan.occupied,
    );
    let world = plan_image.to_grid(true)?;
    let clear = Obstacles::new(Vec::new(), Some(&world))?;
    let start = truth(&bot)?;
    // The frame of the goals and the map: with SLAM, the floor plan's own (SLAM starts at the
    // true start); without, the odometry's, which reads zero at the start.
    // The arm travels folded: out, its reach would be the navigator's radius.
    if bot.config().arm.as_ref().is_some_and(|a| a.stow.is_some()) {
        bot.arm()?.stow()?;
    }
    let frame = if slam {
        // The camera looks down a little, at the floor ahead and what stands on it.
        bot.head()?.set_pan_tilt(0.0, 0.45)?;
        bot.start_slam(start, None)?;
        // Its first frames: a pose and a first keyframe.
        bot.wait(0.5)?;
        [0.0, 0.0, 0.0]
    } else {
        let odo0 = base.get_state()?;
        to_planar(&(planar(start) * planar(odo0).inverse()))
    };
    let exploration = if a.explore {
        Some(explore(
            &bot,
            &plan_image,
            start,
            a.out.as_deref(),
            a.trace,
        )?)
    } else {
        None
    };
    let grid = if slam {
        world.clone()
    } else {
        resample(&world, frame)?
    };
    // After exploring, the base plans on SLAM's own map, refreshed as it goes.
    let opts = GoalOptions {
        map: (!a.explore).then_some(grid),
        use_map: a.explore,
        frame: if slam { Source::Slam } else { Source::Odometry },
        ..Default::default()
    };
    let course = Course {
        bot,
        world,
        clear,
        radius,
        frame,
        opts,
        trace: a.trace,
    };
    Ok((course, exploration))
}

/// The goal count and `--localise` checked; whether SLAM localises.
fn check(a: &Args) -> ferrobot::Result<bool> {
    let goals = a.goals;
    if !(1..=10_000).contains(&goals) {
        return Err(ferrobot::Error::Usage(format!(
            "--goals {goals}: ask for 1-10000"
        )));
    }
    match a.localise.as_str() {
        "slam" => Ok(true),
        "odometry" if a.explore => Err(ferrobot::Error::Usage(
            "--explore needs --localise slam: exploration maps with SLAM".into(),
        )),
        "odometry" => Ok(false),
        other => Err(ferrobot::Error::Usage(format!(
            "--localise {other}: say slam or odometry"
        ))),
    }
}

impl Course {
    /// A goal drawn from `rng`: free with clearance, reachable, not too near `here`; its
    /// centre and the shortest path's length (m). `None` after 10,000 draws.
    fn pick_goal(&self, rng: &mut Rng, here: [f64; 3]) -> Option<([f64; 2], f64)> {
        let world = &self.world;
        for _ in 0..10_000 {
            let i = (rng.uniform() * world.width as f64) as usize;
            let j = (rng.uniform() * world.height as f64) as usize;
            let c = world.centre(i.min(world.width - 1), j.min(world.height - 1));
            if self.clear.clearance(c) < self.radius + GOAL_CLEARANCE
                || (c[0] - here[0]).hypot(c[1] - here[1]) < MIN_GOAL_DISTANCE
            {
                continue;
            }
            if let Ok(p) = GridAStar.plan(world, [here[0], here[1]], c, self.radius) {
                return Some((c, p.length));
            }
        }
        None
    }

    /// Pick the next goal and drive to it, counting the result into `tally`; false when no
    /// goal can be reached from where the robot is.
    fn next_goal(&self, rng: &mut Rng, tally: &mut Tally) -> ferrobot::Result<bool> {
        let (bot, base) = (&self.bot, self.bot.base()?);
        let here = truth(bot)?;
        let Some((g, shortest)) = self.pick_goal(rng, here) else {
            return Ok(false);
        };
        // The goal in the odometry's frame, facing along the way there.
        let th = (g[1] - here[1]).atan2(g[0] - here[0]);
        let go = to_planar(&(planar(self.frame).inverse() * planar([g[0], g[1], th])));
        let t0 = bot.time();
        let mut travelled = 0.0;
        let mut last = here;
        // A goal refused at once (the base's place seen as blocked on a drifted map) is a miss.
        let mut motion = match base.go_to_absolute_with(go, self.opts.clone()) {
            Ok(m) => m,
            Err(e) => {
                if self.trace {
                    eprintln!("goal {g:.2?} from {here:.2?}: refused: {e}");
                }
                return Ok(true);
            }
        };
        let result = loop {
            if let Some(r) = motion.poll() {
                if self.trace {
                    if let Err(e) = &r {
                        eprintln!(
                            "goal {g:.2?} from {here:.2?}: {e}; truly at {:.3?}, SLAM says {:.3?}",
                            truth(bot)?,
                            base.get_state_from(Source::Slam).ok()
                        );
                    }
                }
                break r.is_ok();
            }
            let now = truth(bot)?;
            travelled += (now[0] - last[0]).hypot(now[1] - last[1]);
            last = now;
        };
        let now = truth(bot)?;
        travelled += (now[0] - last[0]).hypot(now[1] - last[1]);
        let bumped = bot
            .take_faults()
            .iter()
            .filter(|f| f.kind == ferrobot::FaultKind::Bumper)
            .count();
        tally.hits += bumped;
        let miss = (now[0] - g[0]).hypot(now[1] - g[1]);
        let reached = miss <= GOAL_TOLERANCE;
        if self.trace {
            eprintln!(
                "goal {g:.2?} from {here:.2?}: {} {miss:.3} m off, {bumped} bumps, {:.1} s, {travelled:.2} m for {shortest:.2} m",
                if result { "ok" } else { "failed" },
                bot.time() - t0
            );
        }
        if result && reached && bumped == 0 {
            tally.ok += 1;
            tally.ratios.push(travelled / shortest);
            tally.times.push(bot.time() - t0);
        } else if bumped > 0 {
            // Back off a little so the next goal starts free.
            let _ = base.go_to_relative([-0.1, 0.0, 0.0]);
        }
        Ok(true)
    }
}
