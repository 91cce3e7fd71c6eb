//! `ferrobot bench arm` and `ferrobot bench push` on the simulator, small: the JSON's fields
//! and real tolerances (ISO 9283 figures by ground truth, tracking errors, the plots written;
//! one push judged by ground truth).

use crate::support;
use support::ferrobot;

/// Three cycles of the five poses: every pose within 1 mm of its command (accuracy) and
/// repeated within 2 mm, the tracking error of every joint below 0.1 rad at most and 0.05 rad
/// RMS, one plot per joint.
#[test]
fn bench_arm_measures_accuracy_repeatability_and_tracking() {
    let dir = std::env::temp_dir().join(format!("ferrobot-bench-arm-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.to_str().unwrap();
    let (ok, v, text) = ferrobot(&[
        "bench", "arm", "locobot", "--cycles", "3", "--out", out, "--json",
    ]);
    assert!(ok, "{text}");
    assert_eq!(v["cycles"], 3);
    let poses = v["poses"].as_array().expect("poses");
    assert_eq!(poses.len(), 5, "{text}");
    for p in poses {
        let ap = p["accuracy_mm"].as_f64().unwrap();
        let rp = p["repeatability_mm"].as_f64().unwrap();
        assert!(ap < 1.0 && rp < 2.0, "{p}");
    }
    let joints = v["tracking"].as_array().expect("tracking");
    assert_eq!(joints.len(), 5);
    for j in joints {
        let (max, rms) = (
            j["max_rad"].as_f64().unwrap(),
            j["rms_rad"].as_f64().unwrap(),
        );
        assert!(max < 0.1 && rms < 0.05 && rms <= max, "{j}");
        let name = j["name"].as_str().unwrap();
        assert!(dir.join(format!("tracking_{name}.png")).is_file(), "{name}");
    }
    assert!(v["tracking_duration_s"].as_f64().unwrap() > 1.0, "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// One trial of the push benchmark (seed 1): the JSON's fields, and the trial a success by
/// the simulator's ground truth.
#[test]
fn bench_push_runs_one_trial_judged_by_ground_truth() {
    let (ok, v, text) = ferrobot(&[
        "bench", "push", "locobot", "--trials", "1", "--seed", "1", "--json",
    ]);
    assert!(ok, "{text}");
    assert_eq!(v["trials"], 1);
    assert_eq!(v["pushes"], 1, "{text}");
    let t = &v["per_trial"][0];
    assert!(t["target_moved_m"].as_f64().unwrap() >= 0.05, "{t}");
    assert!(t["others_max_moved_m"].as_f64().unwrap() < 0.01, "{t}");
    assert_eq!(t["side"], "near", "{t}");
    assert_eq!(v["success_rate"], 1.0, "{text}");
    assert!(v["time_s"]["median"].as_f64().unwrap() > 1.0);
}
