//! `ferrobot bench plan`: arm planning on a fixed set of problems: a seeded set generated in a
//! scene (collision-free starts and goals whose straight line collides), or a problems file
//! written by anyone; optionally the same problems planned by OMPL (the Python peer
//! `host/planning/peer/plan_peer.py`) in the same run, and an export the peer reads.
//!
//! Problems-file and export formats, in the URDF root link's frame (m, rad; quaternions
//! `[x, y, z, w]`):
//!
//! ```text
//! problems file: {"joints": [arm joints], "objects": [OBJECT], "problems": [{"start", "goal"}],
//!                 "fixed_joints": {name: value} (optional)}
//! OBJECT:        {"id", "shape": box|cylinder|sphere|capsule|mesh, "size": box [x, y, z],
//!                 cylinder and capsule [radius, length], sphere [radius], mesh its extents
//!                 (ignored), "position": [x, y, z] (optional: the origin),
//!                 "quaternion": [x, y, z, w] (optional: no rotation),
//!                 "mesh": OBJ/STL path relative to the file (its vertices' hull) or null;
//!                 other keys are errors, but for `scene --json`'s "colour" and "static"}
//! export:        the problems file plus robot, urdf, root_link, moving_links, self_pairs,
//!                attached, resolution_m and each problem's success, time_ms and path
//! ```
//!
//! An export is a problems file: `--problems-file EXPORT` plans the same problems again.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use ferrobot::planning::{
    self as planning, bench, planner, CheckOptions, Checker, CollisionModel, PlanOptions,
    PlanningScene, Shape,
};
use ferrobot::scene::{Scene, SceneSource};
use ferrobot::{validate, Error, RobotConfig};
use ferrobot_sim::mesh::TriMesh;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

use super::common::{load, planning_error, print_json};

/// Distance within which both ends of a generated problem have some link of an object, when
/// the scene has objects (besides the floor and walls), m.
pub const NEAR: f64 = 0.05;
/// Generated problems' ends must reach the arm's home within this many times the planning
/// time limit (RRT-Connect, other seeds), or the candidate is dropped as unsolvable.
pub const REACH_FACTOR: f64 = 3.0;
/// Largest problems file read, bytes.
pub const MAX_PROBLEMS_FILE_BYTES: u64 = 256 << 20;
/// How far a problems file's quaternion may be from unit length (it is normalised).
const QUATERNION_SLACK: f64 = 1e-3;

/// What `bench plan` was asked.
pub struct PlanArgs<'a> {
    /// Robot name or configuration path.
    pub robot: &'a str,
    /// Scene name or path (generated problems), or `None` with `problems_file`.
    pub scene: Option<&'a str>,
    /// A problems file to run instead of generated problems.
    pub problems_file: Option<&'a Path>,
    /// Generated problems.
    pub problems: usize,
    /// Seed of the problem set and of the planners (problem k: `seed + k`).
    pub seed: u64,
    /// Planner name.
    pub planner: &'a str,
    /// Time limit per problem, s.
    pub time_limit: f64,
    /// One JSON line instead of a table.
    pub json: bool,
    /// Where to write the export.
    pub export: Option<&'a Path>,
    /// Also run OMPL on the same problems.
    pub ompl: bool,
    /// OMPL's time limit per problem, s.
    pub ompl_time_limit: f64,
}

/// `bench plan --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct SummaryJson {
    /// Sphere-level collision checks (covering and bounding spheres against obstacles and
    /// each other, as run) per second of planning time.
    collision_checks_per_s: f64,
    /// Joint-space path length of the solved problems, rad.
    path_length_rad: LengthJson,
    /// OMPL's summary on the same problems (with `--ompl`).
    #[serde(skip_serializing_if = "Option::is_none")]
    peer: Option<serde_json::Value>,
    /// The planner.
    planner: String,
    /// Problems planned.
    problems: usize,
    /// The robot.
    robot: String,
    /// The scene (or the problems file).
    scene: String,
    /// Fraction solved.
    success_rate: f64,
    /// Time per problem (failures at their full time), ms.
    time_ms: TimeJson,
    /// Generated candidates dropped because an end did not reach the arm's home within
    /// `REACH_FACTOR` times the time limit, at most the planner's 600 s (absent for problems files and when home is not
    /// free).
    #[serde(skip_serializing_if = "Option::is_none")]
    unreached: Option<usize>,
}

/// Path length statistics.
#[derive(Serialize)]
struct LengthJson {
    /// Median, rad (null when nothing was solved).
    median: Option<f64>,
}

