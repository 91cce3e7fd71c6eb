//! The renderer's geometry is exact without noise, and the depth noise follows its model.

use std::path::Path;

use ferrobot_sim::camera::{normal_table, StereoNoise};
use ferrobot_sim::render::{PinholeCamera, RenderedImage, Renderer};
use ferrobot_sim::rng::SimRng;
use ferrobot_sim::scene::Scene;
use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

fn scene(text: &str) -> Scene {
    Scene::parse(text, Path::new("test.toml"), &|p, _| Err(format!("no {p}"))).unwrap()
}

/// The D435's intrinsics at 640 x 480.
fn camera(pose: Isometry3<f64>) -> PinholeCamera {
    PinholeCamera {
        width: 640,
        height: 480,
        fx: 619.8997,
        fy: 620.11,
        cx: 320.654,
        cy: 241.1125,
        pose,
    }
}

/// An optical frame at `eye` looking along world +x (x right = -y, y down = -z).
fn looking_along_x(eye: [f64; 3]) -> Isometry3<f64> {
    let r = Rotation3::from_basis_unchecked(&[-Vector3::y(), -Vector3::z(), Vector3::x()]);
    Isometry3::from_parts(
        Translation3::new(eye[0], eye[1], eye[2]),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// An optical frame at `eye` looking in a random direction, turned at random about it.
fn looking_anywhere(eye: [f64; 3], rng: &mut SimRng) -> Isometry3<f64> {
    let rot = UnitQuaternion::from_euler_angles(
        (rng.uniform() - 0.5) * 6.0,
        (rng.uniform() - 0.5) * 3.0,
        (rng.uniform() - 0.5) * 6.0,
    );
    Isometry3::from_parts(Translation3::new(eye[0], eye[1], eye[2]), rot)
}

fn wall_scene(distance: f64) -> Scene {
    scene(&format!(
        "name = \"wall\"\n[[object]]\nid = \"wall\"\nshape = \"box\"\nsize = [0.2, 20.0, 20.0]\n\
         position = [{}, 0.0, 0.0]\ncolour = [0.5, 0.5, 0.5]\nstatic = true\n\
         texture = {{ pattern = \"noise\", scale = 0.05, colour = [0.2, 0.3, 0.4] }}\n",
        distance + 0.1
    ))
}

fn render(s: &Scene, cam: &PinholeCamera) -> (Renderer, RenderedImage) {
    let r = Renderer::new(s, None);
    let poses: Vec<_> = s.bodies.iter().map(|b| b.pose).collect();
    let mut img = RenderedImage::new(cam.width, cam.height);
    r.render(cam, &poses, &[], &mut img);
    (r, img)
}

#[test]
fn a_wall_at_one_metre_reads_one_metre_in_every_pixel() {
    let s = wall_scene(1.0);
    let cam = camera(looking_along_x([0.0, 0.0, 0.0]));
    let (_, img) = render(&s, &cam);
    let mut worst = 0.0f64;
    for &d in &img.depth {
        assert!(d > 0.0, "the wall fills the image");
        worst = worst.max((f64::from(d) - 1.0).abs());
    }
    assert!(worst <= 0.0005, "worst error {worst} m (tolerance 0.5 mm)");
    // The texture gives the image contrast (features).
    let (lo, hi) = img
        .rgb
        .iter()
        .fold((255u8, 0u8), |(l, h), &v| (l.min(v), h.max(v)));
    assert!(hi - lo > 40, "contrast {lo}..{hi}");
}

#[test]
fn a_boxs_corners_project_where_the_intrinsics_say() {
    // A 0.3 m cube 1.5 m ahead, turned and lifted so that its silhouette is a hexagon.
    let s = scene(
        "name = \"box\"\n[[object]]\nid = \"cube\"\nshape = \"box\"\nsize = [0.3, 0.3, 0.3]\n\
         position = [1.5, 0.1, -0.05]\nrpy = [0.3, 0.2, 0.6]\ncolour = [0.9, 0.2, 0.2]\nstatic = true\n",
    );
    let cam = camera(looking_along_x([0.0, 0.0, 0.0]));
    let (r, img) = render(&s, &cam);
    let cube = s.body("cube").unwrap();
    let label = (1..10).find(|&l| r.label_name(l) == Some("cube")).unwrap();
    // Projected corners.
    let mut corners = Vec::new();
    for sx in [-0.15, 0.15] {
        for sy in [-0.15, 0.15] {
            for sz in [-0.15, 0.15] {
                let p = cube.pose * Point3::new(sx, sy, sz);
                corners.push(cam.project(&p).unwrap());
            }
        }
    }
    let (umin, umax) = corners
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), c| (a.min(c.0), b.max(c.0)));
    let (vmin, vmax) = corners
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), c| (a.min(c.1), b.max(c.1)));
    // The rendered silhouette's extremes.
    let (w, _) = (img.width as usize, img.height as usize);
    let px: Vec<(f64, f64)> = img
        .labels
        .iter()
        .enumerate()
        .filter(|(_, &l)| l == label)
        .map(|(i, _)| ((i % w) as f64, (i / w) as f64))
        .collect();
    assert!(px.len() > 1000, "{} pixels", px.len());
    let (cmin, cmax) = px
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), c| (a.min(c.0), b.max(c.0)));
    let (rmin, rmax) = px
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), c| (a.min(c.1), b.max(c.1)));
    // Pixel centres sample the silhouette: none lies outside the projected corners' box, and
    // the extremes are within a pixel and a half of it (a vertex between two rows).
    for (lo, hi, want_lo, want_hi) in [(cmin, cmax, umin, umax), (rmin, rmax, vmin, vmax)] {
        assert!(
            lo >= want_lo - 1e-9 && hi <= want_hi + 1e-9,
            "[{lo}, {hi}] in [{want_lo}, {want_hi}]"
        );
        assert!(
            lo - want_lo < 1.5 && want_hi - hi < 1.5,
            "[{lo}, {hi}] vs [{want_lo}, {want_hi}]"
        );
    }
    // The pixel of each corner on the silhouette's outline has a cube pixel within 1 px.
    for c in &corners {
        let (u, v) = (c.0.round(), c.1.round());
        let near = px
            .iter()
            .any(|p| (p.0 - u).abs() <= 1.0 && (p.1 - v).abs() <= 1.0);
        let inside_outline =
            c.0 > umin + 1.0 && c.0 < umax - 1.0 && c.1 > vmin + 1.0 && c.1 < vmax - 1.0;
        assert!(
            near || inside_outline,
            "corner at {c:?} has no cube pixel within 1 px"
        );
    }
}

