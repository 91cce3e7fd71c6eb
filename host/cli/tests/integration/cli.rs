//! The `ferrobot` command line: JSON shapes, negative numbers, exit codes, and agreement with
//! the library.

use std::process::Command;

use ferrobot::RobotConfig;

fn run(args: &[&str]) -> (bool, serde_json::Value) {
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(args)
        .output()
        .expect("runs");
    let v = serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
    (out.status.success(), v)
}

#[test]
fn robots_and_info() {
    let (ok, v) = run(&["robots", "--json"]);
    assert!(ok);
    assert_eq!(
        v["robots"],
        serde_json::json!(["locobot", "locobot_lite", "sawyer"])
    );
    let (ok, v) = run(&["info", "sawyer", "--json"]);
    assert!(ok);
    assert_eq!(v["arm"]["ee_frame"], "right_hand");
    assert_eq!(v["joints"].as_array().map(Vec::len), Some(7));
}

#[test]
fn fk_matches_the_library_with_negative_numbers() {
    let q = [0.1, -0.2, 0.3, -0.4, 0.5];
    let args: Vec<String> = q.iter().map(|v| v.to_string()).collect();
    let mut cmd = vec!["fk", "locobot"];
    cmd.extend(args.iter().map(String::as_str));
    cmd.push("--json");
    let (ok, v) = run(&cmd);
    assert!(ok, "{v}");
    let chain =
        ferrobot::profile::arm_chain(&RobotConfig::bundled("locobot").expect("cfg")).expect("arm");
    let t = chain.fk(&q);
    for (k, want) in [t.translation.x, t.translation.y, t.translation.z]
        .iter()
        .enumerate()
    {
        assert!((v["position"][k].as_f64().expect("number") - want).abs() < 1e-12);
    }
    let quat = v["quaternion"].as_array().expect("quaternion");
    let norm: f64 = quat.iter().map(|x| x.as_f64().unwrap_or(0.0).powi(2)).sum();
    assert!((norm - 1.0).abs() < 1e-12);
    assert_eq!(v["rotation"].as_array().map(Vec::len), Some(3));
}

#[test]
fn jacobian_has_six_rows() {
    let (ok, v) = run(&[
        "jacobian", "sawyer", "0", "-1.18", "0", "2.18", "0", "0.57", "3.32", "--json",
    ]);
    assert!(ok);
    let rows = v["jacobian"].as_array().expect("rows");
    assert_eq!(rows.len(), 6);
    assert!(rows.iter().all(|r| r.as_array().map(Vec::len) == Some(7)));
}

#[test]
fn ik_succeeds_and_fails_with_json_and_exit_codes() {
    let (ok, v) = run(&[
        "ik",
        "locobot",
        "--position",
        "0.35",
        "0",
        "0.15",
        "--pitch",
        "1.5708",
        "--roll",
        "0",
        "--json",
    ]);
    assert!(ok, "{v}");
    assert_eq!(v["success"], true);
    let q: Vec<f64> = v["joints"]
        .as_array()
        .expect("joints")
        .iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect();
    let chain =
        ferrobot::profile::arm_chain(&RobotConfig::bundled("locobot").expect("cfg")).expect("arm");
    let p = chain.fk(&q).translation;
    assert!((p.x - 0.35).abs() < 1e-5 && p.y.abs() < 1e-5 && (p.z - 0.15).abs() < 1e-5);
    let (ok, v) = run(&[
        "ik",
        "sawyer",
        "--position",
        "0.6",
        "-0.1",
        "0.4",
        "--quaternion",
        "0",
        "1",
        "0",
        "0",
        "--json",
    ]);
    assert!(ok && v["success"] == true, "{v}");
    let (ok, v) = run(&[
        "ik",
        "locobot",
        "--position",
        "3",
        "0",
        "0",
        "--rpy",
        "0",
        "0",
        "0",
        "--json",
    ]);
    assert!(!ok);
    assert_eq!(v["success"], false);
    assert!(
        v["error"]
            .as_str()
            .is_some_and(|e| e.contains("unreachable")),
        "{v}"
    );
    let (ok, v) = run(&["fk", "locobot", "1", "2", "--json"]);
    assert!(
        !ok && v["error"]
            .as_str()
            .is_some_and(|e| e.contains("expected 5")),
        "{v}"
    );
}