/// Time statistics, ms.
#[derive(Serialize)]
struct TimeJson {
    /// Largest.
    max: f64,
    /// Median.
    median: f64,
    /// 95th percentile (nearest rank).
    p95: f64,
}

/// The export (`--export`), fields in alphabetical order.
#[derive(Serialize)]
struct ExportJson<'a> {
    /// Objects attached to the robot (none).
    attached: Vec<serde_json::Value>,
    /// Values of the joints that are not planned, rad or m.
    fixed_joints: BTreeMap<String, f64>,
    /// The planned joints, in order.
    joints: &'a [String],
    /// Links that move with the planned joints.
    moving_links: Vec<String>,
    /// World objects, root frame.
    objects: Vec<ObjectJson>,
    /// The problems and their outcomes.
    problems: Vec<ProblemJson>,
    /// Largest robot-point motion between states checked while searching, m.
    resolution_m: f64,
    /// Robot name.
    robot: &'a str,
    /// The URDF's root link: the frame of everything here.
    root_link: &'a str,
    /// Body pairs checked against each other (moving link, other link).
    self_pairs: Vec<[String; 2]>,
    /// The URDF, absolute or relative to the export.
    urdf: String,
}

/// An object of the export and of a problems file.
#[derive(Serialize)]
struct ObjectJson {
    /// Its id.
    id: String,
    /// The mesh file (absolute or relative to the export), or null.
    mesh: Option<String>,
    /// Position of its frame's origin, m.
    position: [f64; 3],
    /// Orientation `[x, y, z, w]`.
    quaternion: [f64; 4],
    /// `box`, `cylinder`, `sphere`, `capsule` or `mesh`.
    shape: &'static str,
    /// Box: extents; cylinder and capsule: radius and length; sphere: radius; mesh: extents
    /// of its vertices' box, m.
    size: Vec<f64>,
}

/// A problem of the export.
#[derive(Serialize)]
struct ProblemJson {
    /// Goal, rad.
    goal: Vec<f64>,
    /// The path found (empty on failure), rad.
    path: Vec<Vec<f64>>,
    /// Start, rad.
    start: Vec<f64>,
    /// Whether a path was found.
    success: bool,
    /// Time spent, ms.
    time_ms: f64,
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

/// A problems file as read: objects and problems are checked one by one below.
#[derive(Deserialize)]
struct ProblemsFile {
    joints: Vec<String>,
    #[serde(default)]
    objects: Vec<serde_json::Value>,
    problems: Vec<serde_json::Value>,
    #[serde(default)]
    fixed_joints: BTreeMap<String, f64>,
    #[serde(default)]
    attached: Vec<serde_json::Value>,
}

/// An object of a problems file. Unknown keys are errors (a misspelt `position` would leave
/// the object at the origin); `colour` and `static`, which `ferrobot scene --json` prints, are
/// read and ignored.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectFile {
    id: String,
    shape: String,
    #[serde(default)]
    size: Vec<f64>,
    #[serde(default)]
    position: Option<[f64; 3]>,
    #[serde(default)]
    quaternion: Option<[f64; 4]>,
    #[serde(default)]
    mesh: Option<String>,
    #[serde(default, rename = "colour")]
    _colour: Option<serde::de::IgnoredAny>,
    #[serde(default, rename = "static")]
    _fixed: Option<serde::de::IgnoredAny>,
}

#[derive(Deserialize)]
struct ProblemFile {
    start: Vec<f64>,
    goal: Vec<f64>,
}

fn file_error(file: &Path, key: impl Into<String>, problem: impl Into<String>) -> Error {
    Error::Config {
        file: file.to_path_buf(),
        key: key.into(),
        problem: problem.into(),
    }
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

/// The pose of a problems file's object; `key` names it in errors.
fn object_pose(file: &Path, key: &str, o: &ObjectFile) -> ferrobot::Result<Isometry3<f64>> {
    let p = o.position.unwrap_or([0.0; 3]);
    let q = o.quaternion.unwrap_or([0.0, 0.0, 0.0, 1.0]);
    if p.iter().chain(&q).any(|v| !v.is_finite()) {
        return Err(file_error(file, key, "its pose is not finite"));
    }
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > QUATERNION_SLACK {
        return Err(file_error(
            file,
            key,
            format!("quaternion {q:?} is not of unit length (its norm is {norm})"),
        ));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2])),
    ))
}

