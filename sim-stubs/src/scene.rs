//! Scenes: the world a simulated robot lives in, read from a TOML file.
//!
//! A scene holds static geometry (a floor, walls with door openings, furniture) and movable
//! objects, each a primitive (box, cylinder, sphere, capsule) or a triangle mesh (OBJ or STL
//! beside the scene file), with a pose, mass, friction, colour and optional texture, and the
//! robot's start pose. World frame: z up, metres, radians; quaternions `[x, y, z, w]`.
//!
//! ```toml
//! name = "demo"
//! [robot]
//! pose = [0.0, 0.0, 0.0]          # x, y (m), heading (rad) of base_footprint on the floor
//! [floor]
//! size = [10.0, 10.0]             # m, centred on the origin
//! colour = [0.6, 0.6, 0.6]
//! texture = { pattern = "checker", scale = 0.5, colour = [0.4, 0.4, 0.4] }
//! [[wall]]
//! from = [-2.0, 2.0]
//! to = [2.0, 2.0]
//! height = 2.4                    # default 2.4 m
//! thickness = 0.1                 # default 0.1 m
//! doors = [{ at = 1.0, width = 0.9, height = 2.0 }]  # `at`: start of the opening from `from`, m
//! [[object]]
//! id = "cube"
//! shape = "box"                   # box | cylinder | sphere | capsule | mesh
//! size = [0.03, 0.03, 0.03]       # box: full extents; cylinder, capsule: [radius, length]; sphere: [radius]
//! position = [0.4, 0.0, 0.015]
//! rpy = [0.0, 0.0, 0.3]           # or quaternion = [x, y, z, w]
//! mass = 0.05                     # kg (movable objects)
//! friction = 0.8
//! colour = [0.9, 0.1, 0.1]
//! static = false
//! ```
//!
//! Unknown keys are rejected, and every error names the file, the key and the problem.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Vector3};

use crate::mesh::TriMesh;

mod file;
mod sections;
mod shapes;
mod textures;
mod walls;

/// Names of the bundled scenes.
pub const BUNDLED: [&str; 5] = ["empty", "tabletop", "apartment", "shelf", "clutter"];

/// Largest scene file read, bytes.
pub const MAX_SCENE_BYTES: u64 = 1 << 20;
/// Largest mesh file read, bytes.
pub const MAX_MESH_BYTES: u64 = 32 << 20;
/// Largest texture image read, bytes.
pub const MAX_TEXTURE_BYTES: u64 = 16 << 20;
/// Largest extent of anything in a scene, m: positions and sizes beyond it are absurd.
pub const MAX_EXTENT: f64 = 1000.0;
/// Most objects (static and movable) in one scene.
pub const MAX_OBJECTS: usize = 10_000;

/// The files of a bundled scene: its TOML text, and the other files it names by path.
fn bundled_text(name: &str) -> Option<&'static str> {
    Some(match name {
        "empty" => include_str!("../scenes/empty.toml"),
        "tabletop" => include_str!("../scenes/tabletop.toml"),
        "apartment" => include_str!("../scenes/apartment.toml"),
        "shelf" => include_str!("../scenes/shelf.toml"),
        "clutter" => include_str!("../scenes/clutter.toml"),
        _ => return None,
    })
}

/// A file a bundled scene names (meshes, textures).
fn bundled_asset(path: &str) -> Option<&'static [u8]> {
    Some(match path {
        "meshes/mug.obj" => include_bytes!("../scenes/meshes/mug.obj"),
        "meshes/wedge.stl" => include_bytes!("../scenes/meshes/wedge.stl"),
        _ => return None,
    })
}

/// A scene problem: each names the file and, where it applies, the key.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// No bundled scene of that name and no such file.
    #[error("unknown scene {name:?} (bundled: {known}; or give the path of a scene file)")]
    Unknown {
        /// The name asked for.
        name: String,
        /// The bundled names.
        known: String,
    },
    /// A value in the file is wrong.
    #[error("{}: {key}: {problem}", file.display())]
    Invalid {
        /// The scene file.
        file: PathBuf,
        /// Dotted key (`object[3].size`), `-` for the whole file.
        key: String,
        /// What is wrong.
        problem: String,
    },
    /// A scene body overlaps the robot's body at the start.
    #[error("object {object:?} overlaps the robot's link {link:?} at the start pose")]
    Overlap {
        /// The scene body's id.
        object: String,
        /// The robot link's name (URDF).
        link: String,
    },
}

