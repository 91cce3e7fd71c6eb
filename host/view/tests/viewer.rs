//! A viewer written from Foxglove's protocol spec (`peer/view_peer.py`: the `websockets`
//! package, rosbags to decode by schema name) connects to the live view of a moving LoCoBot:
//! it gets the subprotocol, the server's info and the channels, the latched URDF and fixed
//! transforms on subscribing, joint states equal to the robot's reports, camera frames until it
//! unsubscribes, and nothing of the camera after; the arm's planned path, its end where forward
//! kinematics puts the goal; and the tabletop scene's bodies as markers, where the simulator
//! has them.

use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use ferrobot::{Backend, Robot};
use ferrobot_view::{ViewOptions, ViewServer};

/// Nobody watching: the view reads no camera frame (the simulator renders none for it) while
/// the robot's other streams flow.
#[test]
fn without_a_viewer_of_the_camera_no_frame_is_read() {
    let robot = Robot::builder("locobot")
        .backend(Backend::Sim {
            seed: 1,
            realtime: false,
        })
        .build()
        .expect("robot");
    let view = ViewServer::start(&robot, "127.0.0.1:0", ViewOptions::default()).expect("served");
    robot.wait(1.0).expect("time passes");
    // The feed thread takes what the robot's streams delivered.
    let deadline = Instant::now() + Duration::from_secs(10);
    while view.published("/joint_states") < 50 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(view.published("/joint_states") >= 50);
    assert_eq!(view.published("/camera/color/image_raw"), 0);
    assert_eq!(
        view.published("/camera/aligned_depth_to_color/image_raw"),
        0
    );
}

