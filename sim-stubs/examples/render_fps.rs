//! Frames per second of the simulated camera (LoCoBot, head tilted 0.8 rad down, arm folded
//! out of the view) in the bundled tabletop and apartment scenes, with and without depth
//! noise, and the last frames in DIR (default /tmp) as PNGs for a look and as raw colour and
//! depth (f32, little-endian) for comparisons. Run:
//! `cargo run --release -p ferrobot-sim --example render_fps [DIR [SCENE]]`.

use std::sync::Arc;

use ferrobot_sim::camera::{SimCamera, StereoNoise};
use ferrobot_sim::render::RenderedImage;
use ferrobot_sim::scene::Scene;

/// This thread's time on a CPU so far, s (Linux: /proc/thread-self/schedstat); wall time
/// elsewhere.
fn cpu_time() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .map_or_else(
            || {
                std::time::UNIX_EPOCH
                    .elapsed()
                    .expect("clock")
                    .as_secs_f64()
            },
            |ns| ns as f64 * 1e-9,
        )
}

fn write_png(path: &str, w: u32, h: u32, colour: png::ColorType, data: &[u8]) {
    let f = std::io::BufWriter::new(std::fs::File::create(path).expect("create"));
    let mut e = png::Encoder::new(f, w, h);
    e.set_color(colour);
    e.set_depth(png::BitDepth::Eight);
    e.write_header()
        .expect("header")
        .write_image_data(data)
        .expect("png");
}

fn main() {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "/tmp".into());
    let only = std::env::args().nth(2);
    for name in ["tabletop", "apartment"] {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let cfg = ferrobot_description::RobotConfig::bundled("locobot").expect("locobot");
        let desc = ferrobot_sim::robots::from_description(&cfg);
        let scene = Arc::new(Scene::bundled(name).expect("scene"));
        let sim = ferrobot_sim::LockstepSim::with_scene(
            desc.clone(),
            cfg.firmware_profile(),
            1,
            scene.clone(),
        )
        .expect("the robot fits the scene");
        let mut truth = sim.truth();
        let body = desc.body.as_ref().expect("body");
        let ti = body.tree.joint_index("head_tilt_joint").expect("tilt");
        truth.joints[ti] = 0.8;
        // The arm folded up and back, out of the view.
        for (j, q) in [("joint_2", -1.5), ("joint_3", 1.5), ("joint_4", 0.6)] {
            let i = body.tree.joint_index(j).expect("arm joint");
            truth.joints[i] = q;
        }
        truth.links = body.link_poses(&truth.root, &truth.joints);
        let mut cam =
            SimCamera::new(&scene, body, cfg.camera.as_ref().expect("camera"), 1).expect("cam");
        let mut img = RenderedImage::new(640, 480);
        for noise in [None, Some(StereoNoise::D435)] {
            cam.noise = noise;
            let n = 1000;
            let (t, c) = (std::time::Instant::now(), cpu_time());
            for _ in 0..n {
                cam.capture_into(&truth, &mut img);
            }
            let dt = t.elapsed().as_secs_f64() / f64::from(n);
            let dc = (cpu_time() - c) / f64::from(n);
            let tag = if noise.is_some() { "noise" } else { "exact" };
            let valid = img.depth.iter().filter(|&&d| d > 0.0).count();
            let centre = img.depth[240 * 640 + 320];
            let hash = img
                .rgb
                .iter()
                .chain(
                    img.depth
                        .iter()
                        .flat_map(|d| d.to_le_bytes())
                        .collect::<Vec<_>>()
                        .iter(),
                )
                .fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
                    (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
                });
            println!(
                "{name} {tag}: {} tris, {:.2} ms/frame ({:.0} fps), cpu {:.2} ms/frame, valid {valid}, centre {centre:.4} m, hash {hash:016x}",
                cam.renderer().triangles(),
                dt * 1e3,
                1.0 / dt,
                dc * 1e3
            );
            let (w, h) = (img.width, img.height);
            let raw: Vec<u8> = img.depth.iter().flat_map(|d| d.to_le_bytes()).collect();
            std::fs::write(format!("{dir}/{name}_{tag}_depth.f32"), raw).expect("write");
            std::fs::write(format!("{dir}/{name}_{tag}_rgb.raw"), &img.rgb).expect("write");
            write_png(
                &format!("{dir}/{name}_{tag}_rgb.png"),
                w,
                h,
                png::ColorType::Rgb,
                &img.rgb,
            );
            let grey: Vec<u8> = img
                .depth
                .iter()
                .map(|&d| {
                    if d > 0.0 {
                        (255.0 - d * 60.0).clamp(0.0, 255.0) as u8
                    } else {
                        0
                    }
                })
                .collect();
            write_png(
                &format!("{dir}/{name}_{tag}_depth.png"),
                w,
                h,
                png::ColorType::Grayscale,
                &grey,
            );
            let lab: Vec<u8> = img
                .labels
                .iter()
                .flat_map(|&l| {
                    let x = l.wrapping_mul(2_654_435_761);
                    [(x >> 24) as u8, (x >> 16) as u8, (x >> 8) as u8]
                })
                .collect();
            write_png(
                &format!("{dir}/{name}_{tag}_labels.png"),
                w,
                h,
                png::ColorType::Rgb,
                &lab,
            );
        }
    }
}
