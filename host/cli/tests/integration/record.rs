//! `ferrobot record`: a recording cut by `kill -9` reads back, with the MCAP library's own
//! reader, to within 1 s of the robot's time at the kill; a whole one ends with its summary.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use serde_json::Value;

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("cli-record-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// host/record/peer/read_truncated.py's report of `file`.
fn read_back(py: &Path, file: &Path) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../record/peer/read_truncated.py");
    let out = Command::new(py).arg(script).arg(file).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn a_recording_killed_mid_way_reads_back_to_within_a_second_of_the_kill() {
    let Some(py) =
        ferrobot_peers::for_test("mcap, rosbags.typesys", "scripts/python-env.sh record")
    else {
        return;
    };
    let dir = scratch("kill");
    let file = dir.join("killed.mcap");
    // The simulator paced at real time, as a robot is: the recorder keeps up with the robot
    // as it would on one, and the kill lands at an instant of the robot's time.
    let mut child = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(["record", "locobot", "--realtime", "--seconds", "60"])
        .args(["--progress", "0.1", "-o"])
        .arg(&file)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut at_kill = 0.0;
    for line in lines.by_ref() {
        at_kill = line.unwrap().trim().parse::<f64>().unwrap();
        if at_kill >= 3.0 {
            break;
        }
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let r = read_back(&py, &file);
    let last = r["last_ns"].as_u64().unwrap() as f64 * 1e-9;
    println!("killed at {at_kill:.3} s of the robot's time; read back to {last:.3} s: {r}");
    assert_ne!(r["ended"], "footer", "the recording was not cut: {r}");
    assert!(
        last >= at_kill - 1.0,
        "read back to {last:.3} s, killed at {at_kill:.3} s"
    );
    for topic in ["/joint_states", "/tf", "/odom", "/camera/color/image_raw"] {
        assert!(r["topics"][topic].as_u64().unwrap_or(0) > 0, "{topic}: {r}");
    }
    // A whole recording, for contrast: it ends with its footer and nothing was dropped.
    let whole = dir.join("whole.mcap");
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(["record", "locobot", "--seconds", "2", "--json", "-o"])
        .arg(&whole)
        .output()
        .unwrap();
    assert!(out.status.success());
    let s: Value = serde_json::from_slice(&out.stdout).unwrap();
    // 60 frames at 30 Hz, or 61 where the first frame's instant lay up to half a period
    // before the start (the camera's frame clock takes it late rather than skipping it).
    assert_eq!(s["frames_dropped"].as_u64(), Some(0), "{s}");
    assert!(matches!(s["frames"].as_u64(), Some(60..=61)), "{s}");
    let r = read_back(&py, &whole);
    assert_eq!(r["ended"], "footer");
    assert_eq!(r["messages"], s["messages"]);
}
