//! `ferrobot hardware check` on an emulated LoCoBot: the plants at the stock robot's rates
//! behind pseudo-terminals, on the virtual-time link the check keeps time on, and each fault
//! a user meets named in the table, as the JSON report's typed problem: a servo that does not
//! answer, a servo of another model, servos at another bit rate, a device this user may not
//! open, no base.

use std::process::{Command, Output};

use ferrobot_sim::board::{BoardOptions, BoardServer};
use serde_json::Value;

/// The plants of the LoCoBot as its `[direct]` section describes them (1 Mbit/s).
fn plants() -> BoardServer {
    let cfg = ferrobot::profile::bundled("locobot").expect("locobot");
    let direct = cfg
        .direct_config()
        .expect("the LoCoBot has a [direct] section");
    let desc = ferrobot_sim::robots::from_description(&direct);
    BoardServer::start_robot(
        &desc,
        BoardOptions::default(),
        &ferrobot_sim::scene::Scene::empty(),
    )
    .expect("the plants")
}

/// `ferrobot hardware check locobot` on `server`'s devices, as `run_as` (a user name to drop
/// to, or `None`): its output and the JSON report.
fn check(server: &BoardServer, run_as: Option<&str>) -> (Output, Value) {
    check_as(server, run_as, true)
}

/// [`check`], with `--json` or the table.
fn check_as(server: &BoardServer, run_as: Option<&str>, json: bool) -> (Output, Value) {
    let wiring = server.wiring();
    let exe = env!("CARGO_BIN_EXE_ferrobot");
    let mut cmd = match run_as {
        Some(user) => {
            let mut c = Command::new("setpriv");
            c.args(["--reuid", user, "--regid", user, "--clear-groups", exe]);
            c
        }
        None => Command::new(exe),
    };
    cmd.args(["hardware", "check", "locobot", "--clock"])
        .arg(&server.board.clock)
        .arg("--servo")
        .arg(wiring.link(0).expect("a servo line"))
        .arg("--base")
        .arg(wiring.link(1).expect("a base line"));
    if json {
        cmd.arg("--json");
    }
    let out = cmd.output().expect("ferrobot runs");
    if !json {
        return (out, Value::Null);
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    let report = stdout
        .lines()
        .find_map(|l| {
            serde_json::from_str::<Value>(l)
                .ok()
                .filter(|v| v.get("rows").is_some())
        })
        .unwrap_or_else(|| panic!("no report in {stdout:?}; stderr {:?}", out.stderr));
    (out, report)
}

/// The typed problems of the report's faults.
fn faults(report: &Value) -> Vec<Value> {
    report["rows"]
        .as_array()
        .expect("rows")
        .iter()
        .filter(|r| r["severity"] == "Fault")
        .map(|r| r["problem"].clone())
        .collect()
}

#[test]
fn a_healthy_emulated_locobot_passes_with_a_row_per_servo_and_its_base() {
    let server = plants();
    let (out, report) = check(&server, None);
    assert!(out.status.success(), "{report:#}");
    let rows = report["rows"].as_array().expect("rows");
    // Two devices, nine servos (joint_2's twin included), the base.
    assert_eq!(rows.len(), 12, "{report:#}");
    let servo4 = rows
        .iter()
        .find(|r| {
            r["subject"]
                .as_str()
                .is_some_and(|s| s.starts_with("servo 4 "))
        })
        .expect("servo 4's row");
    let reading = servo4["reading"].as_str().expect("reading");
    assert!(
        reading.contains("model 1020") && reading.contains("12.0 V"),
        "{reading}"
    );
    assert!(
        rows.last().unwrap()["reading"]
            .as_str()
            .is_some_and(|r| r.contains("battery 16.0 V")),
        "{report:#}"
    );
    // The table a user reads (fresh plants: a conductor's clock serves one board).
    let (out, _) = check_as(&plants(), None, false);
    let table = String::from_utf8_lossy(&out.stdout);
    eprintln!("{table}");
    assert!(
        table.contains("servo 4 (joint_3)") && table.ends_with("passed: the robot may move\n"),
        "{table}"
    );
}

#[test]
fn a_servo_that_does_not_answer_is_named() {
    let server = plants();
    assert_eq!(server.command("silent 5 on")["ok"], true);
    let (out, report) = check(&server, None);
    assert!(!out.status.success());
    assert_eq!(faults(&report), [serde_json::json!({"ServoMissing": 5})]);
}

#[test]
fn a_servo_of_another_model_is_named() {
    let server = plants();
    server.with_hardware(|hw, _| {
        hw.chain.servo_mut(8).expect("servo 8").set_register(
            ferrobot_protocol::dxl::addr::MODEL_NUMBER,
            2,
            1200,
        )
    });
    let (_, report) = check(&server, None);
    assert_eq!(
        faults(&report),
        [serde_json::json!({"WrongModel": {"id": 8, "found": 1200, "expected": 1060}})]
    );
}

#[test]
fn servos_at_another_bit_rate_are_found_at_theirs() {
    let server = plants();
    server.rewire(|w| w.baud[0] = Some(57_600));
    let (_, report) = check(&server, None);
    assert_eq!(
        faults(&report),
        [serde_json::json!({"WrongBaud": {"found": 57600, "expected": 1000000}})]
    );
}

#[test]
fn no_base_is_named() {
    let server = plants();
    let base = server.wiring().link(1).expect("base").to_path_buf();
    server.rewire(|w| w.plugged[1] = false);
    // The server pulls the cable at its next pass: the link goes.
    let t = std::time::Instant::now();
    while base.exists() && t.elapsed().as_secs() < 5 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let (_, report) = check(&server, None);
    assert_eq!(
        faults(&report),
        [serde_json::json!({"NoBase": base.display().to_string()})]
    );
}

#[test]
fn a_device_without_permission_is_named() {
    use std::os::unix::fs::PermissionsExt;
    let server = plants();
    let wiring = server.wiring();
    let servo = std::fs::canonicalize(wiring.link(0).expect("servo")).expect("its PTY");
    // Root opens anything: the check runs as `nobody`, who may open the base's and the
    // clock's PTYs but not the servo bus's.
    let others = [
        std::fs::canonicalize(wiring.link(1).expect("base")).expect("its PTY"),
        std::fs::canonicalize(&server.board.clock).expect("the clock's PTY"),
    ];
    for p in &others {
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o666)).expect("chmod");
    }
    std::fs::set_permissions(&servo, std::fs::Permissions::from_mode(0o000)).expect("chmod");
    let root = nix_is_root();
    let (out, report) = check(&server, root.then_some("65534"));
    assert!(!out.status.success());
    let servo_link = wiring.link(0).unwrap().display().to_string();
    assert_eq!(
        faults(&report),
        [serde_json::json!({"Permission": servo_link})]
    );
}

