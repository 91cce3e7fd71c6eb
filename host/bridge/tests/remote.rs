//! The remote backend: a LoCoBot served by one program (the simulator, paced to the wall
//! clock) and driven through the API by another, over zenoh on loopback. The arm, base and
//! camera work as on the robot's own link, errors arrive typed, and a client killed mid-motion
//! has the robot stopped by the server's watchdog.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ferrobot::{Backend, Error, Robot};
use ferrobot_bridge::remote::{self, wire::WATCHDOG};
use ferrobot_bridge::{access, Access, ServeOptions, Server};

/// A served LoCoBot whose time passes on a thread of its own, paced to the wall clock.
struct Served {
    robot: Robot,
    server: Option<Server>,
    endpoint: String,
    stop: Arc<AtomicBool>,
    clock: Option<std::thread::JoinHandle<()>>,
    _session: zenoh::Session,
}

impl Served {
    fn start(namespace: &str) -> Served {
        let robot = Robot::builder("locobot")
            .backend(Backend::Sim {
                seed: 1,
                realtime: true,
            })
            .build()
            .expect("robot");
        let endpoint = format!("tcp/127.0.0.1:{}", ferrobot_peers::free_port());
        let session = access::open(&Access::listen(&endpoint)).expect("session");
        let opts = ServeOptions {
            namespace: namespace.into(),
            ..ServeOptions::default()
        };
        let server = Server::start(&robot, &session, opts).expect("served");
        let stop = Arc::new(AtomicBool::new(false));
        let (r, s) = (robot.clone(), stop.clone());
        let clock = std::thread::spawn(move || {
            while !s.load(Ordering::SeqCst) {
                let _ = r.wait(0.01);
            }
        });
        Served {
            robot,
            server: Some(server),
            endpoint,
            stop,
            clock: Some(clock),
            _session: session,
        }
    }

    fn stats(&self) -> ferrobot_bridge::ServeStats {
        self.server.as_ref().expect("server").stats()
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(c) = self.clock.take() {
            let _ = c.join();
        }
        self.server.take();
    }
}

fn client(endpoint: &str, namespace: &str) -> Robot {
    remote::connect(
        "locobot",
        &Access::connect(endpoint),
        namespace,
        Duration::from_secs(10),
    )
    .expect("connected")
    .build()
    .expect("built")
}

#[test]
fn a_remote_program_moves_the_arm_and_base_and_sees_through_the_camera() {
    let served = Served::start("/locobot");
    let bot = client(&served.endpoint, "/locobot");
    let arm = bot.arm().expect("arm");
    let target = [0.3, -0.2, 0.4, 0.2, -0.1];
    arm.set_joint_positions(&target).expect("the arm moves");
    // The served robot's own joints (and its simulator's truth) are where the client sent them.
    let truth = served.robot.truth().expect("truth");
    let mine = arm.get_joint_angles().expect("angles");
    let theirs = served
        .robot
        .arm()
        .expect("arm")
        .get_joint_angles()
        .expect("angles");
    for j in 0..5 {
        assert!((mine[j] - target[j]).abs() < 0.02, "{mine:?}");
        assert!(
            (theirs[j] - mine[j]).abs() < 0.01,
            "{theirs:?} against {mine:?}"
        );
    }
    eprintln!("arm at {mine:?}; served truth {:?}", &truth.joints[..5]);

    let start = served.robot.truth().expect("truth").root.translation.vector;
    bot.base()
        .expect("base")
        .go_to_relative([0.3, 0.0, 0.0])
        .expect("the base drives");
    let end = served.robot.truth().expect("truth").root.translation.vector;
    let moved = (end - start).xy().norm();
    eprintln!("the base drove {moved:.3} m");
    assert!((moved - 0.3).abs() < 0.05, "{moved}");

    let (rgb, depth) = bot
        .camera()
        .expect("camera")
        .get_rgb_depth()
        .expect("a frame");
    assert_eq!((rgb.width, rgb.height), (depth.width, depth.height));
    // The same view as the served robot's own camera (both still): the valid depths and the
    // mean colour agree within the depth noise.
    let (rgb0, depth0) = served
        .robot
        .camera()
        .expect("camera")
        .get_rgb_depth()
        .expect("a frame");
    let valid = |d: &ferrobot::perception::DepthImage| d.data.iter().filter(|x| **x > 0.0).count();
    let mean = |i: &ferrobot::perception::RgbImage| {
        i.data.iter().map(|&b| f64::from(b)).sum::<f64>() / i.data.len() as f64
    };
    let (v, v0) = (valid(&depth) as f64, valid(&depth0) as f64);
    eprintln!(
        "remote frame: {v} valid depths (served: {v0}), mean colour {:.2} ({:.2})",
        mean(&rgb),
        mean(&rgb0)
    );
    assert!(v > 1000.0 && (v - v0).abs() < 0.02 * v0, "{v} against {v0}");
    assert!((mean(&rgb) - mean(&rgb0)).abs() < 1.0);

    // Errors arrive typed: the client's own checks, and the firmware's refusals through the
    // server (an emergency stop latched by the client).
    let beyond = arm.set_joint_positions(&[9.0, 0.0, 0.0, 0.0, 0.0]);
    assert!(
        matches!(beyond, Err(Error::OutOfLimits { .. })),
        "{beyond:?}"
    );
    bot.emergency_stop().expect("stopped");
    let refused = arm.set_joint_positions(&[0.0; 5]);
    assert!(matches!(refused, Err(Error::EmergencyStop)), "{refused:?}");
    bot.resume().expect("resumed");
    arm.set_joint_positions(&[0.0; 5]).expect("moves again");
    let s = served.stats();
    eprintln!("served: {:?}", s.remote);
    assert_eq!(s.remote.bad_calls, 0);
}

