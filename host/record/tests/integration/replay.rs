//! Replay: a recording's commands sent to a fresh simulated robot with the same seed give the
//! same states; its frames fed to SLAM offline give SLAM's poses of the live run.

use std::collections::BTreeMap;
use std::path::Path;

use ferrobot::slam::{optimise, RgbdInput, Slam, SlamSettings, SELF_RADIUS};
use ferrobot::Robot;
use ferrobot_record::reader::Reading;
use ferrobot_record::replay::{replay_commands, SensorFrames};
use ferrobot_record::{decode, topics, RecordOptions, Recorder};

/// A program: SLAM, the arm by positions and by velocities, the gripper, the base.
fn program(robot: &Robot) {
    robot.start_slam([0.0, 0.0, 0.0], None).unwrap();
    let arm = robot.arm().unwrap();
    arm.set_joint_positions(&[0.3, 0.2, -0.3, 0.4, 0.1])
        .unwrap();
    arm.set_joint_velocities(&[0.2, 0.0, 0.0, -0.2, 0.0])
        .unwrap();
    robot.wait(0.5).unwrap();
    robot.gripper().unwrap().close().unwrap();
    robot.base().unwrap().set_vel(0.2, 0.3, 1.5).unwrap();
    arm.go_home().unwrap();
    robot.wait(0.3).unwrap();
}

/// `/joint_states` of a recording: time (ns) to positions.
fn states(path: &Path) -> BTreeMap<u64, Vec<f64>> {
    Reading::open(path)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| &*m.topic == topics::JOINT_STATES.name)
        .map(|m| (m.time_ns, decode::joint_state(&m.data).unwrap().2))
        .collect()
}

#[test]
fn replayed_commands_give_the_same_states_and_replayed_frames_the_same_slam_poses() {
    let dir = crate::scratch("replay-same");
    let live = dir.join("live.mcap");
    let robot = Robot::new("locobot").unwrap();
    let recorder = Recorder::start(&robot, &live, RecordOptions::default()).unwrap();
    program(&robot);
    let end = robot.time();
    recorder.finish().unwrap();

    // The commands, into a fresh robot with the same seed, recorded again.
    let again = dir.join("replayed.mcap");
    let fresh = Robot::new("locobot").unwrap();
    let recorder = Recorder::start(
        &fresh,
        &again,
        RecordOptions {
            camera: false,
            ..Default::default()
        },
    )
    .unwrap();
    let stats = replay_commands(&fresh, &live).unwrap();
    fresh.wait(end - fresh.time()).unwrap();
    recorder.finish().unwrap();
    assert_eq!(stats.refused, 0, "{stats:?}");
    assert!(stats.sent > 20, "{stats:?}");
    let (a, b) = (states(&live), states(&again));
    let common: Vec<u64> = a.keys().filter(|t| b.contains_key(t)).copied().collect();
    assert!(
        common.len() as f64 > 0.95 * a.len() as f64,
        "{} of {}",
        common.len(),
        a.len()
    );
    let worst = common
        .iter()
        .flat_map(|t| a[t].iter().zip(&b[t]).map(|(x, y)| (x - y).abs()))
        .fold(0.0, f64::max);
    println!(
        "{} commands replayed; {} joint states compared, worst difference {worst:e} rad",
        stats.sent,
        common.len()
    );
    assert!(worst <= 1e-9, "replayed states differ by {worst} rad");
    let moved = a.values().map(|q| q[0].abs()).fold(0.0, f64::max);
    assert!(moved > 0.25, "the arm hardly moved ({moved} rad)");

    // The frames, into SLAM offline: the live run's poses.
    let radius = robot.config().base.as_ref().unwrap().footprint_radius;
    let mut slam: Option<Slam> = None;
    let mut offline = BTreeMap::new();
    for f in SensorFrames::open(&live).unwrap() {
        let f = f.unwrap();
        let s = slam.get_or_insert_with(|| {
            let settings = SlamSettings::ground_robot(radius.max(SELF_RADIUS));
            Slam::new(settings, f.intrinsics, optimise::planar([0.0, 0.0, 0.0])).unwrap()
        });
        let r = s
            .track(&RgbdInput {
                time: f.time.as_secs_f64(),
                rgb: &f.rgb,
                depth: &f.depth,
                camera: f.camera_pose,
                odometry: Some(f.odometry),
            })
            .unwrap();
        offline.insert(f.time.as_nanos() as u64, r.pose);
    }
    let online: BTreeMap<u64, _> = Reading::open(&live)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| &*m.topic == topics::SLAM_POSE.name)
        .map(|m| (m.time_ns, decode::pose_stamped(&m.data).unwrap().2))
        .collect();
    assert_eq!(online.len(), offline.len());
    let worst = online
        .iter()
        .map(|(t, p)| (p.translation.vector - offline[t].translation.vector).norm())
        .fold(0.0, f64::max);
    println!(
        "{} frames through SLAM offline: worst difference from the live poses {worst:e} m",
        offline.len()
    );
    assert!(worst <= 1e-9, "offline SLAM differs by {worst} m");
}
