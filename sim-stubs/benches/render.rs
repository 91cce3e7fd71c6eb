//! Rendering benchmarks: the simulated camera's frames (640 x 480 colour, depth and labels)
//! in the bundled `tabletop` and `apartment` scenes, and PyBullet's CPU renderer
//! (`getCameraImage` with `ER_TINY_RENDERER`, DIRECT mode) on the same scene and camera in the
//! same run. Run: `cargo bench -p ferrobot-sim --bench render`.
//!
//! * The view: the LoCoBot at the scene's start pose, its arm folded up out of the view, the
//!   head tilted down (0.8 rad at the table, 0.3 rad in the apartment); the robot's links are
//!   drawn on both sides. Camera: the description's intrinsics (fx, fy, cx, cy at 640 x 480).
//! * Criterion group `render`: one frame, without and with the D435's depth noise.
//! * The comparison: the whole process is pinned to one CPU (PyBullet, a child process,
//!   inherits it), the scene is exported to JSON (primitives with the same sizes, poses and
//!   colours; meshes as OBJ files of the same triangles; textures are not exported, PyBullet
//!   draws flat colours) and `benches/pybullet_render.py` renders it. Rounds alternate ours and
//!   PyBullet's; the table gives medians over the rounds of wall and CPU time per frame and
//!   the median of the rounds' ratios. PyBullet's Python environment comes from
//!   `scripts/python-env.sh bench` (run by the bench; it installs `pybullet` and `numpy`
//!   into `target/py-venv` when they are missing).
//! * One image pair per scene goes to `target/bench-render/` (ours and PyBullet's colour and
//!   depth as PNG), and the depths at the image centre are printed.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use ferrobot_description::{CameraSection, RobotConfig};
use ferrobot_sim::body::RobotBody;
use ferrobot_sim::camera::StereoNoise;
use ferrobot_sim::mesh::TriMesh;
use ferrobot_sim::render::{PinholeCamera, RenderedImage, Renderer};
use ferrobot_sim::rng::SimRng;
use ferrobot_sim::scene::{Scene, Shape};
use nalgebra::{Isometry3, Matrix4};
use serde_json::{json, Value};
use std::hint::black_box;

/// Near and far planes of PyBullet's projection, m.
const NEAR: f64 = 0.01;
const FAR: f64 = 20.0;
/// Rounds of the comparison, and about how long each side renders in one, s.
const ROUNDS: usize = 7;
const ROUND_S: f64 = 0.6;

/// One camera view of a scene.
struct View {
    name: &'static str,
    scene: Arc<Scene>,
    body: Arc<RobotBody>,
    renderer: Renderer,
    camera: PinholeCamera,
    bodies: Vec<Isometry3<f64>>,
    links: Vec<Isometry3<f64>>,
}

impl View {
    /// The LoCoBot's camera in bundled scene `name`, head tilted `tilt` rad down.
    fn new(name: &'static str, tilt: f64) -> View {
        let cfg = RobotConfig::bundled("locobot").expect("locobot");
        let desc = ferrobot_sim::robots::from_description(&cfg);
        let body = desc.body.clone().expect("the LoCoBot has a body");
        let scene = Arc::new(Scene::bundled(name).expect("scene"));
        let section: &CameraSection = cfg.camera.as_ref().expect("camera");
        let mut q = vec![0.0; body.tree.joints().len()];
        // The head down, the arm folded up and back out of the view.
        for (joint, value) in [
            ("head_tilt_joint", tilt),
            ("joint_2", -1.5),
            ("joint_3", 1.5),
            ("joint_4", 0.6),
        ] {
            q[body.tree.joint_index(joint).expect("joint")] = value;
        }
        let [x, y, heading] = scene.robot_pose;
        let root = RobotBody::root_pose([x, y, heading], scene.robot_height);
        let links = body.link_poses(&root, &q);
        let optical = body.tree.link_index(&section.frame).expect("optical frame");
        let camera = PinholeCamera {
            width: section.width,
            height: section.height,
            fx: section.fx,
            fy: section.fy,
            cx: section.cx,
            cy: section.cy,
            pose: links[optical],
        };
        View {
            name,
            renderer: Renderer::new(&scene, Some(&body)),
            bodies: scene.bodies.iter().map(|b| b.pose).collect(),
            scene,
            body,
            camera,
            links,
        }
    }