/// The child of the kill test: connects, drives the base for 20 s, says so, and waits to be
/// killed.
#[test]
#[ignore = "run by a_killed_remote_program_has_the_robot_stopped_by_the_watchdog"]
fn remote_program_killed_mid_motion() {
    let Ok(endpoint) = std::env::var("FERROBOT_TEST_ENDPOINT") else {
        return;
    };
    let bot = client(&endpoint, "/");
    let _motion = bot
        .base()
        .expect("base")
        .set_vel_async(0.2, 0.0, 20.0)
        .expect("drives");
    bot.wait(0.5).expect("drives on");
    println!("DRIVING");
    loop {
        bot.wait(1.0).expect("drives on");
    }
}

#[test]
fn a_killed_remote_program_has_the_robot_stopped_by_the_watchdog() {
    let served = Served::start("/");
    let mut child = Command::new(std::env::current_exe().expect("this test"))
        .args([
            "--exact",
            "remote_program_killed_mid_motion",
            "--ignored",
            "--nocapture",
        ])
        .env("FERROBOT_TEST_ENDPOINT", &served.endpoint)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("the client starts");
    let mut lines = BufReader::new(child.stdout.take().expect("its output")).lines();
    let driving = lines.any(|l| l.is_ok_and(|l| l.contains("DRIVING")));
    assert!(driving, "the client never drove");
    let speed = |r: &Robot| {
        r.telemetry()
            .map(|t| f64::from(t.odometry.v))
            .unwrap_or(0.0)
    };
    assert!(
        speed(&served.robot) > 0.15,
        "not driving: {}",
        speed(&served.robot)
    );
    child.kill().expect("killed");
    let killed_at = Instant::now();
    let t0 = served.robot.time();
    let _ = child.wait();
    // The watchdog's stop, then the base at rest; both on the served robot's clock.
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut stopped_at = None;
    while Instant::now() < deadline {
        if stopped_at.is_none() && served.stats().remote.watchdog_stops > 0 {
            stopped_at = Some(served.robot.time() - t0);
        }
        if stopped_at.is_some() && speed(&served.robot).abs() < 0.005 {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let at_rest = served.robot.time() - t0;
    let stopped = stopped_at.expect("the watchdog never stopped the robot");
    eprintln!(
        "client killed: the watchdog stopped the robot {stopped:.3} s after (period {WATCHDOG:?}), \
         the base at rest {at_rest:.3} s after; wall {:?}",
        killed_at.elapsed()
    );
    assert!(stopped <= WATCHDOG.as_secs_f64() + 0.05, "{stopped} s");
    assert!(speed(&served.robot).abs() < 0.005, "still driving");
}
