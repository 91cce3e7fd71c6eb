//! `ferrobot slam` and `ferrobot record-rgbd` end to end on the simulated LoCoBot in the
//! apartment (the `short` route: half a metre and a quarter turn, about 9 s of frames): the
//! files, the error against the simulator's ground truth, the saved map localised in by a
//! second drive, a recorded sequence read back by `slam --dataset`, and each refusal's exit
//! code.

use std::path::{Path, PathBuf};
use std::process::Command;

use ferrobot::nav::MapImage;
use ferrobot::slam::{ate, parse_tum, Dataset};

/// Exit code and standard output (JSON) of `ferrobot ARGS`.
fn run(args: &[&str]) -> (i32, serde_json::Value) {
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(args)
        .output()
        .expect("runs");
    let v = serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
    (out.status.code().unwrap_or(-1), v)
}

/// A path `name` that does not exist yet, in a temporary directory removed with the guard.
fn dir(name: &str) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().expect("temporary directory");
    let d = tmp.path().join(name);
    (tmp, d)
}

fn tum(p: &Path) -> Vec<ferrobot::slam::Stamped> {
    parse_tum(&std::fs::read_to_string(p).expect("read"), p).expect("TUM")
}

#[test]
fn a_drive_is_mapped_within_a_centimetre_and_its_files_agree_with_the_json() {
    let (_tmp, out) = dir("drive");
    let o = out.to_str().expect("utf-8");
    let (code, v) = run(&[
        "slam", "locobot", "--route", "short", "--seed", "3", "--out", o, "--json",
    ]);
    assert_eq!(code, 0, "{v}");
    let frames = v["frames"].as_u64().expect("frames") as usize;
    // 30 frames a second over the drive and the second at rest.
    assert!(frames > 200, "{v}");
    let est = tum(&out.join("estimate.tum"));
    let gt = tum(&out.join("ground_truth.tum"));
    assert_eq!((est.len(), gt.len()), (frames, frames));
    // The printed ATE is the files' (recomputed here), and within the 1 cm.
    let a = ate(&est, &gt, 0.001).expect("ate");
    let printed = v["ate_rmse_m"].as_f64().expect("ate");
    assert!((a.rmse - printed).abs() < 1e-6, "{} vs {printed}", a.rmse);
    assert!(a.rmse < 0.01, "ATE {} m", a.rmse);
    // Without a prior or a correction the camera alone would not know where the robot
    // started: the map's frame is the world's, so the first pose is the true start.
    let d0 = est[0].pose.inverse() * gt[0].pose;
    assert!(d0.translation.vector.norm() < 1e-9);
    assert!(v["ms_per_frame"]["mean"].as_f64().expect("ms") > 0.0);
    // The map is map_server's and holds the wall ahead (x = 0 seen from x = -3).
    let map = MapImage::load(&out.join("map.yaml")).expect("map");
    let grid = map.to_grid(false).expect("grid");
    assert!(grid.occupied.iter().any(|&o| o), "no obstacle mapped");
    let iou = v["occupancy_iou"].as_f64().expect("iou");
    assert!(iou > 0.0 && iou <= 1.0, "{v}");
    let cloud = ferrobot::perception::io::read_ply(out.join("cloud.ply")).expect("ply");
    assert!(cloud.len() > 1000, "{} points", cloud.len());
    // Every cloud point lies in the apartment (8.4 m x 6.4 m, 2.4 m high walls) within the
    // depth noise.
    for p in &cloud.points {
        assert!(
            p.x.abs() < 4.3 && p.y.abs() < 3.3 && p.z > -0.1 && p.z < 2.6,
            "{p:?}"
        );
    }
    assert!(out.join("trajectory.png").is_file());
    // The saved map reloads, and a second drive (another seed) finds itself in it within
    // 10 s, SLAM not told where it starts.
    let (_tmp_again, again) = dir("again");
    let map = out.join("map.slam");
    let (code, v) = run(&[
        "slam",
        "locobot",
        "--route",
        "short",
        "--seed",
        "4",
        "--map",
        map.to_str().expect("utf-8"),
        "--out",
        again.to_str().expect("utf-8"),
        "--json",
    ]);
    assert_eq!(code, 0, "{v}");
    let after = v["localised_after_s"].as_f64().expect("localised");
    assert!((0.0..10.0).contains(&after), "{v}");
    assert!(v["ate_rmse_m"].as_f64().expect("ate") < 0.01, "{v}");
    // A file that is not a map is refused as bad input.
    let (code, v) = run(&[
        "slam",
        "locobot",
        "--route",
        "short",
        "--map",
        out.join("map.yaml").to_str().expect("utf-8"),
        "--out",
        again.to_str().expect("utf-8"),
        "--json",
    ]);
    assert_eq!(code, 2, "{v}");
}

