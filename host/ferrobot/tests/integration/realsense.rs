//! The RealSense server (`host/peers/realsense/serve_realsense.py`) on librealsense's own
//! software device, read through [`SocketCamera`]: alignment, depth units and intrinsics are
//! Intel's code, and this test predicts what they must give from the scene it chose.
//!
//! The scene (the depth imager's optical frame, m): a plane z = 1.2 + 0.25 y and, in front of
//! it, a box face at z = 0.7 for x in [-0.10, 0.08], y in [-0.05, 0.12]. The depth imager is
//! 424x240 with its own intrinsics and a 0.1 mm depth unit; the colour camera is the LoCoBot's
//! (its description's size and rate) with other intrinsics, 15 mm right of and 1 mm below the
//! depth imager. Each colour pixel's ray is followed here into the scene and back into the
//! depth image, independently of librealsense, to say which surface it must show and at what
//! depth.
//!
//! Needs pyrealsense2 (`scripts/python-env.sh realsense`): skipped only where PyPI has no
//! wheel for the platform, by [`ferrobot_peers::for_test_where_wheels_exist`]'s rule.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use ferrobot::backend::camera_socket::SocketCamera;
use ferrobot::backend::Link;
use ferrobot::camera::{RawFrame, TimeDomain};
use ferrobot::{CameraDevice, RobotConfig};
use nalgebra::{Matrix3, Vector3};

/// A pinhole: size (px) and intrinsics (px).
#[derive(Clone, Copy)]
struct Pinhole {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
}

impl Pinhole {
    /// The ray through pixel (column u, row v), z = 1.
    fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        Vector3::new((u - self.cx) / self.fx, (v - self.cy) / self.fy, 1.0)
    }
    /// The pixel (column, row) where `p` (z > 0) projects.
    fn project(&self, p: &Vector3<f64>) -> (f64, f64) {
        (self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy)
    }
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Surface {
    Plane,
    Box,
}

/// The software device's scene and calibration (see the module's doc).
struct Scene {
    colour: Pinhole,
    depth: Pinhole,
    /// m per Z16 step.
    depth_unit: f64,
    /// Depth imager to colour camera: p_colour = rotation · p_depth + translation (m).
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
    /// The plane z = distance + slope · y.
    plane: (f64, f64),
    box_x: (f64, f64),
    box_y: (f64, f64),
    box_z: f64,
}

impl Scene {
    fn new(width: u32, height: u32) -> Self {
        Scene {
            // Not the description's intrinsics: the served ones must be the device's.
            colour: Pinhole {
                width,
                height,
                fx: 615.25,
                fy: 614.75,
                cx: 318.5,
                cy: 243.25,
            },
            depth: Pinhole {
                width: 424,
                height: 240,
                fx: 213.0,
                fy: 212.5,
                cx: 211.0,
                cy: 119.0,
            },
            depth_unit: 0.0001,
            rotation: Matrix3::identity(),
            translation: Vector3::new(0.015, 0.001, 0.0),
            plane: (1.2, 0.25),
            box_x: (-0.10, 0.08),
            box_y: (-0.05, 0.12),
            box_z: 0.7,
        }
    }

