//! SLAM's front end on the simulator's frames. Run:
//! `cargo bench -p ferrobot-benches --bench front_end`.
//!
//! * ORB extraction (1000 features, 4 levels) of 640 × 480 frames of the bundled apartment,
//!   rendered as the LoCoBot's camera sees them (criterion).

use std::f64::consts::PI;
use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use ferrobot_sim::render::{PinholeCamera, RenderedImage, Renderer};
use ferrobot_sim::scene::Scene;
use ferrobot_slam::orb::{GreyImage, OrbExtractor, OrbSettings};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

const W: u32 = 640;
const H: u32 = 480;

/// The apartment seen from the body pose `(x, y, yaw)` (m, m, rad) by a camera 0.6 m up,
/// tilted 0.3 rad down.
fn frame(scene: &Scene, renderer: &mut Renderer, at: (f64, f64, f64)) -> GreyImage {
    let body = Isometry3::from_parts(
        Translation3::new(at.0, at.1, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, at.2),
    );
    let look = UnitQuaternion::from_euler_angles(-PI / 2.0 - 0.3, 0.0, -PI / 2.0);
    let cam = PinholeCamera {
        width: W,
        height: H,
        fx: 619.9,
        fy: 620.1,
        cx: 320.65,
        cy: 241.11,
        pose: body * Isometry3::from_parts(Translation3::new(0.1, 0.0, 0.6), look),
    };
    let poses: Vec<Isometry3<f64>> = scene.bodies.iter().map(|b| b.pose).collect();
    let mut image = RenderedImage::new(W, H);
    renderer.render(&cam, &poses, &[], &mut image);
    GreyImage::from_rgb(W as usize, H as usize, &image.rgb).expect("grey")
}

fn orb(c: &mut Criterion) {
    let scene = Scene::bundled("apartment").expect("scene");
    let mut renderer = Renderer::new(&scene, None);
    let frames: Vec<GreyImage> = [(0.0, 0.0, 0.0), (1.0, 0.5, 1.2), (0.5, -0.5, -1.5)]
        .into_iter()
        .map(|at| frame(&scene, &mut renderer, at))
        .collect();
    let extractor = OrbExtractor::new(OrbSettings::default());
    for (i, f) in frames.iter().enumerate() {
        let n = extractor.extract(f).keypoints.len();
        println!("frame {i}: {n} features");
    }
    c.bench_function("orb_extract_640x480", |b| {
        let mut i = 0;
        b.iter(|| {
            i = (i + 1) % frames.len();
            black_box(extractor.extract(black_box(&frames[i])))
        })
    });
}

criterion_group!(benches, orb);
criterion_main!(benches);
