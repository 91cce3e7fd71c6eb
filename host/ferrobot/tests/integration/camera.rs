//! The camera API on the simulator backend, against the simulated world's ground truth:
//! the robot sees its own gripper where forward kinematics and the camera's pose project it,
//! `pix_to_3dpt` lands on the objects' surfaces, clouds in `base_link` agree with the scene,
//! and bad input is a typed error.

use ferrobot::perception::Intrinsics;
use ferrobot::{Error, Robot};
use ferrobot_sim::camera::BandedCamera;
use ferrobot_sim::render::RenderedImage;
use nalgebra::{Isometry3, Point3, Vector3};

/// Pixel bounds (min col, min row, max col, max row) of a box of half extents `h` at pose `t`
/// in the optical frame.
fn projected_bounds(k: &Intrinsics, t: &Isometry3<f64>, h: Vector3<f64>) -> [f64; 4] {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for i in 0..8 {
        let c = Point3::new(
            if i & 1 == 0 { -h.x } else { h.x },
            if i & 2 == 0 { -h.y } else { h.y },
            if i & 4 == 0 { -h.z } else { h.z },
        );
        let (u, v) = k.project(&(t * c)).expect("in front of the camera");
        b = [b[0].min(u), b[1].min(v), b[2].max(u), b[3].max(v)];
    }
    b
}

/// Distance (m) of `p` (in the box's frame) from the surface of a box of half extents `h`.
fn box_surface_distance(p: &Point3<f64>, h: &Vector3<f64>) -> f64 {
    let q = p.coords.abs() - h;
    if q.max() <= 0.0 {
        -q.max()
    } else {
        q.map(|v| v.max(0.0)).norm()
    }
}

/// The pixels the renderer labels `label`, rendered without noise from the simulator's ground
/// truth now by the camera the simulator backend uses (two bands of rows), and that render's
/// depth.
fn labelled_pixels(bot: &Robot, label: &str) -> (Vec<(usize, usize)>, Vec<f32>) {
    let sim = bot.simulator().expect("simulator");
    let cfg = bot.config().camera.clone().unwrap();
    let mut cam = BandedCamera::new(sim.scene(), sim.body().unwrap(), &cfg, 1, false).unwrap();
    let mut img = RenderedImage::new(cfg.width, cfg.height);
    cam.capture_into(&sim.truth(), &mut img);
    let w = cfg.width as usize;
    let px = (0..img.labels.len())
        .filter(|&i| cam.label_name(img.labels[i]) == Some(label))
        .map(|i| (i / w, i % w))
        .collect();
    (px, img.depth)
}

/// With the arm at home and the head tilted down, the gripper's box appears where the link
/// transform (from the measured joints), the frame's camera pose and the intrinsics project
/// it: its unoccluded silhouette edges within 2 px, and every pixel the gripper covers
/// back-projects onto the box's surface within 1.5 mm (2 px at 0.45 m).
#[test]
fn the_robot_sees_its_gripper_where_kinematics_project_it() {
    let bot = Robot::builder("locobot")
        .depth_noise(false)
        .build()
        .unwrap();
    bot.arm().unwrap().set_joint_positions(&[0.0; 5]).unwrap();
    bot.head().unwrap().set_pan_tilt(0.0, 0.45).unwrap();
    bot.wait(0.5).unwrap();
    let cam = bot.camera().unwrap();
    let frame = cam.get_frame().unwrap();
    let (px, depth) = labelled_pixels(&bot, "robot/gripper_link");
    assert_eq!(
        depth, frame.depth.data,
        "the API's frame is the world's render at its time"
    );
    assert!(px.len() > 2000, "the gripper covers {} px", px.len());

    // The gripper's collision box in the optical frame, from the API alone.
    let gripper_in_base = cam.get_link_transform("gripper_link", "base_link").unwrap();
    let sim = bot.simulator().unwrap();
    let body = sim.body().unwrap().clone();
    drop(sim);
    let shape = &body.shapes[body.tree.link_index("gripper_link").unwrap()][0];
    let h = shape.shape.half_extents();
    let h = Vector3::new(h[0], h[1], h[2]);
    let box_in_cam = frame.camera_pose.inverse() * gripper_in_base * shape.origin;
    let p = projected_bounds(&frame.intrinsics, &box_in_cam, h);
    // A pixel is covered when its centre is, so the covered centres lie within half a pixel
    // inside the silhouette's bounds.
    let mut l = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for &(r, c) in &px {
        let (r, c) = (r as f64, c as f64);
        l = [
            l[0].min(c - 0.5),
            l[1].min(r - 0.5),
            l[2].max(c + 0.5),
            l[3].max(r + 0.5),
        ];
    }
    println!("gripper box: projected {p:.2?}, seen {l:.2?} (left, top, right, bottom px)");
    // The bottom edge (the wrist's side, nearest the camera) is hidden by the wrist.
    for (edge, i) in [("left", 0), ("top", 1), ("right", 2)] {
        assert!(
            (p[i] - l[i]).abs() <= 2.0,
            "{edge} edge: projected {:.2}, seen {:.2}",
            p[i],
            l[i]
        );
    }
    assert!(
        l[3] <= p[3] + 2.0,
        "nothing of the gripper shows below its silhouette"
    );

    // Every covered pixel lands on the box.
    let rows: Vec<i64> = px.iter().map(|&(r, _)| r as i64).collect();
    let cols: Vec<i64> = px.iter().map(|&(_, c)| c as i64).collect();
    let pts = frame.pixels(&rows, &cols, false).unwrap();
    let to_box = (gripper_in_base * shape.origin).inverse();
    let worst = pts
        .points
        .iter()
        .map(|p| box_surface_distance(&(to_box * p.expect("valid depth")), &h))
        .fold(0.0f64, f64::max);
    println!(
        "worst distance of a gripper pixel from the box's surface: {:.3} mm",
        worst * 1e3
    );
    assert!(worst < 1.5e-3, "{worst} m");
}

