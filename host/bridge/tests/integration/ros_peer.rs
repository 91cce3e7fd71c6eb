//! A served LoCoBot against an independent ROS 2 peer (`peer/ros_peer.py`: eclipse-zenoh from
//! PyPI, rosbags' Jazzy type store for CDR and type hashes, no code of ours): it finds the
//! robot's node and publishers by their liveliness tokens, decodes the robot's topics with the
//! robot's values, gets the latched URDF and fixed transforms as a late subscriber, and its
//! `/cmd_vel` drives the base; its two hostile samples are refused. Then its `/goal_pose`
//! takes the base to a pose and its `/arm/joint_trajectory` the arm through two points (its
//! joints named in reverse order), after two hostile trajectories that are refused.

use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use ferrobot::{Backend, Robot};
use ferrobot_bridge::{access, Access, ServeOptions, Server};

#[test]
fn a_ros_2_peer_reads_the_robots_topics_and_drives_its_base() {
    let Some(py) = ferrobot_peers::for_test(
        "zenoh, zenoh.ext, rosbags.typesys",
        "scripts/python-env.sh zenoh",
    ) else {
        return;
    };
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
        namespace: "/locobot".into(),
        ..ServeOptions::default()
    };
    let server = Server::start(&robot, &session, opts).expect("served");
    let telemetry = robot.subscribe_telemetry(100_000).expect("telemetry");
    let start = robot.truth().expect("truth").root.translation.vector;
    let peer = Command::new(py)
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/peer/ros_peer.py"))
        .args([&endpoint, "/locobot", "1.5", "0.2", "0.0", "2.0"])
        .env("FERROBOT_PEER_GOALS", "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the peer starts");
    // The robot's time passes (paced to the wall clock) while the peer works.
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut peer = peer;
    while peer.try_wait().expect("the peer").is_none() {
        assert!(Instant::now() < deadline, "the peer did not finish in 60 s");
        robot.wait(0.05).expect("time passes");
    }
    let out = peer.wait_with_output().expect("the peer's output");
    let said = String::from_utf8_lossy(&out.stdout);
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the peer failed: {said}");
    let v: serde_json::Value = serde_json::from_str(said.trim()).expect("the peer's JSON");
    let moved_by_cmd_vel = robot.truth().expect("truth").root.translation.vector - start;
    let goals = reach_goals(&robot, &v["goals"]);
    let stats = server.stop();
    eprintln!("served: {stats:?}");
    let got = &v["received"];
    assert_eq!(
        v["errors"].as_array().map(Vec::len),
        Some(0),
        "{}",
        v["errors"]
    );

    // Every topic arrived, each sample with rmw_zenoh's attachment, sequence numbers rising.
    for topic in [
        "/joint_states",
        "/odom",
        "/tf",
        "/camera/color/image_raw",
        "/camera/color/camera_info",
        "/robot_description",
        "/tf_static",
        "/clock",
    ] {
        let r = &got[topic];
        assert!(
            r["count"].as_u64().unwrap_or(0) > 0,
            "nothing on {topic}: {got}"
        );
        assert_eq!(r["bad_attachments"], 0, "{topic}");
        assert_eq!(r["seq_increasing"], true, "{topic}");
    }
    let n = got["/joint_states"]["count"].as_u64().unwrap_or(0);
    assert!(n > 100, "{n} joint states in the peer's 4.5 s (100 Hz)");

    // The joint states carry the robot's values: each sample is a telemetry report's, to f32.
    let reports: BTreeMap<u64, Vec<f64>> = telemetry
        .drain()
        .into_iter()
        .map(|t| {
            let q = t.joints.iter().map(|j| f64::from(j.position)).collect();
            (t.time_us, q)
        })
        .collect();
    let names: Vec<String> = robot
        .config()
        .joints
        .iter()
        .map(|j| j.name.clone())
        .collect();
    let samples = got["/joint_states"]["samples"].as_array().expect("samples");
    assert!(samples.len() >= 20, "{} samples kept", samples.len());
    for s in samples {
        let us = (s["stamp"].as_f64().expect("stamp") * 1e6).round() as u64;
        let ours = reports
            .get(&us)
            .unwrap_or_else(|| panic!("no report at {us} µs"));
        let theirs: Vec<f64> = serde_json::from_value(s["position"].clone()).expect("positions");
        let names_seen: Vec<String> = serde_json::from_value(s["name"].clone()).expect("names");
        assert_eq!(names_seen, names[..theirs.len()]);
        for (a, b) in theirs.iter().zip(ours) {
            assert!(
                (a - b).abs() < 1e-9,
                "at {us} µs: {theirs:?} against {ours:?}"
            );
        }
    }

    // The robot's clock, as a node with use_sim_time keeps time: as far as the last joint state.
    let clock = got["/clock"]["last"].as_f64().expect("a clock");
    let last = samples
        .last()
        .and_then(|s| s["stamp"].as_f64())
        .expect("a stamp");
    assert!(
        clock >= last - 0.05,
        "clock {clock} s, last joint state {last} s"
    );

    // The points: as many as the valid depths at the stride, each where the peer's own
    // reconstruction from the depth image and camera info of the same stamp puts it.
    let pc = &v["points_check"];
    eprintln!("points: {pc}");
    assert!(pc["theirs"].as_u64().unwrap_or(0) > 1000, "{pc}");
    assert_eq!(pc["mine"], pc["theirs"], "{pc}");
    assert!(pc["max_error"].as_f64().is_some_and(|e| e < 1e-5), "{pc}");
    assert_eq!(
        got["/camera/depth/color/points"]["last"]["fields"],
        serde_json::json!(["x", "y", "z", "rgb"])
    );

    // The URDF as the robot parsed it; the camera's image and intrinsics.
    assert!(got["/robot_description"]["length"].as_u64().unwrap_or(0) > 1000);
    let img = &got["/camera/color/image_raw"]["last"];
    let cam = robot.config().camera.clone().expect("camera");
    assert_eq!(img["encoding"], "rgb8");
    assert_eq!(img["frame"], cam.frame.as_str());
    let (w, h) = (
        img["width"].as_u64().unwrap(),
        img["height"].as_u64().unwrap(),
    );
    assert_eq!(img["bytes"].as_u64(), Some(w * h * 3));
    let k: Vec<f64> =
        serde_json::from_value(got["/camera/color/camera_info"]["last"]["k"].clone()).expect("K");
    let i = robot
        .camera()
        .expect("camera")
        .intrinsics()
        .expect("intrinsics");
    assert!(
        (k[0] - i.fx).abs() < 1e-9 && (k[2] - i.cx).abs() < 1e-9,
        "{k:?} against {i:?}"
    );

    // Found as a ROS 2 node: its token and its publishers' under the namespace.
    let tokens: Vec<String> = serde_json::from_value(v["tokens"].clone()).expect("tokens");
    assert!(
        tokens.iter().any(|t| t.contains("/NN/%/%locobot/ferrobot")),
        "{tokens:?}"
    );
    assert!(tokens
        .iter()
        .any(|t| t.contains("/MP/%/%locobot/ferrobot/%locobot%joint_states/")));

    // Its /cmd_vel drove the base forward: 0.2 m/s for 2 s, less the start and the stop; the
    // malformed and the NaN commands were refused.
    let moved = moved_by_cmd_vel.xy();
    eprintln!("the base moved {moved:?} m");
    // 0.2 m/s for the 2 s of commands and the last one's 0.5 s hold: 0.5 m at most.
    assert!(
        moved.x > 0.3 && moved.x < 0.52 && moved.y.abs() < 0.05,
        "{moved:?}"
    );
    let odom = &got["/odom"]["last"];
    assert!(odom["x"].as_f64().unwrap_or(0.0) > 0.15, "{odom}");
    assert_eq!(stats.cmd_vel_refused, 2, "{stats:?}");
    assert!(stats.cmd_vel_accepted >= 30, "{stats:?}");

    // Its goals: the base at the pose, the arm at the trajectory's last point; the hostile
    // trajectories (a joint the arm does not have, a NaN) refused.
    let (base_error, arm_error) = goals;
    eprintln!("goals reached: base {base_error:.3} m off, arm {arm_error:.3} rad off");
    assert!(base_error < 0.05, "{base_error}");
    assert!(arm_error < 0.02, "{arm_error}");
    assert_eq!(stats.goals_refused, 2, "{stats:?}");
    assert_eq!(stats.goals_accepted, 2, "{stats:?}");
}

/// Lets the robot's time pass until the peer's goals are reached (60 s at most): how far the
/// base's odometry is from the base goal (m), and the arm from the trajectory's last point
/// (rad, the largest joint error).
fn reach_goals(robot: &Robot, goals: &serde_json::Value) -> (f64, f64) {
    let base_goal: Vec<f64> = serde_json::from_value(goals["base"].clone()).expect("base goal");
    let points: Vec<Vec<f64>> = serde_json::from_value(goals["arm"].clone()).expect("arm goal");
    let last = points.last().expect("points");
    let errors = || {
        let s = robot.base().expect("base").get_state().expect("odometry");
        let b = (s[0] - base_goal[0]).hypot(s[1] - base_goal[1]);
        let q = robot
            .arm()
            .expect("arm")
            .get_joint_angles()
            .expect("angles");
        let a = q
            .iter()
            .zip(last)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        (b, a)
    };
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let (b, a) = errors();
        if (b < 0.05 && a < 0.02) || Instant::now() > deadline {
            return (b, a);
        }
        robot.wait(0.1).expect("time passes");
    }
}
