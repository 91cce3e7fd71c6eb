//! The export of `bench plan --export`: the problems file of the run (robot, objects and
//! problems, in the URDF root link's frame; m, rad, quaternions `[x, y, z, w]`) plus robot,
//! urdf, root_link, moving_links, self_pairs, attached, resolution_m and each problem's
//! success, time_ms and path, as `host/planning/peer/plan_peer.py` reads it.

use std::collections::BTreeMap;
use std::path::Path;

use ferrobot::planning::{bench, Checker, Shape};
use ferrobot::{Error, RobotConfig};
use ferrobot_sim::mesh::TriMesh;
use serde::Serialize;

use super::{MeshSource, Object};

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
pub(super) fn write_export(
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
    let objs = objects_json(dir, &stem, objects)?;
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

/// The objects as the export gives them; a scene's meshes written into `dir` as
/// `STEM-K-ID.obj`.
fn objects_json(dir: &Path, stem: &str, objects: &[Object]) -> ferrobot::Result<Vec<ObjectJson>> {
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
    Ok(objs)
}
