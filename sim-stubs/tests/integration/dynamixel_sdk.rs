//! Dynamixel conformance: `ferrobot-sim serve --robot locobot`, driven over its PTY by ROBOTIS'
//! official Python SDK (PyPI `dynamixel-sdk`). The test command installs the SDK in a virtual
//! environment and names its interpreter in `FERROBOT_PYTHON`.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Kills the server when the test ends, pass or fail.
struct Server(Child);

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The SDK's Python: the test command's (`FERROBOT_PYTHON`), or the workspace's environment.
fn python() -> std::path::PathBuf {
    ferrobot_peers::for_test("dynamixel_sdk", "scripts/python-env.sh").expect(
        "the ROBOTIS Dynamixel SDK is needed: run `scripts/python-env.sh` (scripts/test.sh does)",
    )
}

#[test]
fn official_robotis_sdk_drives_the_simulated_locobot_chain() {
    let py = python();
    let mut child = Command::new(env!("CARGO_BIN_EXE_ferrobot-sim"))
        .args(["serve", "--robot", "locobot", "--seed", "3"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("ferrobot-sim starts");
    let stdout = child.stdout.take().expect("stdout");
    let server = Server(child);
    let mut line = String::new();
    BufReader::new(stdout)
        .read_line(&mut line)
        .expect("first line");
    let info: serde_json::Value = serde_json::from_str(&line).expect("first line is JSON");
    let bus = info["servo_bus"]
        .as_str()
        .expect("servo_bus path")
        .to_string();
    assert!(
        info["base"]
            .as_str()
            .is_some_and(|p| p.starts_with("/dev/")),
        "{info}"
    );

    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/conformance/dxl_sdk_conformance.py"
    );
    let mut sdk = Command::new(&py)
        .args([script, &bus])
        .stdout(Stdio::piped())
        .spawn()
        .expect("python runs");
    let deadline = Instant::now() + Duration::from_secs(60);
    while sdk.try_wait().expect("poll").is_none() {
        assert!(
            Instant::now() < deadline,
            "the SDK script did not finish in 60 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = sdk.wait_with_output().expect("output");
    assert!(out.status.success(), "SDK script failed");
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("SDK script prints JSON");
    drop(server);

    // 1. Every servo answers a ping with its model number.
    for id in 1..=9 {
        let p = &r["ping"][id.to_string()];
        assert_eq!(p["ok"], true, "ping {id}: {p}");
        let expected = if id <= 5 { 1020 } else { 1060 }; // XM430-W350, XL430-W250
        assert_eq!(p["model"], expected, "model of {id}");
    }
    // 2. Joint 1 powers up at its centre tick (0 rad), ±1 tick of quantisation.
    assert_eq!(r["present_position_1"]["ok"], true);
    let p1 = r["present_position_1"]["value"].as_i64().expect("value");
    assert!((p1 - 2048).abs() <= 1, "present position {p1}");
    // 3. The pan servo arrives within 10 ticks of its goal.
    let m = &r["move"];
    assert_eq!(m["writes_ok"], true, "{m}");
    let t = m["arrived_after_s"]
        .as_f64()
        .unwrap_or_else(|| panic!("pan servo never arrived: {m}"));
    assert!(t < 3.0);
    // 4. The sync read returns all nine servos, consistent with single reads (±5 ticks: the
    //    unpowered arm links may still be settling under gravity between the two reads).
    assert_eq!(r["sync_read"]["ok"], true, "{}", r["sync_read"]);
    let sync = r["sync_read"]["values"].as_object().expect("values");
    assert_eq!(sync.len(), 9, "{sync:?}");
    for id in [1, 7, 8, 9] {
        let a = sync[&id.to_string()].as_i64().expect("sync value");
        let b = r["single_reads"][id.to_string()]
            .as_i64()
            .expect("single value");
        assert!((a - b).abs() <= 5, "servo {id}: sync {a}, single {b}");
    }
    let gripper = sync["7"].as_i64().expect("gripper");
    assert!(
        (gripper - 2800).abs() <= 1,
        "gripper starts open at 2800, reads {gripper}"
    );
}