/// The shape of a problems file's object (a mesh read relative to `dir`).
fn object_shape(
    file: &Path,
    dir: &Path,
    key: &str,
    o: &ObjectFile,
) -> ferrobot::Result<(Shape, Option<MeshSource>)> {
    let need = |n: usize| -> ferrobot::Result<()> {
        if o.size.len() != n {
            return Err(file_error(
                file,
                key,
                format!("a {} takes {n} size values, got {}", o.shape, o.size.len()),
            ));
        }
        Ok(())
    };
    let s = &o.size;
    let shape = match o.shape.as_str() {
        "box" => {
            need(3)?;
            Shape::Box([s[0], s[1], s[2]])
        }
        "cylinder" => {
            need(2)?;
            Shape::Cylinder {
                radius: s[0],
                length: s[1],
            }
        }
        "capsule" => {
            need(2)?;
            Shape::Capsule {
                radius: s[0],
                length: s[1],
            }
        }
        "sphere" => {
            need(1)?;
            Shape::Sphere(s[0])
        }
        "mesh" => {
            let name =
                o.mesh.as_deref().filter(|m| !m.is_empty()).ok_or_else(|| {
                    file_error(file, key, "a mesh object needs its \"mesh\" file")
                })?;
            let path = dir.join(name);
            let bytes = ferrobot::config::read_bytes(&path, ferrobot_sim::scene::MAX_MESH_BYTES)
                .map_err(|e| {
                    file_error(file, key, format!("cannot read {}: {e}", path.display()))
                })?;
            let mesh = ferrobot_sim::mesh::parse(name, &bytes)
                .map_err(|e| file_error(file, key, format!("{}: {e}", path.display())))?;
            let abs = std::path::absolute(&path).unwrap_or(path);
            return Ok((Shape::Hull(mesh.vertices), Some(MeshSource::File(abs))));
        }
        other => {
            return Err(file_error(
                file,
                key,
                format!("unknown shape {other:?}; box, cylinder, sphere, capsule or mesh"),
            ))
        }
    };
    Ok((shape, None))
}

