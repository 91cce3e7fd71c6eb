//! The API on the Serial backend, against the firmware core running as a separate Linux
//! process (`ferrobot sim-firmware`, real time, its plants in-process) behind a real PTY.

use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::{Duration, Instant};

use ferrobot::{Backend, Error, GripperState, Robot};
use ferrobot_protocol::*;

/// The firmware process; killed when the test ends, pass or fail.
pub(crate) struct Firmware {
    child: Child,
    stdin: Option<ChildStdin>,
    pub(crate) link: PathBuf,
    /// The link's directory (one per tag: a firmware started again with the same tag is
    /// behind the same path), removed after the process has ended.
    dir: PathBuf,
}

impl Drop for Firmware {
    fn drop(&mut self) {
        drop(self.stdin.take());
        let _ = self.child.kill();
        let _ = self.child.wait();
        // The link and the camera's socket beside it, with their directory.
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

impl Firmware {
    pub(crate) fn start(robot: &str, tag: &str) -> Firmware {
        Self::start_with(robot, tag, &[])
    }

    fn start_with(robot: &str, tag: &str, extra: &[&str]) -> Firmware {
        let dir =
            std::env::temp_dir().join(format!("ferrobot-serial-{}-{tag}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let link = dir.join("host");
        let mut child = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
            .args(["sim-firmware", robot, "--link"])
            .arg(&link)
            .args(extra)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("firmware process starts");
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("first line");
        let v: serde_json::Value = serde_json::from_str(&line).expect("JSON");
        assert_eq!(v["host"].as_str(), Some(link.to_str().expect("utf-8")));
        let stdin = child.stdin.take();
        Firmware {
            child,
            stdin,
            link,
            dir,
        }
    }

    /// Send a control line (`ferrobot sim-firmware`'s standard input).
    pub(crate) fn say(&mut self, what: &str) {
        let s = self.stdin.as_mut().expect("stdin");
        writeln!(s, "{what}").expect("write");
        s.flush().expect("flush");
    }
}

pub(crate) fn connect(fw: &Firmware) -> Robot {
    Robot::builder("locobot")
        .backend(Backend::Serial {
            path: fw.link.clone(),
        })
        .build()
        .expect("connects over serial")
}

#[test]
fn the_arm_and_base_scenario_passes_over_serial() {
    let fw = Firmware::start("locobot", "scenario");
    let bot = connect(&fw);
    let target = [0.4, 0.3, -0.5, 0.6, -0.3];
    bot.arm()
        .expect("arm")
        .set_joint_positions(&target)
        .expect("arm moves");
    let q = bot.arm().expect("arm").get_joint_angles().expect("q");
    assert!(
        q.iter().zip(target).all(|(a, b)| (a - b).abs() < 0.01),
        "{q:?}"
    );
    let pose = bot.arm().expect("arm").get_ee_pose().expect("pose");
    bot.arm().expect("arm").go_home().expect("home");
    assert!(pose.position[0] > 0.1);
    assert_eq!(
        bot.gripper().expect("gripper").close().expect("close"),
        GripperState::Closed
    );
    bot.gripper().expect("gripper").open().expect("open");
    bot.base().expect("base").reset_odometry().expect("reset");
    bot.base()
        .expect("base")
        .go_to_relative([0.5, 0.0, 0.0])
        .expect("base moves");
    let s = bot.base().expect("base").get_state().expect("odometry");
    assert!(
        (s[0] - 0.5).abs() < 0.02 && s[1].abs() < 0.02 && s[2].abs() < 2f64.to_radians(),
        "{s:?}"
    );
    // Bad input is refused the same way as on the simulator.
    assert!(matches!(
        bot.arm()
            .expect("arm")
            .set_joint_positions(&[0.0, 0.0, 2.0, 0.0, 0.0]),
        Err(Error::OutOfLimits { .. })
    ));
}

/// Over a real serial port, one robot driven from three threads at once: the arm moves in
/// one, the head in another, and a monitor reads state in a third. Every call gets its own
/// reply (none is lost to another thread), and nothing deadlocks.
#[test]
fn one_robot_is_driven_from_three_threads_over_serial() {
    let fw = Firmware::start("locobot", "threads");
    let bot = connect(&fw);
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let monitor = {
        let (bot, done) = (bot.clone(), done.clone());
        std::thread::spawn(move || {
            let (mut reads, mut frames) = (0u32, 0u32);
            while !done.load(std::sync::atomic::Ordering::SeqCst) {
                let q = bot.arm().expect("arm").get_joint_angles().expect("q");
                let d = bot
                    .diagnostics()
                    .expect("diagnostics (a request and its reply)");
                // The firmware's count of host frames only grows: each reply is a new one.
                assert!(q.iter().all(|v| v.is_finite()) && d.host_frames > frames);
                frames = d.host_frames;
                reads += 1;
            }
            reads
        })
    };
    let head = {
        let bot = bot.clone();
        std::thread::spawn(move || {
            bot.head()
                .expect("camera")
                .set_pan_tilt(0.4, 0.2)
                .expect("head moves")
        })
    };
    let target = [0.3, 0.2, -0.3, 0.4, 0.0];
    bot.arm()
        .expect("arm")
        .set_joint_positions(&target)
        .expect("arm moves");
    head.join().expect("head thread");
    done.store(true, std::sync::atomic::Ordering::SeqCst);
    let reads = monitor.join().expect("monitor thread");
    assert!(reads >= 3, "the monitor got {reads} replies in");
    let q = bot.arm().expect("arm").get_joint_angles().expect("q");
    assert!(
        q.iter().zip(target).all(|(a, b)| (a - b).abs() < 0.01),
        "{q:?}"
    );
    let pt = bot.head().expect("camera").get_state().expect("pan/tilt");
    assert!(
        (pt[0] - 0.4).abs() < 0.01 && (pt[1] - 0.2).abs() < 0.01,
        "{pt:?}"
    );
}

/// A LoCoBot configuration refuses firmware that runs the LoCoBot-Lite profile: the Hello's
/// robot and base must match the configuration.
#[test]
fn a_configuration_refuses_firmware_of_another_robot() {
    let fw = Firmware::start("locobot_lite", "wrong-robot");
    let e = Robot::builder("locobot")
        .backend(Backend::Serial {
            path: fw.link.clone(),
        })
        .build()
        .expect_err("refused");
    match &e {
        Error::WrongRobot {
            config, firmware, ..
        } => assert_eq!(
            (config.as_str(), firmware.as_str()),
            ("locobot", "locobot_lite")
        ),
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("Create2"), "{e}");
}

#[test]
fn a_protocol_mismatch_is_refused_at_the_handshake() {
    let fw = Firmware::start("locobot", "mismatch");
    let mut port = serialport::new(fw.link.to_string_lossy(), 1_000_000)
        .timeout(Duration::from_millis(20))
        .open()
        .expect("port");
    let mut buf = [0u8; MAX_WIRE];
    let n = encode_frame(
        0,
        &HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION + 7,
            schema_hash: SCHEMA_HASH,
        },
        &mut buf,
    )
    .expect("fits");
    port.write_all(&buf[..n]).expect("write");
    let mut dec = FrameDecoder::new();
    let deadline = Instant::now() + Duration::from_secs(3);
    let info = 'outer: loop {
        assert!(Instant::now() < deadline, "no answer");
        let mut rx = [0u8; 256];
        if let Ok(k) = std::io::Read::read(&mut port, &mut rx) {
            for &b in &rx[..k] {
                if let Some(Ok(Frame {
                    msg: DeviceMsg::Hello(info),
                    ..
                })) = dec.push::<DeviceMsg>(b)
                {
                    break 'outer info;
                }
            }
        }
    };
    assert!(!info.accepted);
    assert_eq!(info.protocol_version, PROTOCOL_VERSION);
}

/// The same program in the same scene gets the same images from the simulator backend and over
/// a serial port from `ferrobot sim-firmware`'s world (its camera on the socket beside the
/// port): same size, intrinsics and content (exact depth: at least 99.5 % of the pixels within
/// 5 mm and a pixel of each other; the two runs' joints settle to within an encoder tick).
#[test]
fn the_camera_sees_the_same_scene_over_serial() {
    let fw = Firmware::start_with("locobot", "camera", &["--scene", "tabletop", "--no-noise"]);
    let serial = Robot::builder("locobot")
        .backend(Backend::Serial {
            path: fw.link.clone(),
        })
        .build()
        .expect("connects over serial");
    let sim = Robot::builder("locobot")
        .scene("tabletop")
        .depth_noise(false)
        .build()
        .expect("simulator");
    let mut frames = Vec::new();
    for bot in [&sim, &serial] {
        bot.arm()
            .expect("arm")
            .set_joint_positions(&[1.5, 0.0, 0.0, 0.0, 0.0])
            .expect("arm aside");
        bot.head()
            .expect("head")
            .set_pan_tilt(0.0, 0.8)
            .expect("head");
        bot.wait(0.5).expect("settles");
        frames.push(bot.camera().expect("camera").get_frame().expect("frame"));
    }
    let (a, b) = (&frames[0], &frames[1]);
    assert_eq!(a.intrinsics, b.intrinsics);
    assert_eq!((b.rgb.width, b.rgb.height), (640, 480));
    // The two runs' joints may settle an encoder tick (1.5 mrad) apart, which moves a
    // silhouette by a pixel: every depth must be seen within 5 mm at most a pixel away.
    let share = a.depth.agreement(&b.depth, 5e-3, 1);
    println!(
        "{:.3} % of the depths within 5 mm and a pixel",
        100.0 * share
    );
    assert!(
        share > 0.995,
        "{:.3} % of the depths within 5 mm and a pixel",
        100.0 * share
    );
    let angle = a.camera_pose.rotation.angle_to(&b.camera_pose.rotation);
    assert!(angle < 0.01, "camera poses differ by {angle} rad");
}