/// Result of scene loading.
pub type Result<T> = std::result::Result<T, SceneError>;

/// A shape in its own frame (centred on the origin; cylinders and capsules along z).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Full extents along x, y, z, m.
    Box([f64; 3]),
    /// Radius and length along z, m.
    Cylinder {
        /// Radius, m.
        radius: f64,
        /// Length, m.
        length: f64,
    },
    /// Radius, m.
    Sphere(f64),
    /// Radius and length of the cylinder between the two half-spheres, along z, m.
    Capsule {
        /// Radius, m.
        radius: f64,
        /// Length of the straight part, m.
        length: f64,
    },
    /// A triangle mesh in the object's frame, m.
    Mesh {
        /// The file it came from, as the scene names it.
        path: String,
        /// Its triangles.
        mesh: TriMesh,
    },
}

impl Shape {
    /// The scene file's name of the shape.
    pub fn kind(&self) -> &'static str {
        match self {
            Shape::Box(_) => "box",
            Shape::Cylinder { .. } => "cylinder",
            Shape::Sphere(_) => "sphere",
            Shape::Capsule { .. } => "capsule",
            Shape::Mesh { .. } => "mesh",
        }
    }

    /// The size as the scene file and `ferrobot scene` give it (box: full extents;
    /// cylinder and capsule: radius and length; sphere: radius; mesh: extents of its box).
    pub fn size(&self) -> Vec<f64> {
        match self {
            Shape::Box(s) => s.to_vec(),
            Shape::Cylinder { radius, length } | Shape::Capsule { radius, length } => {
                vec![*radius, *length]
            }
            Shape::Sphere(r) => vec![*r],
            Shape::Mesh { mesh, .. } => {
                let (lo, hi) = mesh.bounds();
                (hi - lo).iter().copied().collect()
            }
        }
    }

    /// Half-extents of the shape's bounding box in its own frame, m.
    pub fn half_extents(&self) -> Vector3<f64> {
        match self {
            Shape::Box(s) => Vector3::new(s[0], s[1], s[2]) / 2.0,
            Shape::Cylinder { radius, length } => Vector3::new(*radius, *radius, length / 2.0),
            Shape::Capsule { radius, length } => {
                Vector3::new(*radius, *radius, length / 2.0 + radius)
            }
            Shape::Sphere(r) => Vector3::repeat(*r),
            Shape::Mesh { mesh, .. } => {
                let (lo, hi) = mesh.bounds();
                lo.coords.abs().sup(&hi.coords.abs())
            }
        }
    }

    /// Volume, m³ (a mesh's from its closed surface; 0 for an open one).
    pub fn volume(&self) -> f64 {
        use std::f64::consts::PI;
        match self {
            Shape::Box(s) => s[0] * s[1] * s[2],
            Shape::Cylinder { radius, length } => PI * radius * radius * length,
            Shape::Sphere(r) => 4.0 / 3.0 * PI * r.powi(3),
            Shape::Capsule { radius, length } => {
                PI * radius * radius * length + 4.0 / 3.0 * PI * radius.powi(3)
            }
            Shape::Mesh { mesh, .. } => mesh.volume().abs(),
        }
    }
}

/// A surface texture: a procedural pattern or an image, mapped onto the surface by planar
/// projection along the face's dominant axis, repeating every `scale` metres.
#[derive(Debug, Clone, PartialEq)]
pub enum Texture {
    /// Squares of the body's colour and `colour`.
    Checker {
        /// Side of one square, m.
        scale: f64,
        /// The second colour, 0-1.
        colour: [f32; 3],
    },
    /// Smooth value noise between the body's colour and `colour` (wood, plaster, carpet).
    Noise {
        /// Size of a blob, m.
        scale: f64,
        /// The second colour, 0-1.
        colour: [f32; 3],
    },
    /// Tiles of `scale` metres with grout lines of `colour`.
    Tiles {
        /// Side of a tile, m.
        scale: f64,
        /// Grout colour, 0-1.
        colour: [f32; 3],
    },
    /// An image (PNG), `scale` metres wide on the surface, multiplied by the body's colour.
    Image {
        /// The file it came from, as the scene names it.
        path: String,
        /// Width of one repeat on the surface, m.
        scale: f64,
        /// Width, px.
        width: u32,
        /// Height, px.
        height: u32,
        /// Row-major RGB, 0-1.
        pixels: Vec<[f32; 3]>,
    },
}