#[test]
fn depth_noise_follows_the_stereo_model_at_one_and_two_metres() {
    let noise = StereoNoise::D435;
    for distance in [1.0, 2.0] {
        let s = wall_scene(distance);
        let cam = camera(looking_along_x([0.0, 0.0, 0.0]));
        let (_, mut img) = render(&s, &cam);
        let mut rng = SimRng::new(7, 1);
        noise.apply(&mut img.depth, 640, cam.fx, &mut rng);
        let valid: Vec<f64> = img
            .depth
            .iter()
            .filter(|&&d| d > 0.0)
            .map(|&d| f64::from(d) - distance)
            .collect();
        // The left band the right imager cannot see: f B / z px.
        let band = (cam.fx * noise.baseline / distance).floor() as usize;
        let invalid_cols = (0..640)
            .filter(|&c| img.depth[240 * 640 + c] == 0.0)
            .count();
        assert!(
            invalid_cols.abs_diff(band) <= 1,
            "band {invalid_cols} px, model {band} px"
        );
        let n = valid.len() as f64;
        let mean = valid.iter().sum::<f64>() / n;
        let std = (valid.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
        // Model: sigma_z = z^2 sigma_d / (f B), plus the 1 mm quantisation (q^2 / 12).
        let model = (noise.sigma(distance, cam.fx).powi(2) + noise.quantum.powi(2) / 12.0).sqrt();
        assert!(
            (std / model - 1.0).abs() < 0.2,
            "at {distance} m: spread {std} m, model {model} m"
        );
        assert!(mean.abs() < 0.2 * model, "bias {mean} m");
    }
}

#[test]
fn nearer_objects_cast_a_stereo_shadow_to_their_left_and_lose_their_edges() {
    // A post 1 m ahead in front of a wall at 2 m.
    let s = scene(
        "name = \"post\"\n[[object]]\nid = \"wall\"\nshape = \"box\"\nsize = [0.2, 20.0, 20.0]\n\
         position = [2.1, 0.0, 0.0]\ncolour = [0.5, 0.5, 0.5]\nstatic = true\n\
         [[object]]\nid = \"post\"\nshape = \"box\"\nsize = [0.1, 0.1, 3.0]\nposition = [1.05, 0.0, 0.0]\n\
         colour = [0.2, 0.6, 0.2]\nstatic = true\n",
    );
    let cam = camera(looking_along_x([0.0, 0.0, 0.0]));
    let (_, clean) = render(&s, &cam);
    let mut noisy = clean.clone();
    StereoNoise::D435.apply(&mut noisy.depth, 640, cam.fx, &mut SimRng::new(1, 1));
    let row = 240 * 640;
    // The post spans columns where the clean depth is 1 m.
    let post: Vec<usize> = (0..640)
        .filter(|&c| (clean.depth[row + c] - 1.0).abs() < 0.01)
        .collect();
    let left = *post.first().unwrap();
    // Shadow width: f B (1/z_near - 1/z_far) = 620 * 0.05 * (1 - 0.5) = 15.5 px.
    let shadow = (0..left)
        .rev()
        .take_while(|&c| noisy.depth[row + c] == 0.0)
        .count();
    assert!(
        (14..=18).contains(&shadow),
        "shadow {shadow} px (model 15.5 plus the edge)"
    );
    // No shadow on its right side beyond the edge pixel.
    let right = *post.last().unwrap();
    assert!(noisy.depth[row + right + 2] > 0.0);
}

#[test]
fn the_depth_noise_is_the_same_for_the_same_seed() {
    let s = wall_scene(1.5);
    let cam = camera(looking_along_x([0.0, 0.0, 0.0]));
    let (_, clean) = render(&s, &cam);
    let noisy = |seed: u64| {
        let mut d = clean.depth.clone();
        StereoNoise::D435.apply(&mut d, 640, cam.fx, &mut SimRng::new(seed, 1));
        d
    };
    assert_eq!(noisy(5), noisy(5));
    assert_ne!(noisy(5), noisy(6));
    // Successive frames from one generator differ.
    let mut rng = SimRng::new(5, 1);
    let (mut a, mut b) = (clean.depth.clone(), clean.depth.clone());
    StereoNoise::D435.apply(&mut a, 640, cam.fx, &mut rng);
    StereoNoise::D435.apply(&mut b, 640, cam.fx, &mut rng);
    assert_ne!(a, b);
}

#[test]
fn a_surface_filling_the_view_has_no_holes_from_any_angle() {
    // Inside a closed room of six slabs every pixel sees a wall, floor or ceiling: no pixel
    // may stay empty along the edges shared by two triangles, whatever the view.
    let mut text = String::from("name = \"room\"\n");
    for (i, (size, pos)) in [
        ([0.2, 6.2, 6.2], [-3.1, 0.0, 0.0]),
        ([0.2, 6.2, 6.2], [3.1, 0.0, 0.0]),
        ([6.2, 0.2, 6.2], [0.0, -3.1, 0.0]),
        ([6.2, 0.2, 6.2], [0.0, 3.1, 0.0]),
        ([6.2, 6.2, 0.2], [0.0, 0.0, -3.1]),
        ([6.2, 6.2, 0.2], [0.0, 0.0, 3.1]),
    ]
    .iter()
    .enumerate()
    {
        text += &format!(
            "[[object]]\nid = \"slab{i}\"\nshape = \"box\"\nsize = {size:?}\nposition = {pos:?}\n\
             colour = [0.5, 0.5, 0.5]\nstatic = true\n\
             texture = {{ pattern = \"checker\", scale = 0.3, colour = [0.2, 0.3, 0.4] }}\n"
        );
    }
    let s = scene(&text);
    let r = Renderer::new(&s, None);
    let poses: Vec<_> = s.bodies.iter().map(|b| b.pose).collect();
    let mut img = RenderedImage::new(640, 480);
    let mut rng = SimRng::new(11, 2);
    for _ in 0..200 {
        let eye = [0, 1, 2].map(|_| (rng.uniform() - 0.5) * 4.0);
        let pose = looking_anywhere(eye, &mut rng);
        r.render(&camera(pose), &poses, &[], &mut img);
        let holes = img.depth.iter().filter(|&&d| d <= 0.0).count();
        let first = img
            .depth
            .iter()
            .position(|&d| d <= 0.0)
            .map(|i| (i % 640, i / 640));
        assert_eq!(
            holes, 0,
            "{holes} empty pixels (the first at column, row {first:?}) seen from {pose:?}"
        );
        // The farthest corner is at most 5 sqrt(3) m away.
        assert!(img.depth.iter().all(|d| d.is_finite() && *d < 8.7));
    }
}

#[test]
fn any_camera_pose_renders_without_panic() {
    // The bundled scenes from far away, from inside objects, grazing the floor, through the
    // near plane, and from absurd poses: depth stays finite and non-negative.
    let mut rng = SimRng::new(3, 4);
    for name in ["tabletop", "apartment"] {
        let s = Scene::bundled(name).unwrap();
        let r = Renderer::new(&s, None);
        let poses: Vec<_> = s.bodies.iter().map(|b| b.pose).collect();
        let mut img = RenderedImage::new(640, 480);
        let mut eyes: Vec<[f64; 3]> = vec![
            [0.0, 0.0, 0.001],
            [0.505, 0.0, 0.05],
            [1e3, -1e3, 1e3],
            [f64::NAN, 0.0, 0.0],
        ];
        eyes.extend((0..30).map(|_| [0, 1, 2].map(|_| (rng.uniform() - 0.5) * 8.0)));
        for eye in eyes {
            let pose = looking_anywhere(eye, &mut rng);
            r.render(&camera(pose), &poses, &[], &mut img);
            assert!(img.depth.iter().all(|d| d.is_finite() && *d >= 0.0));
            assert!(img.labels.iter().all(|&l| r.label_name(l).is_some()));
            StereoNoise::D435.apply(&mut img.depth, 640, 619.9, &mut rng);
            assert!(img.depth.iter().all(|d| d.is_finite() && *d >= 0.0));
        }
    }
}

/// The camera in two bands of rows (two threads) renders the image one camera renders: the
/// same labels on all but edge pixels (at most 0.05 %), the same depth where the labels agree
/// within 0.5 mm, the geometry tests' tolerance (measured: 0.17 mm, from the spans' 1/z stepped
/// from another first row); with noise, the same seed gives the same frames.
#[test]
fn two_bands_render_the_one_image() {
    use ferrobot_sim::camera::{BandedCamera, SimCamera};
    let cfg = ferrobot_description::RobotConfig::bundled("locobot").unwrap();
    let section = cfg.camera.clone().unwrap();
    let sim = ferrobot_sim::LockstepSim::with_scene(
        ferrobot_sim::robots::from_description(&cfg),
        ferrobot_profile::firmware_profile(&cfg),
        1,
        std::sync::Arc::new(Scene::bundled("tabletop").unwrap()),
    )
    .unwrap();
    let body = sim.body().unwrap().clone();
    let mut truth = sim.truth();
    truth.joints[body.tree.joint_index("head_tilt_joint").unwrap()] = 0.8;
    truth.links = body.link_poses(&truth.root, &truth.joints);
    let mut one = SimCamera::new(sim.scene(), &body, &section, 1).unwrap();
    one.noise = None;
    let mut two = BandedCamera::new(sim.scene(), &body, &section, 1, false).unwrap();
    let (mut a, mut b) = (RenderedImage::new(640, 480), RenderedImage::new(640, 480));
    one.capture_into(&truth, &mut a);
    two.capture_into(&truth, &mut b);
    let same = a
        .labels
        .iter()
        .zip(&b.labels)
        .filter(|(x, y)| x == y)
        .count();
    let worst = (0..a.depth.len())
        .filter(|&i| a.labels[i] == b.labels[i])
        .map(|i| (a.depth[i] - b.depth[i]).abs())
        .fold(0.0f32, f32::max);
    println!(
        "labels differ at {} px; worst depth difference {worst:e} m",
        a.labels.len() - same
    );
    assert!(a.labels.len() - same <= 154, "{} px", a.labels.len() - same);
    assert!(worst < 5e-4, "{worst}");
    assert_eq!(a.rgb.len(), b.rgb.len());
    let noisy = || {
        let mut c = BandedCamera::new(sim.scene(), &body, &section, 7, true).unwrap();
        let mut img = RenderedImage::new(640, 480);
        c.capture_into(&truth, &mut img);
        img.depth
    };
    let (d1, d2) = (noisy(), noisy());
    assert_eq!(d1, d2);
    assert_ne!(d1, b.depth, "the noise is on");
}

#[test]
fn the_normal_table_holds_the_standard_normals_quantiles() {
    let t = normal_table();
    // Φ⁻¹(0.5 / 4096) = -3.6683; the table is symmetric and its spread 0.99984.
    assert!((f64::from(t[0]) + 3.6683).abs() < 1e-3, "{}", t[0]);
    assert!(t
        .iter()
        .zip(t.iter().rev())
        .all(|(a, b)| (a + b).abs() < 1e-4));
    let var = t.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() / 4096.0;
    assert!((var.sqrt() - 0.99984).abs() < 1e-4, "{}", var.sqrt());
    assert!(t.windows(2).all(|w| w[0] < w[1]));
}

/// Frame instants are a grid of the camera's period from t = 0. A frame is taken at the first
/// instant not yet taken at or after the caller's time, or up to half a period after it (a
/// caller that overshot an instant while it let time pass gets that frame, late, rather than
/// none); then one instant after another, none skipped.
#[test]
fn frames_lie_on_the_cameras_grid_and_none_is_skipped() {
    use ferrobot_sim::camera::FrameClock;
    let period = 33_333;
    for start in [0u64, 1, 99_999, 100_000, 103_000, 116_000, 117_000, 133_333] {
        let mut clock = FrameClock::new(30.0).unwrap();
        let first = clock.next(start);
        assert!(
            first.is_multiple_of(period) && first + period / 2 >= start && first < start + period,
            "start {start} µs: first frame at {first} µs"
        );
        // A caller 10 ms late for the next instant still gets it; the one after is next.
        let second = clock.next(first + period + 10_000);
        assert_eq!(second, first + period, "start {start} µs");
        assert_eq!(clock.next(second), second + period, "start {start} µs");
    }
}