    /// The scene as `serve_realsense.py --software-scene` reads it.
    fn json(&self) -> String {
        let (c, d, r) = (self.colour, self.depth, self.rotation);
        serde_json::json!({
            "colour": {"fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy},
            "depth": {"width": d.width, "height": d.height, "fx": d.fx, "fy": d.fy,
                "cx": d.cx, "cy": d.cy},
            "depth_unit": self.depth_unit,
            "rotation": [r[(0, 0)], r[(0, 1)], r[(0, 2)], r[(1, 0)], r[(1, 1)], r[(1, 2)],
                r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            "translation": [self.translation.x, self.translation.y, self.translation.z],
            "plane": {"distance": self.plane.0, "slope": self.plane.1},
            "box": {"x": [self.box_x.0, self.box_x.1], "y": [self.box_y.0, self.box_y.1],
                "z": self.box_z},
        })
        .to_string()
    }

    /// The first surface on the ray `origin + s · dir` (s > 0), and the point, depth frame.
    fn meet(&self, origin: Vector3<f64>, dir: Vector3<f64>) -> Option<(Surface, Vector3<f64>)> {
        let s = (self.box_z - origin.z) / dir.z;
        let p = origin + s * dir;
        let (bx, by) = (self.box_x, self.box_y);
        if s > 0.0 && p.x >= bx.0 && p.x <= bx.1 && p.y >= by.0 && p.y <= by.1 {
            return Some((Surface::Box, p));
        }
        let (d, slope) = self.plane;
        let s = (d - origin.z + slope * origin.y) / (dir.z - slope * dir.y);
        (s > 0.0).then(|| (Surface::Plane, origin + s * dir))
    }

    /// What the colour camera's pixel (column u, row v) sees, in the depth imager's frame.
    fn colour_sees(&self, u: f64, v: f64) -> Option<(Surface, Vector3<f64>)> {
        let rt = self.rotation.transpose();
        self.meet(-(rt * self.translation), rt * self.colour.ray(u, v))
    }

    /// What the depth imager's pixel (column u, row v) sees.
    fn depth_sees(&self, u: f64, v: f64) -> Option<Surface> {
        self.meet(Vector3::zeros(), self.depth.ray(u, v))
            .map(|(s, _)| s)
    }

    /// The depth librealsense's alignment must give colour pixel (u, v), with the surface: the
    /// depth imager's z of what the pixel sees (librealsense keeps the depth imager's z; the
    /// rotation is the identity and the offset has no z, so it is the colour camera's z too).
    /// `None` where the answer is not clear-cut: within `margin` px (colour) of an edge of the
    /// box or of its shadow, or near the depth image's border.
    fn expected(&self, u: f64, v: f64, margin: f64) -> Option<(Surface, f64)> {
        let (surface, p) = self.colour_sees(u, v)?;
        for (du, dv) in [(0.0, 0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
            .into_iter()
            .chain([(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)])
        {
            let (s, q) = self.colour_sees(u + du * margin, v + dv * margin)?;
            let (ud, vd) = self.depth.project(&q);
            let inside = ud >= 2.0
                && vd >= 2.0
                && ud <= f64::from(self.depth.width) - 3.0
                && vd <= f64::from(self.depth.height) - 3.0;
            if s != surface || !inside || self.depth_sees(ud.round(), vd.round()) != Some(s) {
                return None;
            }
        }
        Some((surface, p.z))
    }
}

/// The software frame n's colour at column u, row v (the server's pattern).
fn pattern(u: usize, v: usize, n: u64) -> [u8; 3] {
    let b = (3 * u as u64 + 5 * v as u64 + 7 * n) % 256;
    [(u % 256) as u8, (v % 256) as u8, b as u8]
}

/// The server, stopped (SIGKILL) if the test ends before it shuts down itself.
struct Server {
    child: Child,
    socket: PathBuf,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.socket);
    }
}

impl Server {
    fn start(py: &Path, args: &[String], socket: PathBuf) -> Server {
        let script =
            ferrobot_peers::workspace_root().join("host/peers/realsense/serve_realsense.py");
        let child = Command::new(py)
            .arg(script)
            .arg("--socket")
            .arg(&socket)
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start serve_realsense.py");
        let mut server = Server { child, socket };
        let deadline = Instant::now() + Duration::from_secs(60);
        while !server.socket.exists() {
            if let Some(status) = server.child.try_wait().unwrap() {
                panic!("serve_realsense.py ended ({status}): {}", server.stderr());
            }
            assert!(Instant::now() < deadline, "no socket after 60 s");
            std::thread::sleep(Duration::from_millis(20));
        }
        server
    }

    fn stderr(&mut self) -> String {
        let mut s = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            let _ = std::io::Read::read_to_string(&mut e, &mut s);
        }
        s
    }
}

/// Ends a one-shot run of the server; its status and standard error.
fn run_once(py: &Path, before: &[&str], args: &[&str]) -> (Option<i32>, String) {
    let script = ferrobot_peers::workspace_root().join("host/peers/realsense/serve_realsense.py");
    let out = Command::new(py)
        .args(before)
        .arg(script)
        .args(args)
        .output()
        .expect("run serve_realsense.py");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// Every check of one aligned frame: the colour pattern byte for byte, and depth against the
/// scene where the answer is clear-cut. Returns the number of box and plane pixels checked
/// and the largest plane error (m).
fn check_frame(scene: &Scene, frame: &RawFrame, n: u64) -> (usize, usize, f64) {
    let (w, h) = (scene.colour.width as usize, scene.colour.height as usize);
    let rgb = &frame.rgb.data;
    for v in 0..h {
        for u in 0..w {
            let i = 3 * (v * w + u);
            assert_eq!(
                rgb[i..i + 3],
                pattern(u, v, n),
                "colour at ({u}, {v}), frame {n}"
            );
        }
    }
    let depth = &frame.depth.data;
    let (mut boxes, mut planes, mut worst) = (0, 0, 0.0f64);
    for v in 8..h - 8 {
        for u in 8..w - 8 {
            let Some((surface, z)) = scene.expected(u as f64, v as f64, 3.0) else {
                continue;
            };
            let got = f64::from(depth[v * w + u]);
            let err = (got - z).abs();
            match surface {
                // 0.7 m is 7000 steps of 0.1 mm exactly: only f32 rounding remains.
                Surface::Box => {
                    assert!(err < 1e-4, "box at ({u}, {v}): {got} m, not {z}");
                    boxes += 1;
                }
                // One depth pixel's footprint spans up to 2 mm of the plane (0.25 m/m of slope,
                // 212.5 px focal length, z up to 1.45 m) and alignment takes the depth of the
                // depth pixel whose footprint covers the colour pixel.
                Surface::Plane => {
                    assert!(err < 3e-3, "plane at ({u}, {v}): {got} m, not {z}");
                    planes += 1;
                    worst = worst.max(err);
                }
            }
        }
    }
    (boxes, planes, worst)
}

/// How many checked pixels a camera without the extrinsics (depth imager and colour camera at
/// one place) would show on the other surface: the test's power to see the extrinsics.
fn pixels_the_offset_moves(scene: &Scene) -> usize {
    let still = Scene {
        translation: Vector3::zeros(),
        ..Scene::new(scene.colour.width, scene.colour.height)
    };
    let (w, h) = (scene.colour.width, scene.colour.height);
    (8..h - 8)
        .flat_map(|v| (8..w - 8).map(move |u| (f64::from(u), f64::from(v))))
        .filter(|&(u, v)| {
            let a = scene.expected(u, v, 3.0).map(|e| e.0);
            let b = still.colour_sees(u, v).map(|e| e.0);
            a.is_some() && a != b
        })
        .count()
}

/// The peers' interpreter with pyrealsense2, or `None` (and the skip said) where its wheel
/// does not exist for this platform.
fn realsense_python() -> Option<std::path::PathBuf> {
    ferrobot_peers::for_test_where_wheels_exist(
        "pyrealsense2, numpy",
        "scripts/python-env.sh realsense",
        "pyrealsense2",
    )
}

#[test]
fn a_realsense_software_device_is_served_aligned_in_metres_with_its_intrinsics_and_stamps() {
    let Some(py) = realsense_python() else {
        return;
    };
    let started = Instant::now();
    let section = RobotConfig::bundled("locobot").unwrap().camera.unwrap();
    let scene = Scene::new(section.width, section.height);
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    let args: Vec<String> = [
        "--width",
        &section.width.to_string(),
        "--height",
        &section.height.to_string(),
        "--rate",
        &section.rate.to_string(),
        "--software-device",
        "--software-scene",
        &scene.json(),
    ]
    .map(String::from)
    .to_vec();
    let mut server = Server::start(&py, &args, dir.join("cam"));

    let mut cam = SocketCamera::connect(&server.socket).unwrap();
    // The colour stream's intrinsics (librealsense keeps them as f32), not the depth's.
    let (k, c) = (cam.intrinsics(), scene.colour);
    assert_eq!((k.width, k.height), (c.width, c.height));
    for (got, want) in [(k.fx, c.fx), (k.fy, c.fy), (k.cx, c.cx), (k.cy, c.cy)] {
        assert!((got - want).abs() < 1e-4, "intrinsics {k:?}");
    }
    assert_eq!(cam.rate(), section.rate);
    let distortion = cam.distortion().expect("a distortion");
    assert_eq!(distortion.model, "none");
    assert!(
        distortion.coeffs.iter().all(|&c| c == 0.0),
        "{distortion:?}"
    );
    assert!(cam.device().unwrap().contains("software device"));

    // A socket camera stamps a real camera's frames with its link's clock: a simulator's at 1 s.
    let cfg = RobotConfig::bundled("locobot").unwrap();
    let mut link = ferrobot::backend::sim::SimLink::start(
        &cfg,
        1,
        false,
        std::sync::Arc::new(ferrobot::scene::Scene::empty()),
    )
    .unwrap();
    link.wait(Duration::from_secs(1));
    let now = link.now();
    let moved = pixels_the_offset_moves(&scene);
    assert!(moved > 1000, "{moved} checked pixels see the extrinsics");
    eprintln!("{moved} checked pixels would show the other surface without the extrinsics");
    let mut last = 0;
    for _ in 0..5 {
        let frame = cam.capture(&mut link).unwrap();
        let stamp = frame.device_time.expect("a device stamp");
        let n = stamp.frame_number;
        assert!(n > last, "frame {n} after {last}");
        last = n;
        // The software frame n's timestamp, on its hardware clock.
        let period_ms = 1000.0 / section.rate;
        assert!(
            (stamp.time_ms - n as f64 * period_ms).abs() < 1e-6,
            "{stamp:?}"
        );
        assert_eq!(stamp.domain, TimeDomain::HardwareClock);
        let age = now - frame.time;
        assert!(
            frame.time <= now && age < Duration::from_secs(1),
            "{age:?} old"
        );
        let (boxes, planes, worst) = check_frame(&scene, &frame, n);
        assert!(
            boxes > 10_000 && planes > 100_000,
            "{boxes} box, {planes} plane pixels"
        );
        eprintln!(
            "frame {n}: {boxes} box and {planes} plane pixels checked, the plane within \
             {:.2} mm; {:.1} ms old",
            worst * 1e3,
            age.as_secs_f64() * 1e3
        );
    }

    // SIGTERM: a clean exit, the socket removed.
    let pid = server.child.id().to_string();
    assert!(Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .unwrap()
        .success());
    let deadline = Instant::now() + Duration::from_secs(10);
    let status = loop {
        if let Some(s) = server.child.try_wait().unwrap() {
            break s;
        }
        assert!(
            Instant::now() < deadline,
            "still running 10 s after SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "{status}: {}", server.stderr());
    assert!(!server.socket.exists(), "the socket is left behind");
    drop(server);
    eprintln!(
        "served, checked and stopped in {:.2} s",
        started.elapsed().as_secs_f64()
    );
}

/// Without a camera, or without pyrealsense2, the server says so and fails.
#[test]
fn a_missing_realsense_or_pyrealsense2_is_said_plainly() {
    let Some(py) = realsense_python() else {
        return;
    };
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    let socket = dir.join("cam").display().to_string();
    let size = ["--width", "640", "--height", "480", "--rate", "30"];
    let serial = ["--serial", "ferrobot-no-such-camera"];
    let args: Vec<&str> = ["--socket", &socket]
        .iter()
        .chain(&size)
        .chain(&serial)
        .copied()
        .collect();
    let (code, err) = run_once(&py, &[], &args);
    assert_eq!(code, Some(4), "{err}");
    assert!(err.contains("no RealSense device"), "{err}");
    // `-S`: the interpreter without its site-packages, so without pyrealsense2.
    let (code, err) = run_once(&py, &["-S"], &args);
    assert_eq!(code, Some(3), "{err}");
    assert!(
        err.contains("pyrealsense2") && err.contains("is not installed"),
        "{err}"
    );
    assert!(!Path::new(&socket).exists());
}