/// A problems file's joints, objects and problems for `model` (its fixed joints set).
fn read_problems_file(file: &Path, model: &mut CollisionModel) -> ferrobot::Result<Workload> {
    let text = ferrobot::config::read_text(file, MAX_PROBLEMS_FILE_BYTES)
        .map_err(|e| file_error(file, "-", format!("cannot read: {e}")))?;
    let f: ProblemsFile = serde_json::from_str(&text)
        .map_err(|e| file_error(file, "-", format!("not a problems file: {e}")))?;
    if f.joints != model.joint_names() {
        return Err(file_error(
            file,
            "joints",
            format!(
                "{:?} are not {}'s arm joints {:?}",
                f.joints,
                model.name(),
                model.joint_names()
            ),
        ));
    }
    if !f.attached.is_empty() {
        return Err(file_error(
            file,
            "attached",
            "attached objects are not supported",
        ));
    }
    for (name, value) in &f.fixed_joints {
        model
            .set_value(name, *value)
            .map_err(|e| file_error(file, format!("fixed_joints.{name}"), e.to_string()))?;
    }
    let dir = file.parent().unwrap_or(Path::new("."));
    let mut objects: Vec<Object> = Vec::with_capacity(f.objects.len());
    for (i, v) in f.objects.into_iter().enumerate() {
        let mut key = format!("objects[{i}]");
        let o: ObjectFile =
            serde_json::from_value(v).map_err(|e| file_error(file, &key, e.to_string()))?;
        key = format!("objects[{i}] ({:?})", o.id);
        if objects.iter().any(|x| x.id == o.id) {
            return Err(file_error(file, key, "another object has this id"));
        }
        let pose = object_pose(file, &key, &o)?;
        let (shape, mesh) = object_shape(file, dir, &key, &o)?;
        objects.push(Object {
            id: o.id,
            shape,
            pose,
            mesh,
        });
    }
    if !(1..=bench::MAX_PROBLEMS).contains(&f.problems.len()) {
        return Err(file_error(
            file,
            "problems",
            format!(
                "{} problems; between 1 and {} are planned",
                f.problems.len(),
                bench::MAX_PROBLEMS
            ),
        ));
    }
    let dof = model.dof();
    let limits = model.limits().to_vec();
    let mut problems = Vec::with_capacity(f.problems.len());
    for (i, v) in f.problems.into_iter().enumerate() {
        let p: ProblemFile = serde_json::from_value(v)
            .map_err(|e| file_error(file, format!("problems[{i}]"), e.to_string()))?;
        for (what, q) in [("start", &p.start), ("goal", &p.goal)] {
            let key = format!("problems[{i}].{what}");
            if q.len() != dof {
                return Err(file_error(
                    file,
                    key,
                    format!("{} values for {dof} joints", q.len()),
                ));
            }
            for ((v, (lo, hi)), name) in q.iter().zip(&limits).zip(model.joint_names()) {
                if !(v.is_finite() && *v >= lo - 1e-9 && *v <= hi + 1e-9) {
                    return Err(file_error(
                        file,
                        key,
                        format!("{name} = {v} is outside its limits [{lo}, {hi}]"),
                    ));
                }
            }
        }
        problems.push(bench::Problem {
            start: p.start,
            goal: p.goal,
        });
    }
    Ok(Workload {
        label: file.display().to_string(),
        objects,
        problems,
    })
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

/// Size as the export gives it.
fn size_of(shape: &Shape) -> Vec<f64> {
    match shape {
        Shape::Box(s) => s.to_vec(),
        Shape::Cylinder { radius, length } | Shape::Capsule { radius, length } => {
            vec![*radius, *length]
        }
        Shape::Sphere(r) => vec![*r],
        Shape::Hull(_) => {
            let (lo, hi) = shape.bounds();
            (hi - lo).iter().copied().collect()
        }
    }
}

/// `s` with every character but letters, digits, `-` and `_` replaced by `_`.
fn file_safe(s: &str) -> String {
    s.chars()
        .take(64)
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// A mesh as OBJ text (1-based faces).
fn obj_text(mesh: &TriMesh) -> String {
    let mut s = String::new();
    for v in &mesh.vertices {
        s.push_str(&format!("v {} {} {}\n", v.x, v.y, v.z));
    }
    for t in &mesh.triangles {
        s.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    s
}

/// Writes the export to `path`; a bundled robot's URDF and a scene's meshes go beside it
/// (`STEM.urdf`, `STEM-K-ID.obj`) and are named relative to it.
fn write_export(
    path: &Path,
    cfg: &RobotConfig,
    checker: &Checker,
    objects: &[Object],
    problems: &[bench::Problem],
    outcomes: &[bench::Outcome],
) -> ferrobot::Result<()> {
    let model = checker.model();
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .ok_or_else(|| Error::Usage(format!("--export {}: not a file name", path.display())))?;
    let urdf = match model.urdf_file() {
        Some(p) => std::path::absolute(p)?.display().to_string(),
        None => {
            let (_, text) = ferrobot::config::bundled_files(&cfg.name).ok_or_else(|| {
                Error::Usage(format!("{}: no URDF file to name in the export", cfg.name))
            })?;
            let name = format!("{stem}.urdf");
            std::fs::write(dir.join(&name), text)?;
            name
        }
    };
    let mut objs = Vec::with_capacity(objects.len());
    for (k, o) in objects.iter().enumerate() {
        let mesh = match &o.mesh {
            None => None,
            Some(MeshSource::File(p)) => Some(p.display().to_string()),
            Some(MeshSource::Triangles(m)) => {
                let name = format!("{stem}-{k}-{}.obj", file_safe(&o.id));
                std::fs::write(dir.join(&name), obj_text(m))?;
                Some(name)
            }
        };
        let t = o.pose.translation.vector;
        let q = o.pose.rotation.coords;
        objs.push(ObjectJson {
            id: o.id.clone(),
            mesh,
            position: [t.x, t.y, t.z],
            quaternion: [q.x, q.y, q.z, q.w],
            shape: o.shape.kind(),
            size: size_of(&o.shape),
        });
    }
    let export = ExportJson {
        attached: Vec::new(),
        fixed_joints: model.fixed_values().into_iter().collect(),
        joints: model.joint_names(),
        moving_links: checker.moving_links(),
        objects: objs,
        problems: problems
            .iter()
            .zip(outcomes)
            .map(|(p, o)| ProblemJson {
                goal: p.goal.clone(),
                path: o.path.clone(),
                start: p.start.clone(),
                success: o.success,
                time_ms: o.time_ms,
            })
            .collect(),
        resolution_m: checker.options().resolution,
        robot: &cfg.name,
        root_link: model.tree().root(),
        self_pairs: checker
            .self_pairs()
            .into_iter()
            .map(|(a, b)| [a, b])
            .collect(),
        urdf,
    };
    // Plain structs of numbers, strings and sequences: serialising them cannot fail.
    let text = serde_json::to_string_pretty(&export).expect("a plain struct serialises");
    std::fs::write(path, text + "\n")?;
    Ok(())
}

fn peer_error(why: String) -> Error {
    Error::Io(std::io::Error::other(format!(
        "the OMPL peer: {why}; `scripts/python-env.sh plan` installs OMPL and FCL into \
         target/py-venv (or set FERROBOT_PYTHON to a Python that has them)"
    )))
}

/// Checks, before any planning, that the peer's Python has OMPL and FCL.
fn peer_preflight() -> ferrobot::Result<()> {
    let python = ferrobot_peers::python();
    let out = Command::new(&python)
        .args(["-c", "import ompl.geometric, fcl, numpy"])
        .output()
        .map_err(|e| peer_error(format!("cannot run {}: {e}", python.display())))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().rev().find(|l| !l.trim().is_empty());
        return Err(peer_error(format!(
            "{} cannot import OMPL and FCL: {}",
            python.display(),
            last.unwrap_or("no message")
        )));
    }
    Ok(())
}

/// Runs OMPL's RRTConnect (the peer, with simplification) on the export at `path` with our
/// time limit (s), seed and extension step (rad; `None`: OMPL's default, as ours); its
/// summary.
fn run_peer(
    path: &Path,
    time_limit: f64,
    seed: u64,
    range: Option<f64>,
) -> ferrobot::Result<serde_json::Value> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../planning/peer/plan_peer.py");
    if !script.is_file() {
        return Err(peer_error(format!("{} is missing", script.display())));
    }
    let python = ferrobot_peers::python();
    let out = Command::new(&python)
        .arg(&script)
        .arg("ompl")
        .arg(path)
        .arg("--simplify")
        .args(["--time-limit", &time_limit.to_string()])
        // OMPL's seed is 32-bit.
        .args(["--seed", &(seed % (1 << 31)).to_string()])
        .args(["--range", &range.unwrap_or(0.0).to_string()])
        .output()
        .map_err(|e| peer_error(format!("cannot run {}: {e}", python.display())))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("no message");
        return Err(peer_error(format!(
            "{} failed ({}): {last}",
            python.display(),
            out.status
        )));
    }
    serde_json::from_slice(&out.stdout)
        .map_err(|e| peer_error(format!("its output is not JSON: {e}")))
}

