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

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::Deserialize;

use crate::mesh::{self, TriMesh};

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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: String,
    robot: Option<RobotFile>,
    floor: Option<FloorFile>,
    #[serde(default)]
    wall: Vec<WallFile>,
    #[serde(default)]
    object: Vec<ObjectFile>,
    #[serde(default)]
    route: Vec<RouteFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RouteFile {
    name: String,
    waypoints: Vec<Vec<f64>>,
    #[serde(default)]
    head_tilt: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotFile {
    pose: [f64; 3],
    #[serde(default)]
    height: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FloorFile {
    size: [f64; 2],
    #[serde(default = "grey")]
    colour: [f64; 3],
    texture: Option<TextureFile>,
    #[serde(default = "floor_friction")]
    friction: f64,
}

fn grey() -> [f64; 3] {
    [0.6, 0.6, 0.6]
}
fn floor_friction() -> f64 {
    0.8
}
fn wall_height() -> f64 {
    2.4
}
fn wall_thickness() -> f64 {
    0.1
}
fn default_friction() -> f64 {
    0.6
}
fn wall_colour() -> [f64; 3] {
    [0.85, 0.83, 0.78]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WallFile {
    from: [f64; 2],
    to: [f64; 2],
    #[serde(default = "wall_height")]
    height: f64,
    #[serde(default = "wall_thickness")]
    thickness: f64,
    #[serde(default = "wall_colour")]
    colour: [f64; 3],
    texture: Option<TextureFile>,
    #[serde(default)]
    doors: Vec<DoorFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DoorFile {
    at: f64,
    width: f64,
    height: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TextureFile {
    pattern: Option<String>,
    image: Option<String>,
    scale: f64,
    colour: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectFile {
    id: String,
    shape: String,
    size: Option<Vec<f64>>,
    mesh: Option<String>,
    #[serde(default = "unit")]
    scale: f64,
    position: [f64; 3],
    rpy: Option<[f64; 3]>,
    quaternion: Option<[f64; 4]>,
    mass: Option<f64>,
    #[serde(default = "default_friction")]
    friction: f64,
    colour: [f64; 3],
    texture: Option<TextureFile>,
    #[serde(rename = "static", default)]
    fixed: bool,
}

fn unit() -> f64 {
    1.0
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

    fn texture(&self, key: &str, t: &TextureFile, base: [f32; 3]) -> Result<Texture> {
        let scale = self.positive(&format!("{key}.scale"), t.scale)?;
        let second = match t.colour {
            Some(c) => self.colour(&format!("{key}.colour"), c)?,
            None => base.map(|v| v * 0.6),
        };
        match (&t.pattern, &t.image) {
            (Some(p), None) => match p.as_str() {
                "checker" => Ok(Texture::Checker {
                    scale,
                    colour: second,
                }),
                "noise" => Ok(Texture::Noise {
                    scale,
                    colour: second,
                }),
                "tiles" => Ok(Texture::Tiles {
                    scale,
                    colour: second,
                }),
                other => Err(self.err(
                    format!("{key}.pattern"),
                    format!("unknown pattern {other:?} (checker, noise, tiles)"),
                )),
            },
            (None, Some(path)) => {
                if t.colour.is_some() {
                    return Err(self.err(
                        format!("{key}.colour"),
                        "an image texture takes its colours from the image",
                    ));
                }
                let bytes = (self.read)(path, MAX_TEXTURE_BYTES)
                    .map_err(|e| self.err(format!("{key}.image"), e))?;
                let (width, height, pixels) = decode_png(&bytes)
                    .map_err(|e| self.err(format!("{key}.image"), format!("{path}: {e}")))?;
                Ok(Texture::Image {
                    path: path.clone(),
                    scale,
                    width,
                    height,
                    pixels,
                })
            }
            _ => Err(self.err(key, "give exactly one of `pattern` and `image`")),
        }
    }

    fn rotation(&self, key: &str, o: &ObjectFile) -> Result<UnitQuaternion<f64>> {
        match (o.rpy, o.quaternion) {
            (Some(_), Some(_)) => Err(self.err(key, "give `rpy` or `quaternion`, not both")),
            (Some(r), None) => {
                for v in r {
                    self.finite(&format!("{key}.rpy"), v, -100.0, 100.0)?;
                }
                Ok(UnitQuaternion::from_euler_angles(r[0], r[1], r[2]))
            }
            (None, Some(q)) => {
                for v in q {
                    self.finite(&format!("{key}.quaternion"), v, -1.0, 1.0)?;
                }
                let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                if (n - 1.0).abs() > 1e-3 {
                    return Err(self.err(
                        format!("{key}.quaternion"),
                        format!("norm {n} is not 1 (within 0.001)"),
                    ));
                }
                Ok(UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                    q[3], q[0], q[1], q[2],
                )))
            }
            (None, None) => Ok(UnitQuaternion::identity()),
        }
    }

    fn shape(&self, key: &str, o: &ObjectFile) -> Result<Shape> {
        let size = |n: usize, what: &str| -> Result<Vec<f64>> {
            let s = o.size.as_ref().ok_or_else(|| {
                self.err(
                    format!("{key}.size"),
                    format!("a {} needs `size` ({what})", o.shape),
                )
            })?;
            if s.len() != n {
                return Err(self.err(
                    format!("{key}.size"),
                    format!("a {} takes {n} numbers ({what}), not {}", o.shape, s.len()),
                ));
            }
            s.iter()
                .map(|&v| self.positive(&format!("{key}.size"), v))
                .collect()
        };
        if o.shape != "mesh" && o.mesh.is_some() {
            return Err(self.err(
                format!("{key}.mesh"),
                "only a `mesh` shape takes a mesh file",
            ));
        }
        if o.shape != "mesh" && o.scale != 1.0 {
            return Err(self.err(format!("{key}.scale"), "only a `mesh` shape takes a scale"));
        }
        Ok(match o.shape.as_str() {
            "box" => {
                let s = size(3, "full extents x, y, z")?;
                Shape::Box([s[0], s[1], s[2]])
            }
            "cylinder" => {
                let s = size(2, "radius, length")?;
                Shape::Cylinder {
                    radius: s[0],
                    length: s[1],
                }
            }
            "capsule" => {
                let s = size(2, "radius, length")?;
                Shape::Capsule {
                    radius: s[0],
                    length: s[1],
                }
            }
            "sphere" => Shape::Sphere(size(1, "radius")?[0]),
            "mesh" => {
                if o.size.is_some() {
                    return Err(self.err(
                        format!("{key}.size"),
                        "a mesh takes its size from its file (use `scale`)",
                    ));
                }
                let path = o.mesh.as_ref().ok_or_else(|| {
                    self.err(
                        format!("{key}.mesh"),
                        "a mesh needs `mesh` (an OBJ or STL file)",
                    )
                })?;
                let scale = self.positive(&format!("{key}.scale"), o.scale)?;
                let bytes = (self.read)(path, MAX_MESH_BYTES)
                    .map_err(|e| self.err(format!("{key}.mesh"), e))?;
                let mut m = mesh::parse(path, &bytes)
                    .map_err(|e| self.err(format!("{key}.mesh"), format!("{path}: {e}")))?;
                m.scale(scale);
                let (lo, hi) = m.bounds();
                let ext = (hi - lo).amax();
                if !(ext > 1e-4 && ext <= MAX_EXTENT) {
                    return Err(self.err(
                        format!("{key}.mesh"),
                        format!("{path}: extent {ext} m is not in (0.0001, {MAX_EXTENT}]"),
                    ));
                }
                Shape::Mesh {
                    path: path.clone(),
                    mesh: m,
                }
            }
            other => {
                return Err(self.err(
                    format!("{key}.shape"),
                    format!("unknown shape {other:?} (box, cylinder, sphere, capsule, mesh)"),
                ))
            }
        })
    }
}

/// Decode a PNG (8 or 16 bit, grey, grey-alpha, RGB or RGBA) into linear-ish RGB 0-1.
fn decode_png(bytes: &[u8]) -> std::result::Result<(u32, u32, Vec<[f32; 3]>), String> {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = dec.read_info().map_err(|e| format!("not a PNG: {e}"))?;
    let (w, h) = (reader.info().width, reader.info().height);
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > 16 << 20 {
        return Err(format!("{w}x{h} px is not a texture size (at most 16 Mpx)"));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| "image too large".to_string())?;
    let mut buf = vec![0; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("bad PNG data: {e}"))?;
    let ch = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err("indexed PNG not expanded".into()),
    };
    let px = buf[..info.buffer_size()]
        .chunks_exact(ch)
        .map(|p| {
            let g = |i: usize| f32::from(p[i]) / 255.0;
            if ch < 3 {
                [g(0); 3]
            } else {
                [g(0), g(1), g(2)]
            }
        })
        .collect();
    Ok((w, h, px))
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
        let de = toml::Deserializer::parse(text).map_err(|e| cx.err("-", e.message()))?;
        let raw: SceneFile = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            cx.err(
                if key.is_empty() || key == "." {
                    "-".to_string()
                } else {
                    key
                },
                e.inner().message().to_string(),
            )
        })?;
        if raw.name.is_empty() || raw.name.len() > 64 {
            return Err(cx.err("name", "a name of 1-64 characters"));
        }
        let (robot_pose, robot_height) = match &raw.robot {
            Some(r) => {
                cx.finite("robot.pose", r.pose[0], -MAX_EXTENT, MAX_EXTENT)?;
                cx.finite("robot.pose", r.pose[1], -MAX_EXTENT, MAX_EXTENT)?;
                cx.finite("robot.pose", r.pose[2], -100.0, 100.0)?;
                cx.finite("robot.height", r.height, 0.0, 10.0)?;
                (r.pose, r.height)
            }
            None => ([0.0; 3], 0.0),
        };
        let count = raw.object.len() + raw.wall.len() * 8;
        if count > MAX_OBJECTS {
            return Err(cx.err("-", format!("{count} bodies is more than {MAX_OBJECTS}")));
        }
        let mut bodies = Vec::new();
        if let Some(f) = &raw.floor {
            let sx = cx.positive("floor.size", f.size[0])?;
            let sy = cx.positive("floor.size", f.size[1])?;
            let colour = cx.colour("floor.colour", f.colour)?;
            let texture = f
                .texture
                .as_ref()
                .map(|t| cx.texture("floor.texture", t, colour))
                .transpose()?;
            bodies.push(Body {
                id: "floor".into(),
                shape: Shape::Box([sx, sy, FLOOR_THICKNESS]),
                pose: Isometry3::translation(0.0, 0.0, -FLOOR_THICKNESS / 2.0),
                mass: 0.0,
                friction: cx.finite("floor.friction", f.friction, 0.0, 10.0)?,
                colour,
                texture,
                fixed: true,
            });
        }
        for (i, w) in raw.wall.iter().enumerate() {
            bodies.extend(wall_bodies(&cx, i, w)?);
        }
        let mut movable = Vec::new();
        for (i, o) in raw.object.iter().enumerate() {
            let key = format!("object[{i}]");
            if o.id.is_empty() || o.id.len() > 64 {
                return Err(cx.err(format!("{key}.id"), "an id of 1-64 characters"));
            }
            let shape = cx.shape(&key, o)?;
            let rotation = cx.rotation(&key, o)?;
            let mut p = [0.0; 3];
            for (k, v) in p.iter_mut().zip(o.position) {
                *k = cx.finite(&format!("{key}.position"), v, -MAX_EXTENT, MAX_EXTENT)?;
            }
            let mass = match (o.fixed, o.mass) {
                (true, Some(_)) => {
                    return Err(cx.err(format!("{key}.mass"), "a static object has no mass"))
                }
                (true, None) => 0.0,
                (false, Some(m)) => {
                    if !(m.is_finite() && m > 0.0 && m <= 1000.0) {
                        return Err(cx.err(
                            format!("{key}.mass"),
                            format!("{m} is not a mass in (0, 1000] kg"),
                        ));
                    }
                    m
                }
                (false, None) => {
                    return Err(cx.err(format!("{key}.mass"), "a movable object needs a mass"))
                }
            };
            if !o.fixed && shape.volume() <= 0.0 {
                return Err(cx.err(
                    format!("{key}.mesh"),
                    "a movable mesh must be a closed surface (its volume is 0)",
                ));
            }
            let colour = cx.colour(&format!("{key}.colour"), o.colour)?;
            let texture = o
                .texture
                .as_ref()
                .map(|t| cx.texture(&format!("{key}.texture"), t, colour))
                .transpose()?;
            let body = Body {
                id: o.id.clone(),
                shape,
                pose: Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), rotation),
                mass,
                friction: cx.finite(&format!("{key}.friction"), o.friction, 0.0, 10.0)?,
                colour,
                texture,
                fixed: o.fixed,
            };
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
        let mut routes: Vec<Route> = Vec::new();
        for (i, r) in raw.route.iter().enumerate() {
            let key = format!("route[{i}]");
            if r.name.is_empty() || r.name.len() > 64 || routes.iter().any(|o| o.name == r.name) {
                return Err(cx.err(format!("{key}.name"), "a unique name of 1-64 characters"));
            }
            if r.waypoints.is_empty() || r.waypoints.len() > 1000 {
                return Err(cx.err(format!("{key}.waypoints"), "1-1000 waypoints"));
            }
            let mut waypoints = Vec::new();
            for (k, w) in r.waypoints.iter().enumerate() {
                let wk = format!("{key}.waypoints[{k}]");
                if !(2..=4).contains(&w.len()) {
                    return Err(cx.err(wk, "[x, y], [x, y, heading] or [x, y, heading, wait]"));
                }
                let x = cx.finite(&wk, w[0], -MAX_EXTENT, MAX_EXTENT)?;
                let y = cx.finite(&wk, w[1], -MAX_EXTENT, MAX_EXTENT)?;
                let th = w
                    .get(2)
                    .map(|&t| cx.finite(&wk, t, -100.0, 100.0))
                    .transpose()?;
                let wait = w
                    .get(3)
                    .map(|&t| cx.finite(&wk, t, 0.0, 600.0))
                    .transpose()?
                    .unwrap_or(0.0);
                waypoints.push(Waypoint {
                    xy: [x, y],
                    heading: th,
                    wait,
                });
            }
            routes.push(Route {
                name: r.name.clone(),
                waypoints,
                head_tilt: cx.finite(&format!("{key}.head_tilt"), r.head_tilt, -1.6, 1.6)?,
            });
        }
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

/// A wall as boxes: the pieces between its door openings and a lintel above each.
fn wall_bodies(cx: &Ctx<'_>, i: usize, w: &WallFile) -> Result<Vec<Body>> {
    let key = format!("wall[{i}]");
    for v in w.from.iter().chain(&w.to) {
        cx.finite(&format!("{key}.from/to"), *v, -MAX_EXTENT, MAX_EXTENT)?;
    }
    let height = cx.positive(&format!("{key}.height"), w.height)?;
    let thick = cx.positive(&format!("{key}.thickness"), w.thickness)?;
    let colour = cx.colour(&format!("{key}.colour"), w.colour)?;
    let texture = w
        .texture
        .as_ref()
        .map(|t| cx.texture(&format!("{key}.texture"), t, colour))
        .transpose()?;
    let a = Vector3::new(w.from[0], w.from[1], 0.0);
    let d = Vector3::new(w.to[0] - w.from[0], w.to[1] - w.from[1], 0.0);
    let len = d.norm();
    if len < 0.01 {
        return Err(cx.err(format!("{key}.to"), "a wall needs two distinct ends"));
    }
    let dir = d / len;
    let rot = UnitQuaternion::from_euler_angles(0.0, 0.0, dir.y.atan2(dir.x));
    if w.doors.len() > 6 {
        return Err(cx.err(format!("{key}.doors"), "at most 6 doors per wall"));
    }
    // Openings sorted along the wall, each inside it and apart from the others.
    let mut doors: Vec<(f64, f64, f64)> = Vec::new();
    for (k, dr) in w.doors.iter().enumerate() {
        let dk = format!("{key}.doors[{k}]");
        let at = cx.finite(&format!("{dk}.at"), dr.at, 0.0, len)?;
        let width = cx.positive(&format!("{dk}.width"), dr.width)?;
        let dh = cx.positive(&format!("{dk}.height"), dr.height)?;
        if at + width > len + 1e-9 {
            return Err(cx.err(
                format!("{dk}.width"),
                format!(
                    "the opening ends at {} m, beyond the wall's {len} m",
                    at + width
                ),
            ));
        }
        if dh > height {
            return Err(cx.err(
                format!("{dk}.height"),
                format!("{dh} m is higher than the wall ({height} m)"),
            ));
        }
        doors.push((at, at + width, dh));
    }
    doors.sort_by(|x, y| x.0.total_cmp(&y.0));
    for p in doors.windows(2) {
        if p[1].0 < p[0].1 {
            return Err(cx.err(format!("{key}.doors"), "door openings overlap"));
        }
    }
    let mut out = Vec::new();
    let mut piece = |s0: f64, s1: f64, z0: f64, z1: f64| {
        if s1 - s0 < 1e-6 || z1 - z0 < 1e-6 {
            return;
        }
        let centre = a + dir * ((s0 + s1) / 2.0) + Vector3::z() * ((z0 + z1) / 2.0);
        out.push(Body {
            id: format!("wall{i}.{}", out.len()),
            shape: Shape::Box([s1 - s0, thick, z1 - z0]),
            pose: Isometry3::from_parts(Translation3::from(centre), rot),
            mass: 0.0,
            friction: 0.6,
            colour,
            texture: texture.clone(),
            fixed: true,
        });
    };
    let mut s = 0.0;
    for &(d0, d1, dh) in &doors {
        piece(s, d0, 0.0, height);
        piece(d0, d1, dh, height);
        s = d1;
    }
    piece(s, len, 0.0, height);
    Ok(out)
}