/// `base-move --json`: the documented shape, its keys in alphabetical order, the odometry
/// within 2 cm and 2° of the target, ground truth within 5 cm of the odometry; an unknown
/// controller is a clear error.
#[test]
fn base_move_reports_target_odometry_and_ground_truth() {
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args([
            "base-move",
            "locobot",
            "--relative",
            "1",
            "-0.5",
            "-1.25",
            "--controller",
            "lqr",
            "--smooth",
            "--json",
        ])
        .output()
        .expect("runs");
    let text = String::from_utf8_lossy(&out.stdout);
    let v: serde_json::Value = serde_json::from_str(&text).unwrap_or_default();
    assert!(out.status.success(), "{text}");
    assert_eq!(v["success"], true);
    // `print_json`'s promise: the keys in alphabetical order, an absent error left out.
    let at: Vec<usize> = [
        "\"ground_truth\":",
        "\"odometry\":",
        "\"success\":",
        "\"target\":",
    ]
    .iter()
    .map(|k| text.find(k).unwrap_or_else(|| panic!("{k} in {text}")))
    .collect();
    assert!(at.windows(2).all(|w| w[0] < w[1]), "{text}");
    assert!(!text.contains("\"error\""), "{text}");
    let f = |k: &str| -> Vec<f64> {
        v[k].as_array()
            .expect(k)
            .iter()
            .map(|x| x.as_f64().expect("number"))
            .collect()
    };
    let (t, o, g) = (f("target"), f("odometry"), f("ground_truth"));
    assert_eq!(t, vec![1.0, -0.5, -1.25]);
    assert!((o[0] - t[0]).hypot(o[1] - t[1]) < 0.02, "{v}");
    assert!((o[2] - t[2]).abs() < 2f64.to_radians(), "{v}");
    assert!((g[0] - o[0]).hypot(g[1] - o[1]) < 0.05, "{v}");
    let (ok, v) = run(&[
        "base-move",
        "locobot",
        "--relative",
        "1",
        "0",
        "0",
        "--controller",
        "pid",
        "--json",
    ]);
    assert!(!ok);
    assert_eq!(v["success"], false);
    assert!(
        v["error"]
            .as_str()
            .is_some_and(|e| e.contains("base controller")),
        "{v}"
    );
}

