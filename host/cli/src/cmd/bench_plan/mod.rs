//! `ferrobot bench plan`: arm planning on a fixed set of problems: a seeded set generated in a
//! scene (collision-free starts and goals whose straight line collides), or a problems file
//! written by anyone ([`problems_file`]); optionally the same problems planned by OMPL (the
//! Python peer `host/planning/peer/plan_peer.py`, [`peer`]) in the same run, and an export the
//! peer reads ([`export`]); the figures as a table or JSON ([`table`]).

mod export;
mod peer;
mod problems_file;
mod table;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use ferrobot::planning::{
    self as planning, bench, checker::Engine, planner, CheckOptions, Checker, CollisionModel,
    PlanOptions, PlanningScene, Shape,
};
use ferrobot::scene::{Scene, SceneSource};
use ferrobot::{validate, Error, RobotConfig};
use ferrobot_sim::mesh::TriMesh;
use nalgebra::Isometry3;

use super::common::{load, planning_error};
use problems_file::{file_error, read_problems_file};

/// Distance within which both ends of a generated problem have some link of an object, when
/// the scene has objects (besides the floor and walls), m.
pub const NEAR: f64 = 0.05;
/// Generated problems' ends must reach the arm's home within this many times the planning
/// time limit (RRT-Connect, other seeds), or the candidate is dropped as unsolvable.
pub const REACH_FACTOR: f64 = 3.0;

/// `ferrobot bench plan`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    #[arg(long, required_unless_present = "config", conflicts_with = "config")]
    pub robot: Option<String>,
    /// Robot configuration file (the same as --robot PATH).
    #[arg(long)]
    pub config: Option<String>,
    /// Scene name or path: generated problems (collision-free starts and goals whose
    /// straight line collides, both near an object when the scene has any besides floor
    /// and walls).
    #[arg(
        long,
        required_unless_present = "problems_file",
        conflicts_with = "problems_file"
    )]
    pub scene: Option<String>,
    /// Problems file (JSON: joints, objects, problems with start and goal; an export is
    /// one) instead of generated problems.
    #[arg(long)]
    pub problems_file: Option<std::path::PathBuf>,
    /// Generated problems.
    #[arg(long, default_value_t = 100)]
    pub problems: usize,
    /// Seed of the problem set and of the planner (problem k: SEED + k).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// rrt-connect or informed-rrt-star.
    #[arg(long, default_value = "rrt-connect")]
    pub planner: String,
    /// Time limit per problem, s (OMPL's too).
    #[arg(long, default_value_t = 1.0)]
    pub time_limit: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write robot, scene, problems and paths here (JSON, as host/planning/peer/plan_peer.py
    /// reads it; a bundled robot's URDF and the scene's meshes go beside it).
    #[arg(long)]
    pub export: Option<std::path::PathBuf>,
    /// Also plan the problems with OMPL's RRTConnect (simplified) through the Python peer
    /// and compare (needs `scripts/python-env.sh plan`).
    #[arg(long)]
    pub ompl: bool,
    /// OMPL's time limit per problem, s (default: --time-limit; its Python state checks are
    /// about 0.25 ms each).
    #[arg(long, requires = "ompl")]
    pub ompl_time_limit: Option<f64>,
    /// How edges are proven: auto (the checker's choice: the vectorised engine where its
    /// spheres are conclusive), lanes (vectorised: AVX2 where the CPU has it), baseline (the
    /// same on the target's baseline instructions), scalar (its one-state path; all three give
    /// the same answers) or advancement (conservative advancement alone). Generated problems are drawn
    /// with the advancement whatever the engine, so every engine plans the same set.
    #[arg(long, default_value = "auto")]
    pub engine: String,
    /// Random shortcut attempts after a path is found (the planner's default: 60).
    #[arg(long)]
    pub shortcuts: Option<usize>,
    /// Rounds of smoothing after shortcutting, as VAMP simplifies (corner cutting and the
    /// greedy pass; the planner's default: 0).
    #[arg(long)]
    pub smoothing: Option<usize>,
}

/// The engine `--engine` names, `None` for auto.
fn engine(name: &str) -> ferrobot::Result<Option<Engine>> {
    Ok(Some(match name {
        "auto" => return Ok(None),
        "lanes" => Engine::Lanes,
        "baseline" => Engine::Baseline,
        "scalar" => Engine::Scalar,
        "advancement" => Engine::Advancement,
        _ => {
            return Err(Error::Usage(format!(
                "unknown engine {name:?}; engines are: auto, lanes, baseline, scalar, advancement"
            )))
        }
    }))
}

/// Where an object's mesh comes from.
enum MeshSource {
    /// A file, by absolute path.
    File(PathBuf),
    /// A scene's triangles (written beside the export).
    Triangles(TriMesh),
}

/// A world object in the root frame, with its mesh's source.
struct Object {
    id: String,
    shape: Shape,
    pose: Isometry3<f64>,
    mesh: Option<MeshSource>,
}