#[test]
fn a_recorded_sequence_reads_back_and_slam_tracks_it_without_odometry() {
    let (_tmp, out) = dir("record");
    let o = out.to_str().expect("utf-8");
    let (code, v) = run(&["record-rgbd", "locobot", "--route", "short", "--out", o]);
    assert_eq!(code, 0, "{v}");
    let ds = Dataset::open(&out).expect("dataset");
    assert!(ds.frames.len() > 200);
    assert_eq!(ds.depth_factor, 5000.0);
    let gt = ds.ground_truth.clone().expect("ground truth");
    assert_eq!(gt.len(), ds.frames.len());
    // The depth survives the 1/5000 m steps.
    let (_, _, depth) = ds.load(0).expect("frame");
    assert!(depth.data.iter().filter(|&&z| z > 0.0).count() > 100_000);
    // Recording again into the same folder is refused.
    let (code, _) = run(&["record-rgbd", "locobot", "--route", "short", "--out", o]);
    assert_eq!(code, 2);
    let (_tmp_est, est_dir) = dir("record-est");
    let (code, v) = run(&[
        "slam",
        "--dataset",
        o,
        "--out",
        est_dir.to_str().expect("utf-8"),
        "--json",
    ]);
    assert_eq!(code, 0, "{v}");
    assert_eq!(v["frames"].as_u64(), Some(ds.frames.len() as u64));
    // Six motions, no odometry: within 2 cm over this drive (camera poses).
    let a = v["ate_rmse_m"].as_f64().expect("ate");
    assert!(a < 0.02, "{v}");
    let est = tum(&est_dir.join("estimate.tum"));
    assert!((ate(&est, &gt, 0.02).expect("ate").rmse - a).abs() < 1e-6);
    assert!(v.get("occupancy_iou").is_none(), "{v}");
}

#[test]
fn bad_requests_are_refused_with_exit_code_2() {
    let (_tmp, out) = dir("bad");
    let o = out.to_str().expect("utf-8");
    // A route the scene does not have.
    let (code, v) = run(&[
        "slam", "locobot", "--route", "nowhere", "--out", o, "--json",
    ]);
    assert_eq!(code, 2, "{v}");
    assert!(v["error"].as_str().expect("error").contains("loop"), "{v}");
    // A robot and a dataset at once; neither.
    let (code, _) = run(&["slam", "locobot", "--dataset", o]);
    assert_eq!(code, 2);
    let (code, _) = run(&["slam", "--json"]);
    assert_eq!(code, 2);
    // A dataset folder that is not one, and one whose camera.yaml is malformed.
    let (code, v) = run(&["slam", "--dataset", o, "--json"]);
    assert_eq!(code, 2, "{v}");
    std::fs::create_dir_all(&out).expect("dir");
    for bad in [
        "fx: 500\nfy: 500\ncx: 320\ncy: 240\nwidth: 640\nheight: 480\n",
        "fx: .nan\nfy: 500\ncx: 320\ncy: 240\nwidth: 640\nheight: 480\ndepth_factor: 5000\n",
        "fx: 500\nfy: 500\ncx: 320\ncy: 240\nwidth: -640\nheight: 480\ndepth_factor: 5000\n",
        "fx: 500\nfy: 500\ncx: 320\ncy: 240\nwidth: 640\nheight: 480\ndepth_factor: 0\n",
        "[1, 2",
    ] {
        std::fs::write(out.join("camera.yaml"), bad).expect("write");
        let (code, v) = run(&["slam", "--dataset", o, "--json"]);
        assert_eq!(code, 2, "{bad:?}: {v}");
    }
    // A list naming a file outside the folder.
    std::fs::write(
        out.join("camera.yaml"),
        "fx: 500\nfy: 500\ncx: 320\ncy: 240\nwidth: 640\nheight: 480\ndepth_factor: 5000\n",
    )
    .expect("write");
    std::fs::write(out.join("rgb.txt"), "0.0 ../../etc/passwd\n").expect("write");
    std::fs::write(out.join("depth.txt"), "0.0 d.png\n").expect("write");
    let (code, v) = run(&["slam", "--dataset", o, "--json"]);
    assert_eq!(code, 2, "{v}");
    assert!(
        v["error"].as_str().expect("error").contains("leaves"),
        "{v}"
    );
}

/// Two goals through the apartment, steered by SLAM: both reached, no bumper hit, paths
/// within the 1.15 of the shortest. Bad arguments are refused.
#[test]
fn bench_nav_reaches_its_goals_and_refuses_bad_arguments() {
    let (code, v) = run(&[
        "bench", "nav", "locobot", "--goals", "2", "--seed", "1", "--json",
    ]);
    assert_eq!(code, 0, "{v}");
    assert_eq!(v["goals"].as_u64(), Some(2));
    assert_eq!(v["success_rate"].as_f64(), Some(1.0), "{v}");
    assert_eq!(v["bumper_hits"].as_u64(), Some(0), "{v}");
    // No shorter than the shortest (less the 0.2 m tolerance over at least 1 m), no longer
    // than the bound.
    let ratio = v["path_length_ratio"]["median"].as_f64().expect("ratio");
    assert!((0.75..=1.15).contains(&ratio), "{v}");
    assert!(v["time_s"]["median"].as_f64().expect("time") > 0.0, "{v}");
    let (code, _) = run(&["bench", "nav", "locobot", "--goals", "0", "--json"]);
    assert_eq!(code, 2);
    let (code, _) = run(&["bench", "nav", "locobot", "--scene", "nowhere", "--json"]);
    assert_eq!(code, 2);
    let (code, _) = run(&["bench", "nav", "locobot", "--localise", "gps", "--json"]);
    assert_eq!(code, 2);
}
