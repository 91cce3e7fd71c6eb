//! `ferrobot snapshot`: one RGB-D frame of a simulated robot in a scene, as files: `rgb.png`,
//! `depth.png` (16-bit millimetres, 0 invalid), `cloud.ply` (the frame's cloud in the world
//! frame) and `snapshot.png` (colour and depth side by side, for people).

use std::path::Path;

use ferrobot::perception::{io, DepthImage, DepthRange, RgbImage};
use ferrobot::Backend;
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

/// What to take a picture of.
pub struct SnapshotArgs<'a> {
    /// Robot name or configuration path.
    pub robot: &'a str,
    /// Scene name or path.
    pub scene: &'a str,
    /// Head pan and tilt, rad.
    pub pan: f64,
    /// Head tilt, rad (positive down).
    pub tilt: f64,
    /// Arm joint angles, rad.
    pub joints: Option<&'a [f64]>,
    /// Base start pose `[x, y, θ]` in the world.
    pub base: Option<[f64; 3]>,
    /// Exact depth.
    pub no_noise: bool,
    /// Depth range of the cloud, m (default: the description's).
    pub depth_range: Option<[f64; 2]>,
    /// Where the files go (created if missing).
    pub out: &'a Path,
    /// Seed of the plants' and the camera's noise.
    pub seed: u64,
    /// Print JSON.
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
pub fn run(a: &SnapshotArgs) -> ferrobot::Result<()> {
    let mut b = super::common::robot_builder(a.robot)
        .scene(a.scene)
        .depth_noise(!a.no_noise)
        .backend(Backend::Sim {
            seed: a.seed,
            realtime: false,
        });
    if let Some(p) = a.base {
        b = b.start_pose(p);
    }
    let range = a
        .depth_range
        .map(|[lo, hi]| DepthRange::new(lo, hi))
        .transpose()?;
    let bot = b.build()?;
    let cam = bot.camera()?;
    if let Some(q) = a.joints {
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
    // The optical frame's pose in the world: the simulator's ground truth at the frame.
    let optical = bot.config().camera.as_ref().map(|c| c.frame.clone());
    let world = {
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
        sim.truth().links[i]
    };
    std::fs::create_dir_all(a.out)?;
    io::write_rgb_png(a.out.join("rgb.png"), &frame.rgb)?;
    io::write_depth_png(a.out.join("depth.png"), &frame.depth)?;
    let cloud = frame.cloud(range, true)?.transformed(&world);
    io::write_ply(a.out.join("cloud.ply"), &cloud)?;
    io::write_rgb_png(
        a.out.join("snapshot.png"),
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
            a.out.display()
        );
    }
    Ok(())
}