/// Problems, objects and what to call them.
struct Workload {
    /// The scene's name or the problems file.
    label: String,
    objects: Vec<Object>,
    problems: Vec<bench::Problem>,
}

/// Whether a scene body is the floor or a piece of wall (`wall{i}.{k}`).
fn is_floor_or_wall(id: &str) -> bool {
    id == "floor"
        || id.strip_prefix("wall").is_some_and(|rest| {
            rest.split_once('.').is_some_and(|(i, k)| {
                !i.is_empty()
                    && !k.is_empty()
                    && i.bytes().all(|b| b.is_ascii_digit())
                    && k.bytes().all(|b| b.is_ascii_digit())
            })
        })
}

/// Every body of `scene` (floor and walls too) in the frame of the robot's root link.
fn scene_objects(scene: &Scene) -> Vec<Object> {
    let inv = ferrobot::planning::root_in_world(scene).inverse();
    scene
        .bodies
        .iter()
        .map(|b| Object {
            id: b.id.clone(),
            shape: ferrobot::planning::shape_of(&b.shape),
            pose: inv * b.pose,
            mesh: match &b.shape {
                ferrobot::scene::Shape::Mesh { mesh, .. } => {
                    Some(MeshSource::Triangles(mesh.clone()))
                }
                _ => None,
            },
        })
        .collect()
}

/// The planning scene of `objects`; errors name `file` and the object.
fn planning_scene(file: &Path, objects: &[Object]) -> ferrobot::Result<PlanningScene> {
    let mut scene = PlanningScene::new();
    for (i, o) in objects.iter().enumerate() {
        scene
            .add_object(&o.id, o.shape.clone(), o.pose)
            .map_err(|e| file_error(file, format!("objects[{i}] ({:?})", o.id), e.to_string()))?;
    }
    Ok(scene)
}

/// `v` if finite.
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// Run the benchmark and print it.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let robot = a
        .robot
        .as_deref()
        .or(a.config.as_deref())
        .unwrap_or_default();
    let ompl_time_limit = a.ompl_time_limit.unwrap_or(a.time_limit);
    let planner = check(a, ompl_time_limit)?;
    let cfg = load(robot)?;
    if a.ompl {
        peer::preflight()?;
    }
    let mut model = CollisionModel::from_config(&cfg).map_err(|e| planning_error(&cfg.file, e))?;
    let work = workload(a, &mut model)?;
    let source = a.problems_file.as_deref().map_or_else(
        || PathBuf::from(format!("scene {}", work.label)),
        Path::to_path_buf,
    );
    let scene = planning_scene(&source, &work.objects)?;
    let mut checker = Checker::new(Arc::new(model), &scene, CheckOptions::default())
        .map_err(|e| planning_error(&source, e))?;
    let (problems, unreached) = problems(a, &cfg, &mut checker, &work, &source)?;
    let defaults = PlanOptions::default();
    let opts = PlanOptions {
        time_limit: Duration::from_secs_f64(a.time_limit),
        seed: a.seed,
        range: cfg.arm.as_ref().and_then(|arm| arm.planning_range),
        shortcuts: a.shortcuts.unwrap_or(defaults.shortcuts),
        smoothing: a.smoothing.unwrap_or(defaults.smoothing),
        ..defaults
    };
    let (outcomes, summary) = bench::run(&checker, planner.as_ref(), &problems, &opts);
    let (export_path, _temp) = export_path(a)?;
    if let Some(p) = &export_path {
        export::write_export(p, &cfg, &checker, &work.objects, &problems, &outcomes)?;
    }
    let peer = match (&export_path, a.ompl) {
        (Some(p), true) => Some(peer::compare(
            p,
            ompl_time_limit,
            a.seed,
            opts.range,
            summary.time_ms[0],
        )?),
        _ => None,
    };
    let report = table::Report {
        robot: &cfg.name,
        planner: planner.name(),
        engine: checker.engine(),
        label: work.label,
        summary: &summary,
        unreached,
        peer,
        outcomes: &outcomes,
    };
    table::print(a, ompl_time_limit, report);
    Ok(())
}

/// The problems (the file's, or generated with the advancement so that every engine plans
/// the same set) and the candidates dropped as unsolvable; `checker` then proves edges with
/// `--engine`'s engine.
fn problems(
    a: &Args,
    cfg: &RobotConfig,
    checker: &mut Checker,
    work: &Workload,
    source: &Path,
) -> ferrobot::Result<(Vec<bench::Problem>, Option<usize>)> {
    let set_engine = |c: &mut Checker, e| c.set_engine(e).map_err(|e| planning_error(source, e));
    let chosen = checker.engine();
    let out = if a.problems_file.is_some() {
        (work.problems.clone(), None)
    } else {
        set_engine(checker, Engine::Advancement)?;
        let generated = generate(a, cfg, checker, work)?;
        set_engine(checker, chosen)?;
        generated
    };
    if let Some(e) = engine(&a.engine)? {
        set_engine(checker, e)?;
    }
    Ok(out)
}

