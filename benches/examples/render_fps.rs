//! Frames per second of the simulated camera in the render bench's views (the LoCoBot in the
//! bundled tabletop and apartment scenes, arm folded out of the view), with and without depth
//! noise, and the last frames in DIR (default /tmp) as PNGs for a look and as raw colour and
//! depth (f32, little-endian) for comparisons. Quicker than the bench, for profiling. Run:
//! `cargo run --release -p ferrobot-benches --example render_fps [DIR [SCENE]]`.

use std::path::Path;

use ferrobot_benches::render::{cpu_time, depth_png, views, write_png};
use ferrobot_sim::render::RenderedImage;
use ferrobot_sim::rng::SimRng;

fn main() {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "/tmp".into());
    let dir = Path::new(&dir);
    let only = std::env::args().nth(2);
    for v in views() {
        if only.as_deref().is_some_and(|o| o != v.name) {
            continue;
        }
        let (w, h) = (v.camera.width, v.camera.height);
        let mut img = RenderedImage::new(w, h);
        let mut rng = SimRng::new(1, 1);
        for noise in [false, true] {
            let n = 1000;
            let (t, c) = (std::time::Instant::now(), cpu_time());
            for _ in 0..n {
                v.render(&mut img, noise.then_some(&mut rng));
            }
            let dt = t.elapsed().as_secs_f64() / f64::from(n);
            let dc = (cpu_time() - c) / f64::from(n);
            let tag = if noise { "noise" } else { "exact" };
            let valid = img.depth.iter().filter(|&&d| d > 0.0).count();
            let centre = img.depth[(h / 2 * w + w / 2) as usize];
            let hash = img
                .rgb
                .iter()
                .copied()
                .chain(img.depth.iter().flat_map(|d| d.to_le_bytes()))
                .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
                    (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
                });
            println!(
                "{} {tag}: {} tris, {:.2} ms/frame ({:.0} fps), cpu {:.2} ms/frame, valid {valid}, centre {centre:.4} m, hash {hash:016x}",
                v.name,
                v.renderer.triangles(),
                dt * 1e3,
                1.0 / dt,
                dc * 1e3
            );
            let name = |what: &str| dir.join(format!("{}_{tag}_{what}", v.name));
            let raw: Vec<u8> = img.depth.iter().flat_map(|d| d.to_le_bytes()).collect();
            std::fs::write(name("depth.f32"), raw).expect("write");
            std::fs::write(name("rgb.raw"), &img.rgb).expect("write");
            write_png(&name("rgb.png"), w, h, png::ColorType::Rgb, &img.rgb);
            depth_png(&name("depth.png"), w, h, &img.depth);
            let labels: Vec<u8> = img
                .labels
                .iter()
                .flat_map(|&l| {
                    let x = l.wrapping_mul(2_654_435_761);
                    [(x >> 24) as u8, (x >> 16) as u8, (x >> 8) as u8]
                })
                .collect();
            write_png(&name("labels.png"), w, h, png::ColorType::Rgb, &labels);
        }
    }
}