#[test]
fn a_viewer_sees_the_robot_as_foxglove_would() {
    let Some(py) =
        ferrobot_peers::for_test("websockets, rosbags.typesys", "scripts/python-env.sh view")
    else {
        return;
    };
    let robot = Robot::builder("locobot")
        .backend(Backend::Sim {
            seed: 1,
            realtime: true,
        })
        .scene("tabletop")
        .build()
        .expect("robot");
    let view = ViewServer::start(&robot, "127.0.0.1:0", ViewOptions::default()).expect("served");
    let telemetry = robot.subscribe_telemetry(100_000).expect("telemetry");
    let url = format!("ws://{}", view.addr());
    let mut peer = Command::new(py)
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/peer/view_peer.py"))
        .args([&url, "4"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the viewer starts");
    let arm = robot.arm().expect("arm");
    let goal = [0.4, 0.2, 0.3, 0.1, 0.0];
    let plan = arm
        .plan_to(&goal, &ferrobot::arm_plan::PlanningOptions::default())
        .expect("a plan");
    let ee = robot.config().arm.as_ref().expect("arm").ee_frame.clone();
    let goal_ee = arm.compute_fk_position(&goal, &ee).expect("fk");
    let _m = arm.execute(&plan).expect("a motion");
    let deadline = Instant::now() + Duration::from_secs(60);
    while peer.try_wait().expect("the viewer").is_none() {
        assert!(
            Instant::now() < deadline,
            "the viewer did not finish in 60 s"
        );
        robot.wait(0.05).expect("time passes");
    }
    let out = peer.wait_with_output().expect("its output");
    let said = String::from_utf8_lossy(&out.stdout);
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the viewer failed: {said}");
    let v: serde_json::Value = serde_json::from_str(said.trim()).expect("its JSON");
    eprintln!("view: {:?}", view.stats());
    // The camera was read while the viewer subscribed, and is not since it left.
    let color = "/camera/color/image_raw";
    let n = view.published(color);
    robot.wait(0.5).expect("time passes");
    eprintln!(
        "camera frames published: {n}, then {}",
        view.published(color)
    );
    assert!(n > 0);
    assert_eq!(view.published(color), n);
    assert_eq!(v["subprotocol"], "foxglove.websocket.v1");
    assert_eq!(v["server"]["op"], "serverInfo");
    assert_eq!(
        v["errors"].as_array().map(Vec::len),
        Some(0),
        "{}",
        v["errors"]
    );
    let got = &v["received"];
    for t in [
        "/joint_states",
        "/robot_description",
        "/tf_static",
        "/tf",
        "/camera/color/image_raw",
        "/arm/planned_path",
        "/scene/markers",
    ] {
        assert!(
            got[t]["count"].as_u64().unwrap_or(0) > 0,
            "nothing on {t}: {got}"
        );
    }
    assert_eq!(
        got["/robot_description"]["count"], 1,
        "the URDF once, on subscribing"
    );
    assert!(got["/robot_description"]["length"].as_u64().unwrap_or(0) > 1000);
    assert!(
        got["/joint_states"]["count"].as_u64().unwrap_or(0) > 200,
        "{got}"
    );

    // The last joint state the viewer decoded is the robot's report of its stamp.
    let reports: BTreeMap<u64, Vec<f64>> = telemetry
        .drain()
        .into_iter()
        .map(|t| {
            (
                t.time_us,
                t.joints.iter().map(|j| f64::from(j.position)).collect(),
            )
        })
        .collect();
    let last = &got["/joint_states"]["last"];
    let us = (last["stamp"].as_f64().expect("stamp") * 1e6).round() as u64;
    let ours = reports.get(&us).expect("a report of that stamp");
    let theirs: Vec<f64> = serde_json::from_value(last["position"].clone()).expect("positions");
    for (a, b) in theirs.iter().zip(ours) {
        assert!((a - b).abs() < 1e-9, "{theirs:?} against {ours:?}");
    }
    assert_eq!(
        got["/joint_states"]["last_time_ns"].as_u64(),
        Some(us * 1000)
    );

    // The camera, until unsubscribed: at most the frames already queued after.
    let img = &got["/camera/color/image_raw"];
    assert_eq!(img["last"]["encoding"], "rgb8");
    let at = v["camera_count_at_unsubscribe"]
        .as_u64()
        .expect("unsubscribed");
    let total = img["count"].as_u64().unwrap_or(0);
    eprintln!("camera frames: {at} when unsubscribing, {total} in all");
    assert!(at > 10 && total <= at + 3, "{at} then {total}");

    // The plan: its end effector path ends where forward kinematics puts the goal, reached
    // the trajectory's duration after it was planned.
    let path = &got["/arm/planned_path"]["last"];
    let end: Vec<f64> = serde_json::from_value(path["end"].clone()).expect("an end");
    let want = goal_ee.position;
    eprintln!("planned path: {path}; the goal's end effector at {want:?}");
    assert_eq!(
        path["frame"],
        robot
            .config()
            .arm
            .as_ref()
            .expect("arm")
            .base_frame
            .as_str()
    );
    for k in 0..3 {
        assert!((end[k] - want[k]).abs() < 1e-6, "{end:?} against {want:?}");
    }
    let n = path["n"].as_u64().expect("poses") as f64;
    assert!(
        (n - (plan.duration() / 0.05).ceil() - 1.0).abs() <= 1.0,
        "{n} poses"
    );
    let span = path["end_stamp"].as_f64().expect("stamp") - path["stamp"].as_f64().expect("stamp");
    assert!((span - plan.duration()).abs() < 1e-6, "{span} s");

    // The scene: every body a marker in `odom`, each movable one where the simulator has it
    // (within 1 mm: it may have settled since the last markers were sent).
    let scene = robot.scene();
    let truth = robot.truth().expect("truth");
    let markers = &got["/scene/markers"]["last"];
    eprintln!(
        "scene markers: {} for {} bodies",
        markers["n"],
        scene.bodies.len()
    );
    assert_eq!(markers["frames"], serde_json::json!(["odom"]));
    let bodies = markers["bodies"].as_object().expect("bodies");
    assert_eq!(bodies.len(), scene.bodies.len());
    let [x, y, yaw] = scene.robot_pose;
    let odom = nalgebra::Isometry3::new(
        nalgebra::Vector3::new(x, y, scene.robot_height),
        nalgebra::Vector3::new(0.0, 0.0, yaw),
    );
    for (body, pose) in scene.bodies.iter().zip(&truth.bodies) {
        let theirs: Vec<f64> =
            serde_json::from_value(bodies[&body.id]["position"].clone()).expect("position");
        let ours = (odom.inverse() * pose).translation.vector;
        for k in 0..3 {
            assert!(
                (theirs[k] - ours[k]).abs() < 1e-3,
                "{}: {theirs:?} against {ours:?}",
                body.id
            );
        }
    }
}