    fn render(&self, out: &mut RenderedImage, noise: Option<&mut SimRng>) {
        self.renderer
            .render(&self.camera, &self.bodies, &self.links, out);
        if let Some(rng) = noise {
            let w = self.camera.width as usize;
            StereoNoise::D435.apply(&mut out.depth, w, self.camera.fx, rng);
        }
    }

    /// The scene as `pybullet_render.py` reads it; meshes are written as OBJ files in `dir`.
    fn export(&self, dir: &Path) -> Value {
        let mut shapes = Vec::new();
        let mut add = |shape: &Shape, pose: Isometry3<f64>, colour: [f32; 3], tag: String| {
            let mut s = match shape {
                Shape::Box(size) => json!({ "kind": "box", "size": size }),
                Shape::Cylinder { radius, length } => {
                    json!({ "kind": "cylinder", "radius": radius, "length": length })
                }
                Shape::Sphere(radius) => json!({ "kind": "sphere", "radius": radius }),
                Shape::Capsule { radius, length } => {
                    json!({ "kind": "capsule", "radius": radius, "length": length })
                }
                Shape::Mesh { mesh, .. } => {
                    let path = dir.join(format!("{}_{tag}.obj", self.name));
                    write_obj(&path, mesh);
                    json!({ "kind": "mesh", "obj": path })
                }
            };
            let t = pose.translation.vector;
            let q = pose.rotation.coords;
            s["position"] = json!([t.x, t.y, t.z]);
            s["quaternion"] = json!([q.x, q.y, q.z, q.w]);
            s["colour"] = json!(colour);
            shapes.push(s);
        };
        for (b, pose) in self.scene.bodies.iter().zip(&self.bodies) {
            add(&b.shape, *pose, b.colour, b.id.clone());
        }
        for (i, (link_shapes, pose)) in self.body.shapes.iter().zip(&self.links).enumerate() {
            for (j, s) in link_shapes.iter().enumerate() {
                add(&s.shape, pose * s.origin, s.colour, format!("link{i}_{j}"));
            }
        }
        let c = &self.camera;
        let (w, h) = (f64::from(c.width), f64::from(c.height));
        // OpenGL's camera (x right, y up, looking along -z) from the optical frame, and a
        // projection whose pixels fall where the pinhole puts columns and rows. TinyRenderer
        // samples at whole viewport coordinates (column c at x = c, row r at y = h - 1 - r),
        // not at OpenGL's pixel centres (+0.5): the principal point (cx, cy) of our rows
        // counted down is (cx, h - 1 - cy) in its viewport, which this matrix gives. Then the
        // two depth images agree to the rounding in 96 % of the tabletop's pixels.
        let gl = Matrix4::from_diagonal(&nalgebra::Vector4::new(1.0, -1.0, -1.0, 1.0));
        let view = gl * c.pose.inverse().to_homogeneous();
        let (cx, cy) = (c.cx, c.cy + 1.0);
        #[rustfmt::skip]
        let projection = Matrix4::new(
            2.0 * c.fx / w, 0.0, 1.0 - 2.0 * cx / w, 0.0,
            0.0, 2.0 * c.fy / h, 2.0 * cy / h - 1.0, 0.0,
            0.0, 0.0, -(FAR + NEAR) / (FAR - NEAR), -2.0 * FAR * NEAR / (FAR - NEAR),
            0.0, 0.0, -1.0, 0.0,
        );
        json!({
            "shapes": shapes,
            "camera": {
                "width": c.width,
                "height": c.height,
                "view": view.as_slice(),
                "projection": projection.as_slice(),
                "near": NEAR,
                "far": FAR,
            }
        })
    }
}