/// Cleans up a temporary directory when dropped.
struct TempDir(PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

fn ms(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.1}"))
}

/// Run the benchmark and print it.
pub fn run(a: &PlanArgs) -> ferrobot::Result<()> {
    let planner = planner::by_name(a.planner).ok_or_else(|| {
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
        a.ompl_time_limit,
        1e-3,
        planning::planner::MAX_TIME_LIMIT,
    )?;
    if let Some(p) = a.export {
        // Refused before planning, not after.
        let dir = p.parent().filter(|d| !d.as_os_str().is_empty());
        if p.is_dir() || dir.is_some_and(|d| !d.is_dir()) || p.file_stem().is_none() {
            return Err(Error::Usage(format!(
                "--export {}: not a file in an existing directory",
                p.display()
            )));
        }
    }
    let cfg = load(a.robot)?;
    if a.ompl {
        peer_preflight()?;
    }
    let mut model = CollisionModel::from_config(&cfg).map_err(|e| planning_error(&cfg.file, e))?;
    let work = match (a.scene, a.problems_file) {
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
        (None, Some(file)) => read_problems_file(file, &mut model)?,
        (Some(name), None) => {
            validate::count("problems", a.problems, 1..=bench::MAX_PROBLEMS)?;
            let scene = Scene::load(&SceneSource::from_arg(name))?;
            Workload {
                label: scene.name.clone(),
                objects: scene_objects(&scene),
                problems: Vec::new(),
            }
        }
    };
    let source = a.problems_file.map_or_else(
        || PathBuf::from(format!("scene {}", work.label)),
        Path::to_path_buf,
    );
    let scene = planning_scene(&source, &work.objects)?;
    let checker = Checker::new(Arc::new(model), &scene, CheckOptions::default())
        .map_err(|e| planning_error(&source, e))?;
    let (problems, unreached) = if a.problems_file.is_some() {
        (work.problems, None)
    } else {
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
        let set =
            bench::generate(&checker, a.problems, a.seed, near, reach.as_ref()).map_err(|e| {
                Error::Usage(format!(
                    "cannot make {} problems for {} in {}: {e}",
                    a.problems, cfg.name, work.label
                ))
            })?;
        (set.problems, reach.map(|_| set.unreached))
    };
    let opts = PlanOptions {
        time_limit: Duration::from_secs_f64(a.time_limit),
        seed: a.seed,
        range: cfg.arm.as_ref().and_then(|arm| arm.planning_range),
        ..PlanOptions::default()
    };
    let (outcomes, summary) = bench::run(&checker, planner.as_ref(), &problems, &opts);
    let _temp;
    let export_path = match (a.export, a.ompl) {
        (Some(p), _) => Some(p.to_path_buf()),
        (None, true) => {
            let dir =
                std::env::temp_dir().join(format!("ferrobot-bench-plan-{}", std::process::id()));
            std::fs::create_dir_all(&dir)?;
            _temp = TempDir(dir.clone());
            Some(dir.join("export.json"))
        }
        (None, false) => None,
    };
    if let Some(p) = &export_path {
        write_export(p, &cfg, &checker, &work.objects, &problems, &outcomes)?;
    }
    let peer = match (&export_path, a.ompl) {
        (Some(p), true) => {
            let mut v = run_peer(p, a.ompl_time_limit, a.seed, opts.range)?;
            let theirs = v["time_ms"]["median"].as_f64();
            let ratio = theirs.map(|t| t / summary.time_ms[0]).and_then(finite);
            if let Some(o) = v.as_object_mut() {
                o.insert("ratio_median".into(), serde_json::json!(ratio));
            }
            Some(v)
        }
        _ => None,
    };
    if a.json {
        print_json(&SummaryJson {
            collision_checks_per_s: summary.sphere_checks_per_s,
            path_length_rad: LengthJson {
                median: finite(summary.path_length_median),
            },
            peer,
            planner: planner.name().to_string(),
            problems: summary.problems,
            robot: cfg.name.clone(),
            scene: work.label,
            success_rate: summary.success_rate,
            time_ms: TimeJson {
                max: summary.time_ms[2],
                median: summary.time_ms[0],
                p95: summary.time_ms[1],
            },
            unreached,
        });
        return Ok(());
    }
    say!(
        "{} in {}: {} problems, {} s per problem at most{}",
        cfg.name,
        work.label,
        summary.problems,
        a.time_limit,
        if a.ompl {
            format!(" ({} s for OMPL)", a.ompl_time_limit)
        } else {
            String::new()
        }
    );
    if let Some(k) = unreached {
        say!(
            "({k} candidates dropped: an end did not reach the arm's home within {} s)",
            REACH_FACTOR * a.time_limit
        );
    }
    say!("");
    say!("| planner | success | median ms | p95 ms | max ms | median path rad | sphere checks/s |");
    say!("|---|---|---|---|---|---|---|");
    say!(
        "| {} | {:.1}% | {:.2} | {:.2} | {:.2} | {} | {:.3e} |",
        planner.name(),
        100.0 * summary.success_rate,
        summary.time_ms[0],
        summary.time_ms[1],
        summary.time_ms[2],
        finite(summary.path_length_median).map_or("-".into(), |v| format!("{v:.3}")),
        summary.sphere_checks_per_s
    );
    if let Some(v) = &peer {
        let t = &v["time_ms"];
        say!(
            "| OMPL {} RRTConnect + simplify | {:.1}% | {} | {} | {} | {} | - |",
            v["ompl_version"].as_str().unwrap_or("?"),
            100.0 * v["success_rate"].as_f64().unwrap_or(f64::NAN),
            ms(t["median"].as_f64()),
            ms(t["p95"].as_f64()),
            ms(t["max"].as_f64()),
            v["path_length_rad"]["median"]
                .as_f64()
                .map_or("-".into(), |v| format!("{v:.3}")),
        );
        say!("");
        say!(
            "OMPL's median time / ours: {}",
            v["ratio_median"]
                .as_f64()
                .map_or("-".into(), |r| format!("{r:.1}")),
        );
    }
    let failed: Vec<String> = outcomes
        .iter()
        .enumerate()
        .filter(|(_, o)| !o.success)
        .take(5)
        .map(|(i, o)| format!("problem {i}: {}", o.error.as_deref().unwrap_or("failed")))
        .collect();
    if !failed.is_empty() {
        say!("");
        say!("failures (first {}):", failed.len());
        for f in failed {
            say!("  {f}");
        }
    }
    Ok(())
}