/// The planner, and the arguments checked before anything is read.
fn check(a: &Args, ompl_time_limit: f64) -> ferrobot::Result<Box<dyn planner::Planner>> {
    engine(&a.engine)?;
    if a.smoothing.is_some_and(|n| n > planner::MAX_SMOOTHING)
        || a.shortcuts.is_some_and(|n| n > planner::MAX_SHORTCUTS)
    {
        return Err(Error::Usage(format!(
            "--smoothing {:?} must be at most {} and --shortcuts {:?} at most {}",
            a.smoothing,
            planner::MAX_SMOOTHING,
            a.shortcuts,
            planner::MAX_SHORTCUTS
        )));
    }
    let planner = planner::by_name(&a.planner).ok_or_else(|| {
        Error::Usage(format!(
            "unknown planner {:?}; planners are: {}",
            a.planner,
            planner::PLANNERS.join(", ")
        ))
    })?;
    validate::in_range(
        "time limit (s)",
        a.time_limit,
        1e-3,
        planning::planner::MAX_TIME_LIMIT,
    )?;
    validate::in_range(
        "OMPL's time limit (s)",
        ompl_time_limit,
        1e-3,
        planning::planner::MAX_TIME_LIMIT,
    )?;
    if let Some(p) = a.export.as_deref() {
        // Refused before planning, not after.
        let dir = p.parent().filter(|d| !d.as_os_str().is_empty());
        if p.is_dir() || dir.is_some_and(|d| !d.is_dir()) || p.file_stem().is_none() {
            return Err(Error::Usage(format!(
                "--export {}: not a file in an existing directory",
                p.display()
            )));
        }
    }
    Ok(planner)
}

/// The scene's objects (problems generated later) or the problems file's objects and
/// problems.
fn workload(a: &Args, model: &mut CollisionModel) -> ferrobot::Result<Workload> {
    Ok(match (a.scene.as_deref(), a.problems_file.as_deref()) {
        (Some(_), Some(_)) => {
            return Err(Error::Usage(
                "give --scene (generated problems) or --problems-file, not both".into(),
            ))
        }
        (None, None) => {
            return Err(Error::Usage(
                "give --scene (generated problems) or --problems-file".into(),
            ))
        }
        (None, Some(file)) => read_problems_file(file, model)?,
        (Some(name), None) => {
            validate::count("problems", a.problems, 1..=bench::MAX_PROBLEMS)?;
            let scene = Scene::load(&SceneSource::from_arg(name))?;
            Workload {
                label: scene.name.clone(),
                objects: scene_objects(&scene),
                problems: Vec::new(),
            }
        }
    })
}

/// The generated problems (solvable only: both ends reach the arm's home, when it is free),
/// and how many candidates were dropped (`None` when home is not free).
fn generate(
    a: &Args,
    cfg: &RobotConfig,
    checker: &Checker,
    work: &Workload,
) -> ferrobot::Result<(Vec<bench::Problem>, Option<usize>)> {
    let near = if work.objects.iter().any(|o| !is_floor_or_wall(&o.id)) {
        NEAR
    } else {
        0.0
    };
    // Solvable problems only: both ends reach the arm's home, when it is free.
    let reach = cfg
        .arm
        .as_ref()
        .map(|arm| bench::Reach {
            hub: arm.home.clone(),
            // Within the planner's own bound, which a long `--time-limit` would pass.
            within: Duration::from_secs_f64(
                (REACH_FACTOR * a.time_limit).min(planning::planner::MAX_TIME_LIMIT),
            ),
        })
        .filter(|r| checker.is_free(&r.hub));
    let set = bench::generate(checker, a.problems, a.seed, near, reach.as_ref()).map_err(|e| {
        Error::Usage(format!(
            "cannot make {} problems for {} in {}: {e}",
            a.problems, cfg.name, work.label
        ))
    })?;
    Ok((set.problems, reach.map(|_| set.unreached)))
}

/// Where the export goes: `--export`, or with `--ompl` alone a temporary directory's
/// `export.json` (the directory removed when the guard is dropped).
fn export_path(a: &Args) -> ferrobot::Result<(Option<PathBuf>, Option<peer::TempDir>)> {
    Ok(match (a.export.as_deref(), a.ompl) {
        (Some(p), _) => (Some(p.to_path_buf()), None),
        (None, true) => {
            let dir =
                std::env::temp_dir().join(format!("ferrobot-bench-plan-{}", std::process::id()));
            std::fs::create_dir_all(&dir)?;
            let temp = peer::TempDir(dir.clone());
            (Some(dir.join("export.json")), Some(temp))
        }
        (None, false) => (None, None),
    })
}