fn write_obj(path: &Path, m: &TriMesh) {
    let mut s = String::new();
    for v in &m.vertices {
        s += &format!("v {} {} {}\n", v.x, v.y, v.z);
    }
    for t in &m.triangles {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, s).expect("write OBJ");
}

fn views() -> Vec<View> {
    vec![View::new("tabletop", 0.8), View::new("apartment", 0.3)]
}

fn bench(c: &mut Criterion) {
    let cpu = pin_to_one_cpu();
    let mut group = c.benchmark_group("render");
    group.sample_size(30);
    for v in views() {
        let mut img = RenderedImage::new(v.camera.width, v.camera.height);
        group.bench_function(format!("{} 640x480 colour+depth+labels", v.name), |b| {
            b.iter(|| {
                v.render(&mut img, None);
                black_box(&img);
            })
        });
        let mut rng = SimRng::new(1, 1);
        group.bench_function(format!("{} 640x480 with depth noise", v.name), |b| {
            b.iter(|| {
                v.render(&mut img, Some(&mut rng));
                black_box(&img);
            })
        });
    }
    group.finish();
    compare_with_pybullet(cpu);
}

/// Pin this process (and the children it starts) to one CPU: the highest-numbered one it may
/// run on.
fn pin_to_one_cpu() -> Option<usize> {
    use nix::sched::{sched_getaffinity, sched_setaffinity, CpuSet};
    use nix::unistd::Pid;
    let allowed = sched_getaffinity(Pid::from_raw(0)).ok()?;
    let cpu = (0..CpuSet::count())
        .rev()
        .find(|&i| allowed.is_set(i).unwrap_or(false))?;
    let mut one = CpuSet::new();
    one.set(cpu).ok()?;
    sched_setaffinity(Pid::from_raw(0), &one).ok()?;
    Some(cpu)
}

/// This thread's time on a CPU so far, s (Linux's /proc/thread-self/schedstat).
fn cpu_time() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .map_or(f64::NAN, |ns| ns as f64 * 1e-9)
}

fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    x[x.len() / 2]
}

/// PyBullet's renderer behind `benches/pybullet_render.py`.
struct PyBullet {
    child: std::process::Child,
    out: BufReader<std::process::ChildStdout>,
}

impl PyBullet {
    fn start(python: &Path, scene_json: &Path) -> PyBullet {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/pybullet_render.py");
        let mut child = Command::new(python)
            .arg(script)
            .arg(scene_json)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("start PyBullet");
        let out = BufReader::new(child.stdout.take().expect("stdout"));
        PyBullet { child, out }
    }

    fn ask(&mut self, cmd: &str) -> String {
        let stdin = self.child.stdin.as_mut().expect("stdin");
        writeln!(stdin, "{cmd}").expect("to PyBullet");
        stdin.flush().expect("flush");
        let mut line = String::new();
        // PyBullet prints its build time first.
        while !line.starts_with(|c: char| c.is_ascii_digit() || c == 'o') {
            line.clear();
            if self.out.read_line(&mut line).expect("from PyBullet") == 0 {
                panic!("PyBullet ended (command {cmd:?})");
            }
        }
        line.trim().to_string()
    }

    /// Wall and CPU time of `n` frames, s.
    fn render(&mut self, n: usize) -> (f64, f64) {
        let r = self.ask(&format!("render {n}"));
        let mut it = r
            .split_whitespace()
            .map(|x| x.parse::<f64>().expect("time"));
        (it.next().expect("wall"), it.next().expect("cpu"))
    }
}

