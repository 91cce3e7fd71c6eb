//! The scene file's format as read (before checks): every table and key, unknown keys
//! rejected, defaults filled in. The format is shown in [`super`]'s documentation.

use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneFile {
    pub(super) name: String,
    pub(super) robot: Option<RobotFile>,
    pub(super) floor: Option<FloorFile>,
    #[serde(default)]
    pub(super) wall: Vec<WallFile>,
    #[serde(default)]
    pub(super) object: Vec<ObjectFile>,
    #[serde(default)]
    pub(super) route: Vec<RouteFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RouteFile {
    pub(super) name: String,
    pub(super) waypoints: Vec<Vec<f64>>,
    #[serde(default)]
    pub(super) head_tilt: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RobotFile {
    pub(super) pose: [f64; 3],
    #[serde(default)]
    pub(super) height: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FloorFile {
    pub(super) size: [f64; 2],
    #[serde(default = "grey")]
    pub(super) colour: [f64; 3],
    pub(super) texture: Option<TextureFile>,
    #[serde(default = "floor_friction")]
    pub(super) friction: f64,
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
pub(super) struct WallFile {
    pub(super) from: [f64; 2],
    pub(super) to: [f64; 2],
    #[serde(default = "wall_height")]
    pub(super) height: f64,
    #[serde(default = "wall_thickness")]
    pub(super) thickness: f64,
    #[serde(default = "wall_colour")]
    pub(super) colour: [f64; 3],
    pub(super) texture: Option<TextureFile>,
    #[serde(default)]
    pub(super) doors: Vec<DoorFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct DoorFile {
    pub(super) at: f64,
    pub(super) width: f64,
    pub(super) height: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct TextureFile {
    pub(super) pattern: Option<String>,
    pub(super) image: Option<String>,
    pub(super) scale: f64,
    pub(super) colour: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ObjectFile {
    pub(super) id: String,
    pub(super) shape: String,
    pub(super) size: Option<Vec<f64>>,
    pub(super) mesh: Option<String>,
    #[serde(default = "unit")]
    pub(super) scale: f64,
    pub(super) position: [f64; 3],
    pub(super) rpy: Option<[f64; 3]>,
    pub(super) quaternion: Option<[f64; 4]>,
    pub(super) mass: Option<f64>,
    #[serde(default = "default_friction")]
    pub(super) friction: f64,
    pub(super) colour: [f64; 3],
    pub(super) texture: Option<TextureFile>,
    #[serde(rename = "static", default)]
    pub(super) fixed: bool,
}

fn unit() -> f64 {
    1.0
}