/// Distance (m) of `p` (in the shape's frame) from the surface of `shape`.
fn surface_distance(p: &Point3<f64>, shape: &ferrobot_sim::scene::Shape) -> f64 {
    use ferrobot_sim::scene::Shape;
    match shape {
        Shape::Box(s) => box_surface_distance(p, &(Vector3::new(s[0], s[1], s[2]) / 2.0)),
        Shape::Sphere(r) => (p.coords.norm() - r).abs(),
        Shape::Cylinder { radius, length } => {
            let (dr, dz) = (p.xy().coords.norm() - radius, p.z.abs() - length / 2.0);
            if dr <= 0.0 && dz <= 0.0 {
                -dr.max(dz)
            } else {
                (dr.max(0.0).powi(2) + dz.max(0.0).powi(2)).sqrt()
            }
        }
        Shape::Capsule { radius, length } => {
            let z = p.z.clamp(-length / 2.0, length / 2.0);
            ((p - Point3::new(0.0, 0.0, z)).norm() - radius).abs()
        }
        Shape::Mesh { mesh, .. } => mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
                point_triangle_distance(p, &a, &b, &c)
            })
            .fold(f64::INFINITY, f64::min),
    }
}

/// Distance from `p` to triangle `abc` (Ericson, Real-Time Collision Detection, 5.1.5).
fn point_triangle_distance(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.norm();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.norm();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).norm();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.norm();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).norm();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).norm();
    }
    let denom = 1.0 / (va + vb + vc);
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm()
}

/// In `tabletop` with the head tilted down 0.8 rad (PyRobot's grasping view) and the arm
/// turned aside, exact depth:
/// the pixels of every object back-project onto its surface within 2 mm (`pix_to_3dpt` in
/// `base_link`, the objects placed by the world's ground truth), and every point of
/// `get_current_pcd(in_cam = false)` lies on a surface of the world (a scene body or one of
/// the robot's links) within 2 mm.
#[test]
fn points_and_clouds_in_base_link_agree_with_the_scene() {
    let bot = Robot::builder("locobot")
        .scene("tabletop")
        .depth_noise(false)
        .build()
        .unwrap();
    // The arm turned aside, out of the view.
    bot.arm()
        .unwrap()
        .set_joint_positions(&[1.5, 0.0, 0.0, 0.0, 0.0])
        .unwrap();
    bot.head().unwrap().set_pan_tilt(0.0, 0.8).unwrap();
    // Standing still: the head settles inside its tolerance.
    bot.wait(0.5).unwrap();
    let cam = bot.camera().unwrap();
    let frame = cam.get_frame().unwrap();
    let (scene, truth, base, body) = {
        let sim = bot.simulator().unwrap();
        let body = sim.body().unwrap().clone();
        let truth = sim.truth();
        let base = truth.links[body.tree.link_index("base_link").unwrap()];
        (sim.scene().clone(), truth, base, body)
    };
    let world_to_base = base.inverse();
    let mut seen = 0;
    for (i, b) in scene.bodies.iter().enumerate() {
        let (px, depth) = labelled_pixels(&bot, &b.id);
        assert_eq!(depth, frame.depth.data);
        if px.len() < 20 {
            continue;
        }
        let rows: Vec<i64> = px.iter().map(|&(r, _)| r as i64).collect();
        let cols: Vec<i64> = px.iter().map(|&(_, c)| c as i64).collect();
        let pts = frame.pixels(&rows, &cols, false).unwrap();
        let to_body = (world_to_base * truth.bodies[i]).inverse();
        let worst = pts
            .points
            .iter()
            .flatten()
            .map(|p| surface_distance(&(to_body * p), &b.shape))
            .fold(0.0f64, f64::max);
        println!(
            "{:>16}: {:6} px, worst {:.3} mm from its surface",
            b.id,
            px.len(),
            worst * 1e3
        );
        assert!(worst < 2e-3, "{}: {worst} m", b.id);
        seen += 1;
    }
    assert!(seen >= 10, "the camera sees {seen} bodies");

    // Every surface in the world, in base_link: the scene's bodies and the robot's links.
    let mut surfaces: Vec<(Isometry3<f64>, &ferrobot_sim::scene::Shape)> = scene
        .bodies
        .iter()
        .zip(&truth.bodies)
        .map(|(b, pose)| ((world_to_base * pose).inverse(), &b.shape))
        .collect();
    for (shapes, pose) in body.shapes.iter().zip(&truth.links) {
        for s in shapes {
            surfaces.push(((world_to_base * pose * s.origin).inverse(), &s.shape));
        }
    }
    let cloud = cam.get_current_pcd(false).unwrap();
    let mut worst = 0.0f64;
    // Every 5th point keeps the check cheap in debug builds.
    for p in cloud.points.iter().step_by(5) {
        let d = surfaces
            .iter()
            .map(|(to, shape)| surface_distance(&(to * p), shape))
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(d);
    }
    println!(
        "cloud: {} points, worst {:.3} mm from the world's surfaces",
        cloud.len(),
        worst * 1e3
    );
    assert!(cloud.len() > 50_000);
    assert!(worst < 2e-3, "{worst} m");
}