impl Drop for PyBullet {
    fn drop(&mut self) {
        if let Some(stdin) = self.child.stdin.as_mut() {
            let _ = writeln!(stdin, "quit");
        }
        let _ = self.child.wait();
    }
}

fn write_png(path: &Path, w: u32, h: u32, colour: png::ColorType, data: &[u8]) {
    let f = std::io::BufWriter::new(std::fs::File::create(path).expect("create PNG"));
    let mut e = png::Encoder::new(f, w, h);
    e.set_color(colour);
    e.set_depth(png::BitDepth::Eight);
    e.write_header()
        .expect("PNG header")
        .write_image_data(data)
        .expect("PNG data");
}

/// Depth as grey, 0.25 m white to 4 m black (log scale); nothing (0) black.
fn depth_png(path: &Path, w: u32, h: u32, depth: &[f32]) {
    let grey: Vec<u8> = depth
        .iter()
        .map(|&d| {
            if d > 0.0 {
                (255.0 * (1.0 - (d / 0.25).ln() / 16f32.ln())).clamp(0.0, 255.0) as u8
            } else {
                0
            }
        })
        .collect();
    write_png(path, w, h, png::ColorType::Grayscale, &grey);
}

/// One scene's line of the comparison: [wall, CPU] seconds per frame, and the ratios.
struct Row {
    scene: &'static str,
    triangles: usize,
    ours: [f64; 2],
    noisy: [f64; 2],
    pybullet: [f64; 2],
    ratio: [f64; 2],
}

