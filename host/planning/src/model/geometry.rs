//! Each link's collision geometry from a URDF: its shapes (primitives; meshes as the convex
//! hull of their vertices, m), its conservative sphere set and the exact shapes, in the
//! link's frame.

use std::path::{Path, PathBuf};

use ferrobot_description::RobotConfig;
use ferrobot_kinematics::{pose_from_urdf, LinkTree};
use nalgebra::{Isometry3, Point3};

use super::invalid;
use crate::convert::Exact;
use crate::shape::Shape;
use crate::spheres::{self, Sphere};
use crate::Result;

/// Largest mesh file read, bytes.
pub const MAX_MESH_BYTES: u64 = 64 << 20;

/// One link's geometry.
#[derive(Debug, Clone)]
pub struct LinkGeometry {
    /// URDF name.
    pub name: String,
    /// Collision shapes and their poses in the link frame.
    pub shapes: Vec<(Isometry3<f64>, Shape)>,
    /// Spheres (link frame) whose union holds every shape.
    pub spheres: Vec<Sphere>,
    /// A sphere (link frame) that holds every sphere of the set.
    pub bound: Sphere,
    /// The exact shapes: parry's shape frame in the link frame, and the shape.
    pub(crate) exact: Vec<(Isometry3<f64>, Exact)>,
}

impl LinkGeometry {
    /// The geometry of `shapes` (poses in the link frame).
    pub fn new(name: &str, shapes: Vec<(Isometry3<f64>, Shape)>) -> Result<Self> {
        let mut exact = Vec::with_capacity(shapes.len());
        let mut spheres = Vec::new();
        for (origin, shape) in &shapes {
            shape.validate(&format!("collision shape of {name}"))?;
            let e = shape.to_parry()?;
            exact.push((origin * e.correction, e));
            spheres.extend(spheres::cover(shape, origin));
        }
        let bound = bounding_sphere(&spheres);
        Ok(LinkGeometry {
            name: name.to_string(),
            shapes,
            spheres,
            bound,
            exact,
        })
    }

    /// Whether the link has any collision shape.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }
}

/// A sphere that holds `spheres` (about their centroid; radius 0 at the origin when empty).
pub(crate) fn bounding_sphere(spheres: &[Sphere]) -> Sphere {
    if spheres.is_empty() {
        return Sphere {
            centre: Point3::origin(),
            radius: 0.0,
        };
    }
    let c = spheres
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, s| a + s.centre.coords)
        / spheres.len() as f64;
    let c = Point3::from(c);
    let radius = spheres
        .iter()
        .map(|s| (s.centre - c).norm() + s.radius)
        .fold(0.0, f64::max);
    Sphere { centre: c, radius }
}

/// The vertices of a mesh file (OBJ or STL), scaled, m.
fn mesh_points(path: &Path, scale: [f64; 3]) -> Result<Vec<Point3<f64>>> {
    let what = format!("mesh {}", path.display());
    let bytes = ferrobot_description::read_bytes(path, MAX_MESH_BYTES)
        .map_err(|e| invalid(&what, e.to_string()))?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let raw: Vec<[f64; 3]> = match ext.as_deref() {
        Some("obj") => {
            let (models, _) = tobj::load_obj_buf(
                &mut std::io::Cursor::new(&bytes),
                &tobj::LoadOptions::default(),
                |_| Err(tobj::LoadError::OpenFileFailed),
            )
            .map_err(|e| invalid(&what, e.to_string()))?;
            models
                .iter()
                .flat_map(|m| {
                    m.mesh
                        .positions
                        .chunks_exact(3)
                        .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
                })
                .collect()
        }
        Some("stl") => {
            let mesh = stl_io::read_stl(&mut std::io::Cursor::new(&bytes))
                .map_err(|e| invalid(&what, e.to_string()))?;
            mesh.vertices
                .iter()
                .map(|v| [f64::from(v[0]), f64::from(v[1]), f64::from(v[2])])
                .collect()
        }
        _ => return Err(invalid(&what, "only .obj and .stl meshes are read")),
    };
    Ok(raw
        .into_iter()
        .map(|p| Point3::new(p[0] * scale[0], p[1] * scale[1], p[2] * scale[2]))
        .collect())
}

/// A mesh's file: `package://NAME/rest` and `file://` prefixes dropped, relative to `dir`.
fn mesh_path(filename: &str, dir: Option<&Path>) -> PathBuf {
    let rest = if let Some(r) = filename.strip_prefix("package://") {
        r.split_once('/').map_or(r, |(_, rest)| rest)
    } else {
        filename.strip_prefix("file://").unwrap_or(filename)
    };
    let p = PathBuf::from(rest);
    match dir {
        Some(d) if p.is_relative() => d.join(p),
        _ => p,
    }
}

/// Each link's shapes from a URDF's `<collision>` elements; meshes are read relative to `dir`.
pub fn urdf_geometry(urdf: &urdf_rs::Robot, dir: Option<&Path>) -> Result<Vec<LinkGeometry>> {
    let tree = LinkTree::from_urdf(urdf).map_err(|e| invalid("URDF", e.to_string()))?;
    tree.links()
        .map(|name| {
            let link = urdf.links.iter().find(|l| l.name == name);
            let mut shapes = Vec::new();
            for c in link.map(|l| l.collision.as_slice()).unwrap_or_default() {
                let shape = match &c.geometry {
                    urdf_rs::Geometry::Box { size } => Shape::Box([size[0], size[1], size[2]]),
                    urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
                        radius: *radius,
                        length: *length,
                    },
                    urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
                        radius: *radius,
                        length: *length,
                    },
                    urdf_rs::Geometry::Sphere { radius } => Shape::Sphere(*radius),
                    urdf_rs::Geometry::Mesh { filename, scale } => {
                        let s = scale.map_or([1.0; 3], |s| [s[0], s[1], s[2]]);
                        Shape::Hull(mesh_points(&mesh_path(filename, dir), s)?)
                    }
                };
                shapes.push((pose_from_urdf(&c.origin), shape));
            }
            LinkGeometry::new(name, shapes)
        })
        .collect()
}

/// Each link's shapes from a robot configuration's URDF (meshes read beside the
/// configuration file), in the URDF tree's link order.
pub fn config_geometry(cfg: &RobotConfig) -> Result<Vec<LinkGeometry>> {
    urdf_geometry(&cfg.urdf, config_dir(cfg))
}

/// Where a configuration's meshes are read from: its file's folder (none for a bundled robot).
pub(super) fn config_dir(cfg: &RobotConfig) -> Option<&Path> {
    cfg.file
        .parent()
        .filter(|_| !cfg.file.starts_with("<bundled>"))
}
