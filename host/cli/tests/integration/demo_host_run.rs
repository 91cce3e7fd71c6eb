//! The main job's demo on the host-run firmware of both stock LoCoBots with their devices
//! emulated (`ferrobot demo --backend direct-emulated`): the same program as on the simulator,
//! its figures read back from what it prints.

use std::process::Command;

/// `ferrobot demo --robot ROBOT --backend direct-emulated`'s output, asserting it succeeded.
fn demo(robot: &str) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(["demo", "--robot", robot, "--backend", "direct-emulated"])
        .output()
        .expect("ferrobot runs");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// The numbers in the bracketed list after `key` on the line starting with `line`.
fn numbers(text: &str, line: &str, key: &str) -> Vec<f64> {
    let l = text
        .lines()
        .find(|l| l.starts_with(line))
        .unwrap_or_else(|| panic!("no {line:?} line in {text}"));
    let rest = &l[l.find(key).unwrap_or_else(|| panic!("{key:?} in {l}")) + key.len()..];
    let list = &rest[rest.find('[').expect("[") + 1..rest.find(']').expect("]")];
    list.split(',')
        .map(|v| v.trim().parse().expect("a number"))
        .collect()
}

fn check(robot: &str) {
    let text = demo(robot);
    assert!(
        text.contains("host-run firmware on emulated devices"),
        "{text}"
    );
    let joints = numbers(&text, "arm     joints", "joints");
    for (q, t) in joints.iter().zip([0.4, 0.3, -0.5, 0.6, -0.3]) {
        assert!((q - t).abs() < 0.02, "{joints:?}");
    }
    let odom = numbers(&text, "base    go_to_absolute", "odometry");
    assert!(
        (odom[0] - 1.0).abs() < 0.05 && (odom[1] - 1.0).abs() < 0.05,
        "{odom:?}"
    );
    assert!(text.contains("gripper close -> Closed"), "{text}");
}

#[test]
fn the_demo_runs_on_the_host_run_firmware_of_the_locobot() {
    check("locobot");
}

#[test]
fn the_demo_runs_on_the_host_run_firmware_of_the_locobot_lite() {
    check("locobot_lite");
}