/// Bad input is a typed error naming what is wrong, and nothing is lost: the camera works on.
#[test]
fn bad_input_is_a_typed_error() {
    let e = Robot::builder("locobot")
        .scene("kitchen")
        .build()
        .unwrap_err();
    assert!(matches!(e, Error::Scene(_)) && e.is_input(), "{e}");
    assert!(
        e.to_string().contains("kitchen") && e.to_string().contains("tabletop"),
        "{e}"
    );

    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "name = \"bad\"\n[[object]]\nid = \"a\"\nshape = \"box\"\ncolour = [1.0, 0.0, 0.0]\nsize = [0.1, -0.1, 0.1]\nposition = [1.0, 0.0, 0.05]\n").unwrap();
    let e = Robot::builder("locobot")
        .scene(bad.to_str().unwrap())
        .build()
        .unwrap_err();
    assert!(matches!(e, Error::Scene(_)), "{e}");
    assert!(
        e.to_string().contains("bad.toml") && e.to_string().contains("size"),
        "{e}"
    );

    // Sawyer has no camera.
    let sawyer = Robot::new("sawyer").unwrap();
    let e = sawyer.camera().unwrap_err();
    assert!(
        matches!(
            e,
            Error::NoComponent {
                component: "camera",
                ..
            }
        ),
        "{e}"
    );
    // Built without its camera.
    let blind = Robot::builder("locobot").use_camera(false).build().unwrap();
    assert!(blind.camera().is_err() && blind.head().is_err());

    let bot = Robot::new("locobot").unwrap();
    let cam = bot.camera().unwrap();
    for (rows, cols) in [
        (vec![480], vec![0]),
        (vec![0], vec![640]),
        (vec![-1], vec![3]),
        (vec![i64::MAX], vec![i64::MIN]),
    ] {
        let e = cam.pix_to_3dpt(&rows, &cols, true).unwrap_err();
        assert!(matches!(e, Error::Perception(_)) && e.is_input(), "{e}");
        assert!(e.to_string().contains("outside the 640x480 image"), "{e}");
    }
    let e = cam.pix_to_3dpt(&[1, 2], &[3], true).unwrap_err();
    assert!(e.to_string().contains("2 rows but 1 columns"), "{e}");
    for (lo, hi) in [
        (1.5, 0.2),
        (f64::NAN, 1.0),
        (-1.0, 1.0),
        (0.2, f64::INFINITY),
    ] {
        assert!(ferrobot::perception::DepthRange::new(lo, hi).is_err());
    }
    let e = cam
        .get_link_transform("gripper_link", "nowhere")
        .unwrap_err();
    assert!(e.to_string().contains("nowhere"), "{e}");
    // ... and the camera works on.
    let frame = cam.get_frame().unwrap();
    assert_eq!((frame.rgb.width, frame.rgb.height), (640, 480));
    assert_eq!(frame.rgb.data.len(), 640 * 480 * 3);
    assert_eq!(cam.get_intrinsics().unwrap()[0][0], 619.8997);
}