/// A body of the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Unique id.
    pub id: String,
    /// Geometry in the body's frame.
    pub shape: Shape,
    /// Pose of the body's frame in the world.
    pub pose: Isometry3<f64>,
    /// Mass, kg (0 for static bodies).
    pub mass: f64,
    /// Coulomb friction coefficient.
    pub friction: f64,
    /// Base colour, linear 0-1.
    pub colour: [f32; 3],
    /// Texture, if any.
    pub texture: Option<Texture>,
    /// Fixed in the world (floor, walls, furniture).
    pub fixed: bool,
}

impl Body {
    /// Axis-aligned bounds of the body in the world, m.
    pub fn world_bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let h = self.shape.half_extents();
        let r = self.pose.rotation.to_rotation_matrix();
        let m = r.matrix().abs() * h;
        let c = Point3::from(self.pose.translation.vector);
        (c - m, c + m)
    }
}

/// A loaded, validated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Name.
    pub name: String,
    /// Where it came from (`<bundled>/NAME.toml` for bundled scenes).
    pub file: PathBuf,
    /// The robot's start pose on the floor: x, y (m), heading (rad).
    pub robot_pose: [f64; 3],
    /// Height of the robot's base frame above the floor (a pedestal), m.
    pub robot_height: f64,
    /// Every body: static geometry first (floor, walls, then static objects), then movable
    /// objects, in file order.
    pub bodies: Vec<Body>,
    /// Scripted drives through the scene (for SLAM runs and recordings), in file order.
    pub routes: Vec<Route>,
}

/// A scripted drive of a mobile base through a scene: waypoints in the world's floor plane,
/// each `[x, y]` (drive there), `[x, y, θ]` (drive there, then turn in place to heading θ) or
/// `[x, y, θ, t]` (and stay there t seconds).
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    /// Name, unique in the scene.
    pub name: String,
    /// Waypoints, in order.
    pub waypoints: Vec<Waypoint>,
    /// Head tilt for the drive, rad (positive down).
    pub head_tilt: f64,
}

/// One waypoint of a [`Route`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Waypoint {
    /// Where, m (world).
    pub xy: [f64; 2],
    /// Heading to turn to on arrival, rad.
    pub heading: Option<f64>,
    /// Time to stay, s.
    pub wait: f64,
}

impl Scene {
    /// A route by name.
    pub fn route(&self, name: &str) -> Option<&Route> {
        self.routes.iter().find(|r| r.name == name)
    }
}

/// Where a scene comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneSource {
    /// A bundled scene by name.
    Bundled(String),
    /// A scene file; meshes and textures are relative to it.
    File(PathBuf),
}

impl SceneSource {
    /// A bundled name, or else a path (anything with a `/` or ending in `.toml`).
    pub fn from_arg(s: &str) -> Self {
        if BUNDLED.contains(&s) || !(s.contains('/') || s.ends_with(".toml")) {
            SceneSource::Bundled(s.to_string())
        } else {
            SceneSource::File(PathBuf::from(s))
        }
    }
}

impl Default for SceneSource {
    fn default() -> Self {
        SceneSource::Bundled("empty".into())
    }
}

/// Reads a file a scene names (relative path), at most `max` bytes.
type Reader<'a> = dyn Fn(&str, u64) -> std::result::Result<Vec<u8>, String> + 'a;

struct Ctx<'a> {
    file: &'a Path,
    read: &'a Reader<'a>,
}

impl Ctx<'_> {
    fn err(&self, key: impl Into<String>, problem: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            file: self.file.to_path_buf(),
            key: key.into(),
            problem: problem.into(),
        }
    }

    fn finite(&self, key: &str, v: f64, lo: f64, hi: f64) -> Result<f64> {
        if v.is_finite() && (lo..=hi).contains(&v) {
            Ok(v)
        } else {
            Err(self.err(key, format!("{v} is not a finite number in [{lo}, {hi}]")))
        }
    }

    fn positive(&self, key: &str, v: f64) -> Result<f64> {
        if v.is_finite() && v > 0.0 && v <= MAX_EXTENT {
            Ok(v)
        } else {
            Err(self.err(
                key,
                format!("{v} is not a positive length of at most {MAX_EXTENT} m"),
            ))
        }
    }

    fn colour(&self, key: &str, c: [f64; 3]) -> Result<[f32; 3]> {
        let mut out = [0.0f32; 3];
        for (o, v) in out.iter_mut().zip(c) {
            *o = self.finite(key, v, 0.0, 1.0)? as f32;
        }
        Ok(out)
    }
}

