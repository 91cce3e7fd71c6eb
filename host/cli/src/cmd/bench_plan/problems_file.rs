//! Problems files: joints, objects and problems read and checked one by one, every error
//! naming the file and the key at fault. In the URDF root link's frame (m, rad; quaternions
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
//! ```
//!
//! An export ([`super::export`]) is a problems file: `--problems-file EXPORT` plans the same
//! problems again.

use std::collections::BTreeMap;
use std::path::Path;

use ferrobot::planning::{bench, CollisionModel, Shape};
use ferrobot::Error;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::Deserialize;

use super::{MeshSource, Object, Workload};

/// Largest problems file read, bytes.
pub const MAX_PROBLEMS_FILE_BYTES: u64 = 256 << 20;
/// How far a problems file's quaternion may be from unit length (it is normalised).
const QUATERNION_SLACK: f64 = 1e-3;

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

/// The configuration error of `file` at `key`.
pub(super) fn file_error(file: &Path, key: impl Into<String>, problem: impl Into<String>) -> Error {
    Error::Config {
        file: file.to_path_buf(),
        key: key.into(),
        problem: problem.into(),
    }
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
pub(super) fn read_problems_file(
    file: &Path,
    model: &mut CollisionModel,
) -> ferrobot::Result<Workload> {
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
    let objects = read_objects(file, f.objects)?;
    let problems = read_problems(file, model, f.problems)?;
    Ok(Workload {
        label: file.display().to_string(),
        objects,
        problems,
    })
}

/// The objects of a problems file, each checked (ids unique, pose, shape).
fn read_objects(file: &Path, values: Vec<serde_json::Value>) -> ferrobot::Result<Vec<Object>> {
    let dir = file.parent().unwrap_or(Path::new("."));
    let mut objects: Vec<Object> = Vec::with_capacity(values.len());
    for (i, v) in values.into_iter().enumerate() {
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
    Ok(objects)
}

/// The problems of a problems file: between 1 and [`bench::MAX_PROBLEMS`], each end with a
/// value per joint of `model`, within its limits.
fn read_problems(
    file: &Path,
    model: &CollisionModel,
    values: Vec<serde_json::Value>,
) -> ferrobot::Result<Vec<bench::Problem>> {
    if !(1..=bench::MAX_PROBLEMS).contains(&values.len()) {
        return Err(file_error(
            file,
            "problems",
            format!(
                "{} problems; between 1 and {} are planned",
                values.len(),
                bench::MAX_PROBLEMS
            ),
        ));
    }
    let dof = model.dof();
    let limits = model.limits().to_vec();
    let mut problems = Vec::with_capacity(values.len());
    for (i, v) in values.into_iter().enumerate() {
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
    Ok(problems)
}