/// Whether this process runs as root (owner of the files it makes).
fn nix_is_root() -> bool {
    use std::os::unix::fs::MetadataExt;
    let probe = std::env::temp_dir().join(format!("ferrobot-uid-{}", std::process::id()));
    let _ = std::fs::write(&probe, b"");
    let uid = std::fs::metadata(&probe).map(|m| m.uid()).unwrap_or(1);
    let _ = std::fs::remove_file(&probe);
    uid == 0
}

/// The shipped udev rules give every `[direct]` device of the bundled robots its name, by the
/// USB IDs the description gives: the check's hints and the rules cannot drift apart.
#[test]
fn the_udev_rules_name_every_direct_device_by_its_usb_ids() {
    let rules = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../scripts/udev/99-ferrobot.rules"),
    )
    .expect("the rules");
    let mut checked = 0;
    for robot in ["locobot", "locobot_lite"] {
        let cfg = ferrobot::profile::bundled(robot).expect("robot");
        let direct = cfg.direct.expect("a [direct] section");
        for dev in std::iter::once(&direct.servo).chain(direct.base.as_ref()) {
            let (v, p) = dev.usb_ids().expect("USB IDs");
            let name = dev.port.strip_prefix("/dev/").expect("a /dev path");
            let rule = rules
                .lines()
                .find(|l| l.contains(&format!("SYMLINK+=\"{name}\"")))
                .unwrap_or_else(|| panic!("no rule names /dev/{name}"));
            assert!(
                rule.contains(&format!("ATTRS{{idVendor}}==\"{v:04x}\""))
                    && rule.contains(&format!("ATTRS{{idProduct}}==\"{p:04x}\""))
                    && rule.contains("ATTR{device/latency_timer}=\"1\"")
                    && rule.contains("GROUP=\"dialout\""),
                "{rule}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 4);
}

/// `ferrobot drive` serves the host-run firmware of the emulated LoCoBot to another process's
/// program over the serial backend, after its check, until its standard input closes.
#[test]
fn ferrobot_drive_serves_the_host_run_firmware_to_a_program() {
    use std::io::BufRead;
    let server = plants();
    let wiring = server.wiring();
    let link = std::env::temp_dir().join(format!("ferrobot-drive-test-{}", std::process::id()));
    let mut child = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(["drive", "locobot", "--link"])
        .arg(&link)
        .arg("--clock")
        .arg(&server.board.clock)
        .arg("--servo")
        .arg(wiring.link(0).expect("servo"))
        .arg("--base")
        .arg(wiring.link(1).expect("base"))
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("ferrobot drive");
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("its line");
    let said: Value = serde_json::from_str(&line).expect("one JSON line");
    assert_eq!(
        said["check"]["rows"].as_array().map(Vec::len),
        Some(12),
        "{said}"
    );
    let bot = ferrobot::Robot::builder("locobot")
        .backend(ferrobot::Backend::Serial { path: link.clone() })
        .use_camera(false)
        .build()
        .expect("the program connects");
    let arm = bot.arm().expect("arm");
    arm.set_joint_positions(&[0.3, 0.0, 0.0, 0.0, 0.0])
        .expect("a motion");
    let q = server.with_hardware(|hw, _| hw.chain.arm_angles());
    assert!((q[0] - 0.3).abs() < 0.02, "{q:?}");
    drop(bot);
    drop(child.stdin.take());
    let status = child.wait().expect("it ends");
    assert!(status.success(), "{status}");
    assert!(!link.exists(), "the link is removed");
}
