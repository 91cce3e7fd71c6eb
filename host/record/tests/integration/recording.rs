//! A recording of the simulated LoCoBot (arm, gripper, base, camera, SLAM, an emergency stop)
//! decoded by Foxglove's `mcap` reader and by rosbags (its own MCAP storage, and its CDR
//! decoder with the types parsed from the file's schemas): every topic must hold the values the
//! robot delivered, which this test collects through its own subscriptions and hands the
//! checker (host/record/peer/check_recording.py) as JSON and raw frames.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;

use ferrobot::events::{Event, HostMsg};
use ferrobot::{Frame, Robot, Telemetry};
use ferrobot_record::{RecordOptions, Recorder};
use serde_json::{json, Value};

fn python() -> Option<PathBuf> {
    ferrobot_peers::for_test(
        "mcap, rosbags.highlevel, numpy",
        "scripts/python-env.sh record",
    )
}

/// The robot's work while it is recorded: each kind of command, a fault, SLAM.
fn work(robot: &Robot) {
    robot.start_slam([0.0, 0.0, 0.0], None).unwrap();
    let arm = robot.arm().unwrap();
    arm.set_joint_positions(&[0.3, 0.2, -0.3, 0.4, 0.1])
        .unwrap();
    robot.gripper().unwrap().close().unwrap();
    robot.base().unwrap().set_vel(0.2, 0.3, 1.0).unwrap();
    robot.emergency_stop().unwrap();
    robot.wait(0.2).unwrap();
    robot.resume().unwrap();
    robot.gripper().unwrap().open().unwrap();
    arm.go_home().unwrap();
    robot.wait(0.3).unwrap();
    robot.stop_slam();
}

fn telemetry_json(robot: &Robot, t: &Telemetry) -> Value {
    let ee = robot.config().arm.as_ref().unwrap().ee_frame.clone();
    let pose = robot
        .frames()
        .unwrap()
        .transform_at(t, &ee, "base_link")
        .unwrap();
    let q = pose.rotation.coords;
    json!({
        "t_ns": t.time_us * 1000,
        "position": t.joints.iter().map(|j| j.position as f64).collect::<Vec<_>>(),
        "velocity": t.joints.iter().map(|j| j.velocity as f64).collect::<Vec<_>>(),
        "effort": t.joints.iter().map(|j| j.effort as f64).collect::<Vec<_>>(),
        "odom": [t.odometry.x as f64, t.odometry.y as f64, t.odometry.theta as f64,
                 t.odometry.v as f64, t.odometry.w as f64],
        "gripper": t.gripper.pyrobot_code(),
        "ee_in_base": [pose.translation.x, pose.translation.y, pose.translation.z, q.x, q.y, q.z, q.w],
    })
}

fn frame_json(f: &Frame, dir: &Path, i: usize, whole: bool) -> Value {
    let rgb_sum: u64 = f.rgb.data.iter().map(|&b| u64::from(b)).sum();
    let depth: Vec<u8> = f.depth.data.iter().flat_map(|d| d.to_le_bytes()).collect();
    // Every frame's sums; the first and last frames' bytes whole.
    if whole {
        std::fs::write(dir.join(format!("rgb-{i}.bin")), &f.rgb.data).unwrap();
        std::fs::write(dir.join(format!("depth-{i}.bin")), &depth).unwrap();
    }
    let k = &f.intrinsics;
    let c = f.camera_pose.translation.vector;
    json!({
        "t_ns": f.time.as_nanos() as u64,
        "whole": whole,
        "rgb_sum": rgb_sum,
        "depth_valid": f.depth.data.iter().filter(|&&d| d > 0.0).count(),
        "size": [k.width, k.height],
        "k": [k.fx, k.fy, k.cx, k.cy],
        "camera_in_base": [c.x, c.y, c.z],
    })
}

fn event_json(robot: &Robot, e: &Event) -> Option<Value> {
    let t = e.time().as_nanos() as u64;
    match e {
        Event::Command {
            msg: HostMsg::BaseVelocity { v, w, .. },
            ..
        } => Some(json!({"topic": "/cmd_vel", "t_ns": t, "values": [*v as f64, *w as f64]})),
        Event::Command {
            msg: HostMsg::Waypoint { points, .. },
            ..
        } => Some(json!({
            "topic": "/joint_commands", "t_ns": t,
            "values": points.iter().map(|p| p.position as f64).collect::<Vec<_>>()})),
        Event::Command {
            msg: HostMsg::Gripper(g),
            ..
        } => Some(
            json!({"topic": "/gripper/command", "t_ns": t, "values": format!("{g:?}").to_lowercase()}),
        ),
        Event::Command {
            msg: HostMsg::EmergencyStop,
            ..
        } => Some(json!({"topic": "/rosout", "t_ns": t, "values": "emergency stop"})),
        Event::Slam { report, .. } => {
            let p = report.pose.translation.vector;
            let _ = robot;
            Some(json!({"topic": "/slam/pose", "t_ns": t, "values": [p.x, p.y, p.z]}))
        }
        _ => None,
    }
}

#[test]
fn every_topic_decodes_with_rosbags_and_mcap_to_the_values_recorded() {
    let Some(py) = python() else { return };
    let dir = crate::scratch("record-all-topics");
    let robot = Robot::new("locobot").unwrap();
    let file = dir.join("locobot.mcap");
    let recorder = Recorder::start(&robot, &file, RecordOptions::default()).unwrap();
    // The test's own subscriptions: what the robot delivered, to compare with the file.
    let tel = robot.subscribe_telemetry(100_000).unwrap();
    let frames = robot.camera().unwrap().subscribe(100_000).unwrap();
    let events = robot.subscribe_events(100_000).unwrap();
    work(&robot);
    let stats = recorder.finish().unwrap();
    let tel = tel.drain();
    let frames: Vec<Arc<Frame>> = frames.drain();
    let events = events.drain();
    assert_eq!(
        (stats.frames_dropped, stats.telemetry_dropped),
        (0, 0),
        "{stats:?}"
    );
    assert!(
        tel.len() > 300 && frames.len() > 90,
        "{} {}",
        tel.len(),
        frames.len()
    );
    // The recorder subscribed first: it saw every report the test saw, and maybe one more.
    assert!(stats.written.telemetry >= tel.len() as u64, "{stats:?}");
    let frame_list: Vec<Value> = frames
        .iter()
        .enumerate()
        .map(|(i, f)| frame_json(f, &dir, i, i == 0 || i + 1 == frames.len()))
        .collect();
    let expected = json!({
        "joints": robot.config().joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>(),
        "ee_frame": robot.config().arm.as_ref().unwrap().ee_frame,
        "optical": robot.optical_frame().unwrap(),
        "telemetry": tel.iter().map(|t| telemetry_json(&robot, t)).collect::<Vec<_>>(),
        "frames": frame_list,
        "events": events.iter().filter_map(|e| event_json(&robot, e)).collect::<Vec<_>>(),
        "messages": stats.written.messages,
    });
    std::fs::write(dir.join("expected.json"), expected.to_string()).unwrap();
    let checker = Path::new(env!("CARGO_MANIFEST_DIR")).join("peer/check_recording.py");
    let out = Command::new(py)
        .arg(&checker)
        .arg(&file)
        .arg(&dir)
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    println!("{said}{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        out.status.success(),
        "the recording does not read back: {said}"
    );
}