fn compare_with_pybullet(cpu: Option<usize>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let setup = Command::new(root.join("scripts/python-env.sh"))
        .arg("bench")
        .status();
    if !setup.map(|s| s.success()).unwrap_or(false) {
        eprintln!("scripts/python-env.sh bench failed: no PyBullet comparison");
        return;
    }
    let python = root.join("target/py-venv/bin/python");
    let target = std::env::var_os("CARGO_TARGET_DIR").map_or(root.join("target"), PathBuf::from);
    let dir = target.join("bench-render");
    std::fs::create_dir_all(&dir).expect("bench-render dir");
    let mut rows = Vec::new();
    for v in views() {
        let json_path = dir.join(format!("{}.json", v.name));
        std::fs::write(&json_path, v.export(&dir).to_string()).expect("scene JSON");
        let mut py = PyBullet::start(&python, &json_path);
        let mut img = RenderedImage::new(v.camera.width, v.camera.height);
        let mut rng = SimRng::new(1, 1);
        // Warm-up and calibration: frames per round for about ROUND_S s each.
        v.render(&mut img, None);
        let t = Instant::now();
        for _ in 0..10 {
            v.render(&mut img, None);
        }
        let n_ours = ((ROUND_S / (t.elapsed().as_secs_f64() / 10.0)) as usize).max(10);
        let (w1, _) = py.render(2);
        let n_py = ((ROUND_S / (w1 / 2.0)) as usize).max(2);
        let (mut ours, mut ours_cpu, mut noisy, mut noisy_cpu) = (vec![], vec![], vec![], vec![]);
        let (mut theirs, mut theirs_cpu) = (vec![], vec![]);
        let (mut ratio, mut ratio_cpu) = (vec![], vec![]);
        for _ in 0..ROUNDS {
            let (t, c) = (Instant::now(), cpu_time());
            for _ in 0..n_ours {
                v.render(&mut img, None);
                black_box(&img);
            }
            let (w_ours, c_ours) = (
                t.elapsed().as_secs_f64() / n_ours as f64,
                (cpu_time() - c) / n_ours as f64,
            );
            let (t, c) = (Instant::now(), cpu_time());
            for _ in 0..n_ours {
                v.render(&mut img, Some(&mut rng));
                black_box(&img);
            }
            noisy.push(t.elapsed().as_secs_f64() / n_ours as f64);
            noisy_cpu.push((cpu_time() - c) / n_ours as f64);
            let (w, c) = py.render(n_py);
            let (w_py, c_py) = (w / n_py as f64, c / n_py as f64);
            ours.push(w_ours);
            ours_cpu.push(c_ours);
            theirs.push(w_py);
            theirs_cpu.push(c_py);
            ratio.push(w_py / w_ours);
            ratio_cpu.push(c_py / c_ours);
        }
        // One image pair for a look, and the depth at the centre on both sides.
        v.render(&mut img, None);
        let (w, h) = (v.camera.width, v.camera.height);
        let prefix = dir.join(v.name);
        write_png(
            &dir.join(format!("{}_ours_rgb.png", v.name)),
            w,
            h,
            png::ColorType::Rgb,
            &img.rgb,
        );
        depth_png(
            &dir.join(format!("{}_ours_depth.png", v.name)),
            w,
            h,
            &img.depth,
        );
        assert_eq!(py.ask(&format!("dump {}_pybullet", prefix.display())), "ok");
        let rgb = std::fs::read(format!("{}_pybullet.rgb", prefix.display())).expect("rgb");
        let depth: Vec<f32> = std::fs::read(format!("{}_pybullet.depth", prefix.display()))
            .expect("depth")
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        write_png(
            &dir.join(format!("{}_pybullet_rgb.png", v.name)),
            w,
            h,
            png::ColorType::Rgb,
            &rgb,
        );
        depth_png(
            &dir.join(format!("{}_pybullet_depth.png", v.name)),
            w,
            h,
            &depth,
        );
        let centre = (h as usize / 2) * w as usize + w as usize / 2;
        // Where both see something, how far apart the depths are.
        let diffs: Vec<f64> = img
            .depth
            .iter()
            .zip(&depth)
            .filter(|(a, b)| **a > 0.0 && **b > 0.0)
            .map(|(a, b)| f64::from((a - b).abs()))
            .collect();
        let close = diffs.iter().filter(|&&d| d < 0.001).count() as f64 / diffs.len() as f64;
        println!(
            "{}: depth at the centre: ours {:.4} m, PyBullet {:.4} m; {:.1} % of the pixels both see within 1 mm (median difference {:.2} mm)",
            v.name,
            img.depth[centre],
            depth[centre],
            100.0 * close,
            1e3 * median(diffs.clone()),
        );
        rows.push(Row {
            scene: v.name,
            triangles: v.renderer.triangles(),
            ours: [median(ours), median(ours_cpu)],
            noisy: [median(noisy), median(noisy_cpu)],
            pybullet: [median(theirs), median(theirs_cpu)],
            ratio: [median(ratio), median(ratio_cpu)],
        });
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "\nRendering 640x480 colour + depth + labels on one CPU ({}), {ROUNDS} rounds alternating, \
         medians of wall-clock (CPU-time) ms per frame; load average {}",
        cpu.map_or("not pinned".into(), |c| format!("cpu {c}")),
        load.split_whitespace().take(3).collect::<Vec<_>>().join(" "),
    );
    println!(
        "| scene | triangles | ours, ms (fps) | ours with depth noise, ms (fps) | \
         PyBullet ER_TINY_RENDERER, ms (fps) | PyBullet / ours |"
    );
    println!("|---|---|---|---|---|---|");
    let ms = |t: [f64; 2]| {
        format!(
            "{:.2} ({:.0}); CPU {:.2} ({:.0})",
            t[0] * 1e3,
            1.0 / t[0],
            t[1] * 1e3,
            1.0 / t[1]
        )
    };
    for r in &rows {
        println!(
            "| {} | {} | {} | {} | {} | {:.0}x; CPU {:.0}x |",
            r.scene,
            r.triangles,
            ms(r.ours),
            ms(r.noisy),
            ms(r.pybullet),
            r.ratio[0],
            r.ratio[1],
        );
    }
    println!("Images: {}", dir.display());
}

criterion_group!(benches, bench);
criterion_main!(benches);