/// `bench base --json` with one trial per target: every controller × category × reference
/// row, finite statistics, every trial succeeded, and a PNG plot written.
#[test]
fn bench_base_json_rows() {
    let dir = std::env::temp_dir().join(format!("ferrobot-bench-{}", std::process::id()));
    let (ok, v) = run(&[
        "bench",
        "base",
        "--robot",
        "locobot",
        "--trials",
        "1",
        "--json",
        "--plot-dir",
        dir.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{v}");
    assert_eq!(v["robot"], "locobot");
    let rows = v["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 4 * 3 * 2);
    for r in rows {
        for k in ["translation_mm", "rotation_deg"] {
            let ms = r[k].as_array().expect(k);
            assert_eq!(ms.len(), 2);
            assert!(
                ms.iter().all(|x| x.as_f64().is_some_and(f64::is_finite)),
                "{r}"
            );
        }
        assert_eq!(r["successes"], serde_json::json!([2, 2]), "{r}");
    }
    for name in ["circle_locobot.png", "circle_locobot_end.png"] {
        let png = std::fs::read(dir.join(name)).expect("plot");
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{name}");
        // IHDR: 800 × 800 pixels.
        assert_eq!(&png[16..24], &[0, 0, 3, 32, 0, 0, 3, 32], "{name}");
    }
    assert_eq!(
        v["circle_end_error_m"].as_array().map(Vec::len),
        Some(3),
        "{v}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn calibrate_odometry_prints_the_estimate() {
    let (ok, v) = run(&[
        "calibrate-odometry",
        "locobot_lite",
        "--seed",
        "3",
        "--json",
    ]);
    assert!(ok, "{v}");
    assert_eq!(v["robot"], "locobot_lite");
    assert_eq!(v["runs"], 10);
    let g = |k: &str, f: &str| v[k][f].as_f64().expect("number");
    assert_eq!(g("nominal", "track"), 0.235);
    // The simulated Create 2's track is 1 % wider than nominal.
    assert!((g("estimate", "track") / 0.235 - 1.01).abs() < 0.002, "{v}");
    assert!(
        g("residual", "position_m") < g("residual_nominal", "position_m"),
        "{v}"
    );
    let (ok, v) = run(&["calibrate-odometry", "sawyer", "--json"]);
    assert!(!ok, "{v}");
}

#[test]
fn a_reader_that_goes_away_ends_the_demo_quietly() {
    // `ferrobot demo | head -1`: the pipe closes after the first line; the demo must end
    // with success and no panic, not "failed printing to stdout".
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .arg("demo")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ferrobot");
    let mut first = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut first)
        .expect("first line");
    // The reader is dropped here: the pipe is closed.
    assert!(first.starts_with("Ferrobot demo"), "{first}");
    let out = child.wait_with_output().expect("exit");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {err}", out.status);
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn scene_json_lists_every_body_in_the_world_frame() {
    let (ok, v) = run(&["scene", "tabletop", "--json"]);
    assert!(ok, "{v}");
    assert_eq!(v["scene"], "tabletop");
    assert_eq!(v["robot_pose"], serde_json::json!([0.0, 0.0, 0.0]));
    let objects = v["objects"].as_array().unwrap();
    let scene = ferrobot::scene::Scene::bundled("tabletop").unwrap();
    assert_eq!(objects.len(), scene.bodies.len());
    let cube = objects.iter().find(|o| o["id"] == "red_cube").unwrap();
    assert_eq!(cube["shape"], "box");
    assert_eq!(cube["size"], serde_json::json!([0.03, 0.03, 0.03]));
    assert_eq!(cube["position"], serde_json::json!([0.36, 0.0, 0.115]));
    assert_eq!(cube["quaternion"], serde_json::json!([0.0, 0.0, 0.0, 1.0]));
    assert_eq!(cube["static"], false);
    assert_eq!(cube["mesh"], serde_json::Value::Null);
    let mug = objects.iter().find(|o| o["id"] == "mug").unwrap();
    assert_eq!(mug["shape"], "mesh");
    assert!(mug["mesh"].as_str().unwrap().ends_with("mug.obj"));
    let cyl = objects
        .iter()
        .find(|o| o["id"] == "green_cylinder")
        .unwrap();
    assert_eq!(cyl["size"], serde_json::json!([0.02, 0.06]));
    let (ok, v) = run(&["scene", "kitchen", "--json"]);
    assert!(!ok && v["input_error"] == true, "{v}");
}

/// A snapshot without noise: the files are what they claim (8-bit RGB, 16-bit millimetre
/// depth of the same size, a PLY cloud), the printed pose and intrinsics are the description's
/// and the camera's, and the cloud (world frame) holds the table's top at 0.10 m.
#[test]
fn snapshot_writes_images_and_a_cloud_in_the_world_frame() {
    let dir = std::env::temp_dir().join(format!("ferrobot-snapshot-{}", std::process::id()));
    let out = dir.to_str().unwrap();
    let (ok, v) = run(&[
        "snapshot",
        "locobot",
        "--scene",
        "tabletop",
        "--tilt",
        "0.8",
        "--joints",
        "1.5",
        "0",
        "0",
        "0",
        "0",
        "--no-noise",
        "--out",
        out,
        "--json",
    ]);
    assert!(ok, "{v}");
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(640), Some(480))
    );
    assert_eq!(v["intrinsics"][0][0].as_f64(), Some(619.8997));
    assert_eq!(v["intrinsics"][2][2].as_f64(), Some(1.0));
    let p: Vec<f64> = (0..3)
        .map(|i| v["camera_position"][i].as_f64().unwrap())
        .collect();
    let q: Vec<f64> = (0..4)
        .map(|i| v["camera_quaternion"][i].as_f64().unwrap())
        .collect();
    assert!(p[2] > 0.4 && p[2] < 0.7, "camera height {}", p[2]);
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!((norm - 1.0).abs() < 1e-9);
    // The optical axis (z) points forward and 0.8 rad down.
    let rot = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        q[3], q[0], q[1], q[2],
    ));
    let z = rot * nalgebra::Vector3::z();
    assert!(((-z.z).asin() - 0.8).abs() < 0.01 && z.x > 0.0, "{z:?}");

    let rgb = ferrobot::perception::io::read_rgb_png(dir.join("rgb.png")).unwrap();
    let depth = ferrobot::perception::io::read_depth_png(dir.join("depth.png")).unwrap();
    assert_eq!(
        (rgb.width, rgb.height, depth.width, depth.height),
        (640, 480, 640, 480)
    );
    assert!(depth.valid_fraction() > 0.9, "{}", depth.valid_fraction());
    let cloud = ferrobot::perception::io::read_ply(dir.join("cloud.ply")).unwrap();
    // Points over the table (x 0.28-0.73 m, |y| < 0.4 m) lie on its top, z = 0.10 m, within
    // 2 mm, or above it on the objects; none below it (the table is opaque).
    let over: Vec<f64> = cloud
        .points
        .iter()
        .filter(|p| (0.30..0.71).contains(&p.x) && p.y.abs() < 0.38)
        .map(|p| p.z)
        .collect();
    let on_top = over.iter().filter(|z| (*z - 0.10).abs() < 2e-3).count();
    let lowest = over.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(
        on_top > 50_000 && on_top as f64 > 0.8 * over.len() as f64,
        "{on_top} of {}",
        over.len()
    );
    assert!(
        lowest > 0.098,
        "a point {lowest} m high under the table's top"
    );
    let side = ferrobot::perception::io::read_rgb_png(dir.join("snapshot.png")).unwrap();
    assert_eq!((side.width, side.height), (1280, 480));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A planned motion low over the tabletop, from the left of the objects to their right (a
/// benchmark problem whose path, planned without room, grazed the green cylinder and knocked it
/// over when executed): with the default padding the executed motion touches nothing in the
/// physics engine and ends at the goal; the picture is drawn, the gripper's path in red.
#[test]
fn arm_plan_executes_around_the_tabletop_without_contact_and_draws_it() {
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    let png = dir.join("motion.png");
    let goal = [0.6932, -0.0235, 0.6592, 1.3374, -0.4848];
    let goal_s: Vec<String> = goal.iter().map(|v| v.to_string()).collect();
    let mut args = vec![
        "arm-plan", "locobot", "--scene", "tabletop", "--from", "-0.0623", "0.8197", "-0.2944",
        "-0.1524", "1.3604", "--to",
    ];
    args.extend(goal_s.iter().map(String::as_str));
    args.extend(["--png", png.to_str().unwrap(), "--json"]);
    let (ok, v) = run(&args);
    assert!(ok, "{v}");
    assert!(v["scene_objects"].as_u64().unwrap() > 5, "{v}");
    assert_eq!(v["contacts"].as_u64(), Some(0), "{v}");
    // The default 1 cm, or half an end's gap: this start and goal are 1-2 cm from objects.
    let padding = v["padding_m"].as_f64().unwrap();
    assert!(padding > 0.005 && padding <= 0.01, "{v}");
    // The servos' arrival tolerance.
    assert!(v["final_error_rad"].as_f64().unwrap() < 0.02, "{v}");
    let path = v["path"].as_array().unwrap();
    assert!(path.len() >= 3, "the straight line is not free: {v}");
    for (got, want) in path.last().unwrap().as_array().unwrap().iter().zip(goal) {
        assert!((got.as_f64().unwrap() - want).abs() < 1e-9, "{v}");
    }
    assert!(v["duration_s"].as_f64().unwrap() > 0.5, "{v}");
    let img = ferrobot::perception::io::read_rgb_png(&png).unwrap();
    assert_eq!((img.width, img.height), (800, 600));
    let red = img
        .data
        .chunks_exact(3)
        .filter(|p| p[0] == 214 && p[1] == 39 && p[2] == 40)
        .count();
    assert!(red > 300, "{red} px of the gripper's path");
}

/// Any robot in any scene: Sawyer's seven joints from high above its pedestal down beside the
/// shelf (problem 6 of the shelf set), the whole 1 cm kept, no contact when executed.
#[test]
fn arm_plan_moves_sawyer_beside_the_shelf_keeping_its_padding() {
    let (ok, v) = run(&[
        "arm-plan", "sawyer", "--scene", "shelf", "--from", "1.7998", "-1.4818", "-0.4067",
        "-0.6779", "-2.1953", "1.1502", "3.0342", "--to", "0.8502", "0.1147", "-2.2374", "0.2033",
        "-1.636", "0.1789", "2.8987", "--json",
    ]);
    assert!(ok, "{v}");
    assert_eq!(v["joints"].as_array().unwrap().len(), 7, "{v}");
    assert_eq!(v["contacts"].as_u64(), Some(0), "{v}");
    assert_eq!(v["padding_m"].as_f64(), Some(0.01), "{v}");
    assert!(v["path"].as_array().unwrap().len() >= 3, "{v}");
    assert!(v["final_error_rad"].as_f64().unwrap() < 0.02, "{v}");
}

#[test]
fn cluster_prints_the_librarys_labels_in_file_order() {
    use ferrobot::perception::io::{read_ply, write_ply};
    use ferrobot::perception::synthetic::blobs;
    use ferrobot::perception::{Clusterer, Dbscan, PointCloud};
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    // Blobs with noise, binary PLY: the labels are the library's, point for point.
    let centres = [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.2, 0.05]];
    let pts = blobs(4, &centres, 300, 0.01, 150, [-0.1; 3], [0.2, 0.3, 0.1]);
    let path = dir.join("blobs.ply");
    let cloud = PointCloud {
        colours: vec![[0, 0, 0]; pts.len()],
        points: pts,
    };
    write_ply(&path, &cloud).expect("ply");
    let back = read_ply(&path).expect("read");
    let want = Dbscan::new(0.02, 15)
        .unwrap()
        .cluster(&back.points)
        .unwrap();
    let p = path.to_str().expect("utf-8");
    let (ok, v) = run(&[
        "cluster",
        "--in",
        p,
        "--eps",
        "0.02",
        "--min-samples",
        "15",
        "--json",
    ]);
    assert!(ok, "{v}");
    let labels: Vec<i64> = v["labels"]
        .as_array()
        .expect("labels")
        .iter()
        .map(|l| l.as_i64().expect("integer"))
        .collect();
    assert_eq!(labels.len(), back.len());
    assert!(labels
        .iter()
        .zip(&want.labels)
        .all(|(&a, &b)| a == b as i64));
    assert!(want.clusters == 3 && want.noise() > 50, "{}", want.clusters);
    assert_eq!(v.as_object().map(|o| o.len()), Some(1), "only labels");
    // The summary names the clusters and the noise.
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(["cluster", "--in", p, "--eps", "0.02", "--min-samples", "15"])
        .output()
        .expect("runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("3 clusters") && text.contains(&format!("{} noise", want.noise())),
        "{text}"
    );
    // An ASCII PLY by hand: three points 5 cm apart and one far away.
    let ascii = dir.join("line.ply");
    std::fs::write(
        &ascii,
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nend_header\n0 0 0\n0.05 0 0\n5 5 5\n0.1 0 0\n",
    )
    .expect("ply");
    let (ok, v) = run(&[
        "cluster",
        "--in",
        ascii.to_str().expect("utf-8"),
        "--eps",
        "0.06",
        "--min-samples",
        "2",
        "--json",
    ]);
    assert!(ok);
    assert_eq!(v["labels"], serde_json::json!([0, 0, -1, 0]));
}
