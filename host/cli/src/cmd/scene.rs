//! `ferrobot scene`: what a scene holds, in the world frame (z up, metres).

use std::path::Path;

use ferrobot::nav::MapImage;
use ferrobot::scene::{Scene, SceneSource, Shape};
use ferrobot_sim::floor_plan::OBSTACLE_BAND;
use serde::Serialize;

use super::common::{print_json, round};

/// `scene --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct SceneJson {
    /// Every body: floor, walls, furniture and objects.
    objects: Vec<ObjectJson>,
    /// The robot's start pose `[x, y, θ]` (m, m, rad).
    robot_pose: [f64; 3],
    /// The scene's name.
    scene: String,
}

/// One body of `scene --json`.
#[derive(Serialize)]
struct ObjectJson {
    /// Colour `[r, g, b]`, 0-1.
    colour: [f32; 3],
    /// Its id.
    id: String,
    /// The mesh file as the scene names it (meshes only).
    mesh: Option<String>,
    /// Position of its frame's origin `[x, y, z]`, m.
    position: [f64; 3],
    /// Orientation `[x, y, z, w]`.
    quaternion: [f64; 4],
    /// `box`, `cylinder`, `sphere`, `capsule` or `mesh`.
    shape: &'static str,
    /// Box: full extents x y z; cylinder and capsule: radius and length along z; sphere:
    /// radius; mesh: the full extents of its bounding box in its own frame (m).
    size: Vec<f64>,
    /// Fixed in the world.
    #[serde(rename = "static")]
    fixed: bool,
}

fn object(b: &ferrobot::scene::Body) -> ObjectJson {
    let (size, mesh) = match &b.shape {
        Shape::Box(s) => (s.to_vec(), None),
        Shape::Cylinder { radius, length } | Shape::Capsule { radius, length } => {
            (vec![*radius, *length], None)
        }
        Shape::Sphere(r) => (vec![*r], None),
        Shape::Mesh { path, .. } => (
            b.shape.half_extents().iter().map(|h| 2.0 * h).collect(),
            Some(path.clone()),
        ),
    };
    let t = b.pose.translation.vector;
    let q = b.pose.rotation.coords;
    ObjectJson {
        colour: b.colour,
        id: b.id.clone(),
        mesh,
        position: [t.x, t.y, t.z],
        quaternion: [q.x, q.y, q.z, q.w],
        shape: b.shape.kind(),
        size,
        fixed: b.fixed,
    }
}

/// `ferrobot scene`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// `empty`, `tabletop`, `apartment`, `shelf`, `clutter`, or a scene file's path.
    pub name: String,
    /// Also write the scene's ground-truth floor plan here (map_server's YAML, and a PNG
    /// of the same name beside it): obstacles 0.1–0.8 m above the floor, as PyRobot maps.
    #[arg(long)]
    pub map: Option<std::path::PathBuf>,
    /// Cell size of the floor plan, m (PyRobot's 0.02).
    #[arg(long, default_value_t = 0.02)]
    pub resolution: f64,
    /// Write over an existing map file (and its PNG).
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Print the scene (a bundled name or a scene file's path); with `--map`, also write its
/// ground-truth floor plan there in map_server's format (cells of `--resolution` m, obstacles
/// from [`OBSTACLE_BAND`]), refusing to write over existing files unless `--force`.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let scene = Scene::load(&SceneSource::from_arg(&a.name))?;
    if let Some(yaml) = a.map.as_deref() {
        write_floor_plan(&scene, yaml, a)?;
    }
    if a.json {
        print_json(&SceneJson {
            objects: scene.bodies.iter().map(object).collect(),
            robot_pose: scene.robot_pose,
            scene: scene.name.clone(),
        });
        return Ok(());
    }
    print_text(&scene);
    Ok(())
}

/// Write the floor plan of `scene` to `yaml` and the PNG beside it (said in text mode).
fn write_floor_plan(scene: &Scene, yaml: &Path, a: &Args) -> ferrobot::Result<()> {
    let png = yaml.with_extension("png");
    if !matches!(
        yaml.extension().and_then(|e| e.to_str()),
        Some("yaml" | "yml")
    ) {
        return Err(ferrobot::Error::Usage(format!(
            "--map {}: name the map's YAML file (.yaml or .yml); its PNG goes beside it",
            yaml.display()
        )));
    }
    for path in [yaml, png.as_path()] {
        if !a.force && path.exists() {
            return Err(ferrobot::Error::PathExists {
                path: path.to_path_buf(),
            });
        }
    }
    let plan = scene.floor_plan(a.resolution, OBSTACLE_BAND, false)?;
    let image = MapImage::from_occupied(
        plan.origin,
        plan.resolution,
        plan.width,
        plan.height,
        &plan.occupied,
    );
    let png = image.save(yaml)?;
    if !a.json {
        say!(
            "floor plan ({} × {} cells of {} m, obstacles {}–{} m above the floor): {} and {}",
            plan.width,
            plan.height,
            plan.resolution,
            OBSTACLE_BAND[0],
            OBSTACLE_BAND[1],
            yaml.display(),
            png.display()
        );
    }
    Ok(())
}

/// The scene as text: a line about it, then a table of its bodies.
fn print_text(scene: &Scene) {
    say!(
        "scene {} ({}): robot at {:?} (x m, y m, θ rad), {} bodies",
        scene.name,
        scene.file.display(),
        round(&scene.robot_pose),
        scene.bodies.len()
    );
    say!(
        "{:<18} {:<9} {:<7} {:<26} {}",
        "id",
        "shape",
        "static",
        "position (m)",
        "size (m)"
    );
    for b in &scene.bodies {
        let o = object(b);
        say!(
            "{:<18} {:<9} {:<7} {:<26} {:?}",
            o.id,
            o.shape,
            o.fixed,
            format!("{:?}", round(&o.position)),
            round(&o.size)
        );
    }
}
