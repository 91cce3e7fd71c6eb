//! `ferrobot snapshot`: one RGB-D frame of a simulated robot in a scene, as files: `rgb.png`,
//! `depth.png` (16-bit millimetres, 0 invalid), `cloud.ply` (the frame's cloud in the world
//! frame) and `snapshot.png` (colour and depth side by side, for people).

use ferrobot::perception::{io, DepthImage, DepthRange, RgbImage};
use ferrobot::Backend;
use nalgebra::Isometry3;
use serde::Serialize;

use super::common::print_json;

/// `snapshot --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct SnapshotJson {
    /// Position of the optical frame (x right, y down, z forward) in the world, m.
    camera_position: [f64; 3],
    /// Orientation of the optical frame in the world, `[x, y, z, w]`.
    camera_quaternion: [f64; 4],
    /// Image height, px.
    height: u32,
    /// K, rows `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`, px.
    intrinsics: [[f64; 3]; 3],
    /// Image width, px.
    width: u32,
}

/// `ferrobot snapshot`'s arguments: what to take a picture of.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Scene name or path.
    #[arg(long, default_value = "tabletop")]
    pub scene: String,
    /// Head pan, rad (positive left).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub pan: f64,
    /// Head tilt, rad (positive down; PyRobot's grasping view is 0.8).
    #[arg(long, default_value_t = 0.8, allow_negative_numbers = true)]
    pub tilt: f64,
    /// Arm joint angles, rad (default: as the robot starts).
    #[arg(long, num_args = 1.., allow_negative_numbers = true)]
    pub joints: Option<Vec<f64>>,
    /// Base start pose X Y THETA in the world (default: the scene's).
    #[arg(long, num_args = 3, allow_negative_numbers = true, value_names = ["X", "Y", "THETA"])]
    pub base: Option<Vec<f64>>,
    /// Exact depth (no stereo noise).
    #[arg(long)]
    pub no_noise: bool,
    /// Depth range of the cloud MIN MAX, m (default: the description's).
    #[arg(long, num_args = 2, value_names = ["MIN", "MAX"])]
    pub depth_range: Option<Vec<f64>>,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: std::path::PathBuf,
    /// Seed of the plants' and the camera's noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// A colour for depth `d` (m) between `near` and `far`: a perceptual rainbow (turbo, Mikhailov
/// 2019, polynomial fit), near red to far blue; black for invalid.
fn depth_colour(d: f32, near: f32, far: f32) -> [u8; 3] {
    if d <= 0.0 {
        return [0; 3];
    }
    let x = (1.0 - ((d - near) / (far - near)).clamp(0.0, 1.0)) as f64;
    let poly = |c: [f64; 6]| {
        let v = c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * (c[4] + x * c[5]))));
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    };
    [
        poly([0.1357, 4.5974, -42.3277, 130.5887, -150.5666, 58.1375]),
        poly([0.0914, 2.1856, 4.8052, -14.0195, 4.2109, 2.7747]),
        poly([0.1067, 12.5925, -60.1097, 109.0745, -88.5066, 26.8183]),
    ]
}

/// Colour (left) and colourised depth (right) side by side.
fn side_by_side(rgb: &RgbImage, depth: &DepthImage) -> ferrobot::Result<RgbImage> {
    let (w, h) = (rgb.width as usize, rgb.height as usize);
    let valid: Vec<f32> = depth.data.iter().copied().filter(|&d| d > 0.0).collect();
    let near = valid.iter().copied().fold(f32::INFINITY, f32::min);
    let far = valid
        .iter()
        .copied()
        .fold(0.0f32, f32::max)
        .max(near + 0.01);
    let mut out = vec![0u8; 2 * w * h * 3];
    for r in 0..h {
        for c in 0..w {
            let src = 3 * (r * w + c);
            let dst = 3 * (r * 2 * w + c);
            out[dst..dst + 3].copy_from_slice(&rgb.data[src..src + 3]);
            let dc = depth_colour(depth.data[r * w + c], near, far);
            out[dst + 3 * w..dst + 3 * w + 3].copy_from_slice(&dc);
        }
    }
    Ok(RgbImage::new(2 * w as u32, h as u32, out)?)
}

/// Take one frame and write the files.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let mut b = super::common::robot_builder(&a.robot)
        .scene(&a.scene)
        .depth_noise(!a.no_noise)
        .backend(Backend::Sim {
            seed: a.seed,
            realtime: false,
        });
    if let Some(p) = a.base.as_ref().map(|b| [b[0], b[1], b[2]]) {
        b = b.start_pose(p);
    }
    let range = a
        .depth_range
        .as_ref()
        .map(|r| [r[0], r[1]])
        .map(|[lo, hi]| DepthRange::new(lo, hi))
        .transpose()?;
    let bot = b.build()?;
    let cam = bot.camera()?;
    if let Some(q) = a.joints.as_deref() {
        bot.arm()?.set_joint_positions(q)?;
    }
    bot.head()?.set_pan_tilt(a.pan, a.tilt)?;
    // Let the head settle inside its tolerance.
    bot.wait(0.5)?;
    let frame = cam.get_frame()?;
    let range = match range {
        Some(r) => r,
        None => cam.depth_range()?,
    };
    let world = optical_in_world(&bot)?;
    let out = a.out.as_path();
    std::fs::create_dir_all(out)?;
    io::write_rgb_png(out.join("rgb.png"), &frame.rgb)?;
    io::write_depth_png(out.join("depth.png"), &frame.depth)?;
    let cloud = frame.cloud(range, true)?.transformed(&world);
    io::write_ply(out.join("cloud.ply"), &cloud)?;
    io::write_rgb_png(
        out.join("snapshot.png"),
        &side_by_side(&frame.rgb, &frame.depth)?,
    )?;
    let t = world.translation.vector;
    let q = world.rotation.coords;
    if a.json {
        print_json(&SnapshotJson {
            camera_position: [t.x, t.y, t.z],
            camera_quaternion: [q.x, q.y, q.z, q.w],
            height: frame.rgb.height,
            intrinsics: frame.intrinsics.rows(),
            width: frame.rgb.width,
        });
    } else {
        say!(
            "{}x{} frame at t = {:.3} s; camera at ({:.3}, {:.3}, {:.3}) m in the world; {:.0} % valid depth; {} cloud points in ({}, {}) m",
            frame.rgb.width,
            frame.rgb.height,
            frame.time.as_secs_f64(),
            t.x,
            t.y,
            t.z,
            100.0 * frame.depth.valid_fraction(),
            cloud.len(),
            range.min,
            range.max
        );
        say!(
            "wrote {0}/rgb.png, {0}/depth.png, {0}/cloud.ply, {0}/snapshot.png",
            out.display()
        );
    }
    Ok(())
}

/// The optical frame's pose in the world: the simulator's ground truth now.
fn optical_in_world(bot: &ferrobot::Robot) -> ferrobot::Result<Isometry3<f64>> {
    let optical = bot.config().camera.as_ref().map(|c| c.frame.clone());
    let sim = bot
        .simulator()
        .ok_or_else(|| ferrobot::Error::Usage("snapshot needs the simulator".into()))?;
    let body = sim
        .body()
        .ok_or_else(|| ferrobot::Error::Usage("the simulated robot has no body".into()))?;
    let i = optical
        .as_deref()
        .and_then(|f| body.tree.link_index(f))
        .ok_or_else(|| ferrobot::Error::Usage("the URDF has no optical frame".into()))?;
    Ok(sim.truth().links[i])
}