/// Frames come at the description's 30 Hz on the robot's clock, each with its time, and a
/// frame's camera pose follows the head.
#[test]
fn frames_come_at_the_camera_rate_with_their_pose() {
    let bot = Robot::builder("locobot").scene("tabletop").build().unwrap();
    let cam = bot.camera().unwrap();
    // The first frame may be one whose instant had just passed when asked for, taken late;
    // from then on they come one period apart.
    cam.get_frame().unwrap();
    let a = cam.get_frame().unwrap();
    let b = cam.get_frame().unwrap();
    let period = b.time.as_secs_f64() - a.time.as_secs_f64();
    assert!(
        (period - 1.0 / 30.0).abs() < 1e-5,
        "{period} s between frames"
    );
    bot.head().unwrap().set_pan_tilt(0.3, 0.6).unwrap();
    let c = cam.get_frame().unwrap();
    // The optical axis (z) of the new pose points 0.3 rad left and 0.6 rad down.
    let z = c.camera_pose.rotation * Vector3::z();
    let (yaw, pitch) = (z.y.atan2(z.x), (-z.z).asin());
    assert!(
        (yaw - 0.3).abs() < 0.01 && (pitch - 0.6).abs() < 0.01,
        "yaw {yaw}, pitch {pitch}"
    );
    // With noise (the default), depth is valid on most of the view (not beyond the floor's
    // end, nor in the left band, the stereo shadows and at edges).
    let valid = c.depth.valid_fraction();
    assert!(valid > 0.5 && valid < 0.98, "{valid}");
}

/// A camera socket that answers with garbage, absurd intrinsics, a frame of the wrong size, a
/// frame 20 s old (a real camera's server, without the robot's clock) or a truncated frame:
/// each a typed error naming the socket, never a panic or a hang (a camera socket is the
/// serial backend's).
#[cfg(feature = "serial")]
#[test]
fn a_hostile_camera_socket_is_a_clear_error() {
    use ferrobot::backend::camera_socket::SocketCamera;
    use std::io::{BufRead, BufReader, Write};
    use std::os::unix::net::UnixListener;
    let good_info = r#"{"width":4,"height":2,"fx":5.0,"fy":5.0,"cx":2.0,"cy":1.0,"rate":30.0}"#;
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("garbage", b"\x00\xffnot json\n".to_vec()),
        (
            "huge focal",
            br#"{"width":4,"height":2,"fx":1e300,"fy":5.0,"cx":2.0,"cy":1.0,"rate":30.0}"#.to_vec(),
        ),
        (
            "zero rate",
            br#"{"width":4,"height":2,"fx":5.0,"fy":5.0,"cx":2.0,"cy":1.0,"rate":0.0}"#.to_vec(),
        ),
        ("error", br#"{"error":"broken"}"#.to_vec()),
        (
            "wrong size",
            format!("{good_info}\n{{\"time_us\":1,\"width\":640,\"height\":480}}").into_bytes(),
        ),
        (
            "ancient",
            format!("{good_info}\n{{\"width\":4,\"height\":2,\"age_us\":20000000}}").into_bytes(),
        ),
        (
            "truncated",
            format!("{good_info}\n{{\"time_us\":1,\"width\":4,\"height\":2}}\n\x01\x02")
                .into_bytes(),
        ),
        ("silence", Vec::new()),
    ];
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    let bot = Robot::builder("locobot").use_camera(false).build().unwrap();
    for (i, (name, reply)) in cases.into_iter().enumerate() {
        let path = dir.join(format!("cam{i}"));
        let listener = UnixListener::bind(&path).unwrap();
        let server = std::thread::spawn(move || {
            let (s, _) = listener.accept().unwrap();
            let mut r = BufReader::new(s.try_clone().unwrap());
            let mut w = s;
            let mut line = String::new();
            let _ = r.read_line(&mut line);
            let _ = w.write_all(&reply);
            let _ = w.write_all(b"\n");
            line.clear();
            let _ = r.read_line(&mut line);
            // Close: the client must not wait for more.
        });
        // A socket camera ignores the link it is given; a simulator's will do.
        let mut link = ferrobot::backend::sim::SimLink::start(
            bot.config(),
            1,
            false,
            std::sync::Arc::new(ferrobot::scene::Scene::empty()),
        )
        .unwrap();
        let r = SocketCamera::connect(&path).and_then(|mut c| {
            use ferrobot::CameraDevice;
            c.capture(&mut link)
        });
        let e = r.expect_err(name);
        assert!(
            matches!(e, Error::Link(_) | Error::Perception(_)),
            "{name}: {e}"
        );
        assert!(
            e.to_string().contains("cam") || matches!(e, Error::Perception(_)),
            "{name}: {e}"
        );
        assert!(
            name != "ancient" || e.to_string().contains("20 s old"),
            "{e}"
        );
        server.join().unwrap();
    }
}
