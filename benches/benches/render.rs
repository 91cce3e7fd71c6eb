//! Rendering benchmarks: the simulated camera's frames (640 x 480 colour, depth and labels)
//! in the bundled `tabletop` and `apartment` scenes, and PyBullet's CPU renderer
//! (`getCameraImage` with `ER_TINY_RENDERER`, DIRECT mode) on the same scene and camera in the
//! same run. Run: `cargo bench -p ferrobot-benches --bench render`.
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

use std::hint::black_box;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use ferrobot_benches::render::{cpu_time, depth_png, views, write_png};
use ferrobot_sim::render::RenderedImage;
use ferrobot_sim::rng::SimRng;

/// Rounds of the comparison, and about how long each side renders in one, s.
const ROUNDS: usize = 7;
const ROUND_S: f64 = 0.6;

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
    let python = ferrobot_peers::venv_python();
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