impl Scene {
    /// Load a scene from `source`.
    pub fn load(source: &SceneSource) -> Result<Scene> {
        match source {
            SceneSource::Bundled(name) => {
                let text = bundled_text(name).ok_or_else(|| SceneError::Unknown {
                    name: name.clone(),
                    known: BUNDLED.join(", "),
                })?;
                let file = PathBuf::from(format!("<bundled>/{name}.toml"));
                Scene::parse(text, &file, &|p, _| {
                    bundled_asset(p)
                        .map(<[u8]>::to_vec)
                        .ok_or_else(|| format!("no bundled file {p:?}"))
                })
            }
            SceneSource::File(path) => {
                let text = ferrobot_description::read_text(path, MAX_SCENE_BYTES).map_err(|e| {
                    if e.kind() == std::io::ErrorKind::NotFound {
                        SceneError::Unknown {
                            name: path.display().to_string(),
                            known: BUNDLED.join(", "),
                        }
                    } else {
                        SceneError::Invalid {
                            file: path.clone(),
                            key: "-".into(),
                            problem: format!("cannot read: {e}"),
                        }
                    }
                })?;
                let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
                Scene::parse(&text, path, &|p, max| {
                    let full = dir.join(p);
                    ferrobot_description::read_bytes(&full, max)
                        .map_err(|e| format!("cannot read {}: {e}", full.display()))
                })
            }
        }
    }

    /// A bundled scene by name.
    pub fn bundled(name: &str) -> Result<Scene> {
        Scene::load(&SceneSource::Bundled(name.to_string()))
    }

    /// Parse scene TOML `text` (named `file` in errors); `read` fetches the meshes and
    /// textures it names, by relative path, at most a given number of bytes.
    pub fn parse(text: &str, file: &Path, read: &Reader<'_>) -> Result<Scene> {
        let cx = Ctx { file, read };
        let raw = cx.deserialize(text)?;
        if raw.name.is_empty() || raw.name.len() > 64 {
            return Err(cx.err("name", "a name of 1-64 characters"));
        }
        let (robot_pose, robot_height) = cx.robot(raw.robot.as_ref())?;
        let count = raw.object.len() + raw.wall.len() * 8;
        if count > MAX_OBJECTS {
            return Err(cx.err("-", format!("{count} bodies is more than {MAX_OBJECTS}")));
        }
        let mut bodies = Vec::new();
        if let Some(f) = &raw.floor {
            bodies.push(cx.floor(f)?);
        }
        for (i, w) in raw.wall.iter().enumerate() {
            bodies.extend(walls::wall_bodies(&cx, i, w)?);
        }
        let mut movable = Vec::new();
        for (i, o) in raw.object.iter().enumerate() {
            let body = cx.object(i, o)?;
            if o.fixed {
                bodies.push(body);
            } else {
                movable.push(body);
            }
        }
        bodies.extend(movable);
        let mut ids = BTreeSet::new();
        for b in &bodies {
            if !ids.insert(b.id.as_str()) {
                return Err(cx.err("object.id", format!("id {:?} is used twice", b.id)));
            }
        }
        let routes = cx.routes(&raw.route)?;
        Ok(Scene {
            name: raw.name,
            file: file.to_path_buf(),
            robot_pose,
            robot_height,
            bodies,
            routes,
        })
    }

    /// The empty world with no floor: nothing to see or touch (the simulator's default
    /// without a scene).
    pub fn empty() -> Scene {
        Scene {
            name: "none".into(),
            file: PathBuf::from("<none>"),
            robot_pose: [0.0; 3],
            robot_height: 0.0,
            bodies: Vec::new(),
            routes: Vec::new(),
        }
    }

    /// A body by id.
    pub fn body(&self, id: &str) -> Option<&Body> {
        self.body_index(id).map(|i| &self.bodies[i])
    }

    /// Where the body `id` stands in [`Scene::bodies`] (and in every per-body list in that
    /// order, such as the ground truth's poses).
    pub fn body_index(&self, id: &str) -> Option<usize> {
        self.bodies.iter().position(|b| b.id == id)
    }
}

/// Thickness of the floor slab (its top is at z = 0), m.
pub const FLOOR_THICKNESS: f64 = 0.05;
