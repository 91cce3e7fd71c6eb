//! The public API on the simulator backend: every method, with Ferrobot's tolerances
//! (joints 0.01 rad; end effector 5 mm and 0.02 rad; base 2 cm and 2°).
#![allow(clippy::needless_range_loop)]

use ferrobot::base_control::wrap;
use ferrobot::{Error, GripperState, MoveOptions, Orientation, Robot};
use ferrobot_protocol::FaultKind;

use crate::common;

const JOINT_TOL: f64 = 0.01;
const EE_POS_TOL: f64 = 0.005;
const EE_ROT_TOL: f64 = 0.02;
const BASE_POS_TOL: f64 = 0.02;
const BASE_ROT_TOL: f64 = 2.0 * std::f64::consts::PI / 180.0;

fn max_err(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn rot_err(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> f64 {
    let ma = nalgebra::Matrix3::from_row_slice(&a.concat());
    let mb = nalgebra::Matrix3::from_row_slice(&b.concat());
    nalgebra::Rotation3::from_matrix_unchecked(ma.transpose() * mb).angle()
}

fn pos_err(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[test]
fn locobot_joint_control_reads_and_fk() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    assert_eq!(arm.dof(), 5);
    let target = [0.4, 0.3, -0.5, 0.6, -0.3];
    arm.set_joint_positions(&target).expect("moves");
    let q = arm.get_joint_angles().expect("angles");
    assert!(max_err(&q, &target) < JOINT_TOL, "{q:?}");
    assert!((arm.get_joint_angle("joint_3").expect("by name") - target[2]).abs() < JOINT_TOL);
    assert!(arm
        .get_joint_velocities()
        .expect("velocities")
        .iter()
        .all(|v| v.abs() < 0.05));
    let tau = arm.get_joint_torques().expect("torques");
    assert_eq!(tau.len(), 5);
    // Gravity loads the shoulder: its torque reading is clearly non-zero.
    assert!(
        arm.get_joint_torque("joint_2").expect("by name").abs() > 0.05,
        "{tau:?}"
    );
    // FK of the measured angles is the end-effector pose.
    let pose = arm.get_ee_pose().expect("pose");
    let fk = arm.compute_fk_position(&q, "gripper_link").expect("fk");
    assert!(pos_err(&pose.position, &fk.position) < 1e-9);
    // FK to an intermediate frame of the chain.
    let wrist = arm.compute_fk_position(&q, "wrist_link").expect("fk wrist");
    assert!(pos_err(&wrist.position, &pose.position) > 0.05);
    assert!(matches!(
        arm.compute_fk_position(&q, "no_such_link"),
        Err(Error::UnknownName { .. })
    ));
    // Jacobian and FK velocity agree with finite differences of FK.
    let j = arm.get_jacobian(&q).expect("jacobian");
    assert_eq!((j.nrows(), j.ncols()), (6, 5));
    let qd = [0.1, -0.2, 0.3, 0.1, 0.5];
    let tw = arm.compute_fk_velocity(&q, &qd).expect("twist");
    let h = 1e-6;
    let q2: Vec<f64> = q.iter().zip(&qd).map(|(a, b)| a + b * h).collect();
    let p2 = arm.compute_fk_position(&q2, "gripper_link").expect("fk");
    for k in 0..3 {
        assert!(((p2.position[k] - fk.position[k]) / h - tw[k]).abs() < 1e-4);
    }
    arm.go_home().expect("home");
    assert!(max_err(&arm.get_joint_angles().expect("angles"), &[0.0; 5]) < JOINT_TOL);
    // Unplanned moves arrive too (the firmware rate-limits them).
    arm.set_joint_positions_with(
        &[0.2, 0.0, 0.0, 0.0, 0.0],
        MoveOptions {
            plan: false,
            ..Default::default()
        },
    )
    .expect("unplanned");
    assert!((arm.get_joint_angles().expect("angles")[0] - 0.2).abs() < JOINT_TOL);
}

#[test]
fn locobot_end_effector_poses_ik_and_cartesian_lines() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    // A reachable pose from known joints; ask for it in all three orientation forms.
    let q_ref = [0.3, 0.5, 0.3, 0.6, 0.2];
    let pose = arm.compute_fk_position(&q_ref, "gripper_link").expect("fk");
    let [x, y, z, w] = pose.quaternion;
    let rot = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
    let (roll, pitch, yaw) = rot.euler_angles();
    for o in [
        Orientation::Quaternion(pose.quaternion),
        Orientation::YawPitchRoll([yaw, pitch, roll]),
        Orientation::Matrix(pose.rotation),
    ] {
        let q = arm
            .compute_ik(pose.position, o, Some(&[0.0; 5]))
            .expect("ik");
        let back = arm.compute_fk_position(&q, "gripper_link").expect("fk");
        assert!(
            pos_err(&back.position, &pose.position) < 1e-5
                && rot_err(&back.rotation, &pose.rotation) < 1e-5
        );
    }
    arm.set_ee_pose(pose.position, Orientation::Quaternion(pose.quaternion))
        .expect("moves");
    let got = arm.get_ee_pose().expect("pose");
    assert!(
        pos_err(&got.position, &pose.position) < EE_POS_TOL,
        "{got:?}"
    );
    assert!(
        rot_err(&got.rotation, &pose.rotation) < EE_ROT_TOL,
        "{got:?} {pose:?} {:?}",
        arm.get_joint_angles()
    );
    // Top-down grasp pose by pitch and roll.
    arm.set_ee_pose_pitch_roll([0.35, 0.0, 0.15], std::f64::consts::FRAC_PI_2, Some(0.0))
        .expect("pitch-roll");
    let got = arm.get_ee_pose().expect("pose");
    assert!(
        pos_err(&got.position, &[0.35, 0.0, 0.15]) < EE_POS_TOL,
        "{got:?}"
    );
    // The gripper's x axis points down.
    assert!((got.rotation[2][0] + 1.0).abs() < EE_ROT_TOL, "{got:?}");
    // A straight line 10 cm forward, in 1 cm steps; the orientation is kept.
    let before = arm.get_ee_pose().expect("pose");
    arm.move_ee_xyz([0.1, 0.0, 0.0], 0.01).expect("line");
    let after = arm.get_ee_pose().expect("pose");
    let want = [
        before.position[0] + 0.1,
        before.position[1],
        before.position[2],
    ];
    assert!(
        pos_err(&after.position, &want) < EE_POS_TOL,
        "{after:?} vs {want:?}"
    );
    assert!(rot_err(&after.rotation, &before.rotation) < EE_ROT_TOL);
    // Unreachable: nothing moves.
    let q = arm.get_joint_angles().expect("angles");
    let e = arm
        .set_ee_pose([2.0, 0.0, 0.3], Orientation::YawPitchRoll([0.0, 0.0, 0.0]))
        .expect_err("far");
    assert!(matches!(e, Error::Unreachable { .. }), "{e}");
    let e = arm
        .move_ee_xyz([0.0, 0.0, 1.0], 0.01)
        .expect_err("leaves the workspace");
    assert!(matches!(e, Error::Unreachable { .. }), "{e}");
    assert!(max_err(&arm.get_joint_angles().expect("angles"), &q) < JOINT_TOL);
}

#[test]
fn locobot_velocity_and_torque_control() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    arm.set_joint_velocities(&[0.3, 0.0, 0.0, 0.0, 0.0])
        .expect("velocity mode");
    bot.wait(1.0).expect("wait");
    let arm = bot.arm().expect("arm");
    let v = arm.get_joint_velocities().expect("v")[0];
    assert!((v - 0.3).abs() < 0.05, "joint_1 at {v} rad/s");
    arm.set_joint_velocities(&[0.0; 5]).expect("stop");
    // Torque control: push joint_1 (no gravity about a vertical axis) with 0.3 N·m; it turns.
    let q0 = arm.get_joint_angles().expect("q")[0];
    arm.set_joint_torques(&[0.3, 0.0, 0.0, 0.0, 0.0])
        .expect("torque mode");
    bot.wait(0.3).expect("wait");
    let arm = bot.arm().expect("arm");
    let q1 = arm.get_joint_angles().expect("q")[0];
    assert!(q1 - q0 > 0.05, "joint_1 moved from {q0} to {q1}");
    // Back to position control.
    arm.set_joint_positions(&[0.0; 5]).expect("position again");
    assert!(max_err(&arm.get_joint_angles().expect("q"), &[0.0; 5]) < JOINT_TOL);
}

#[test]
fn locobot_gripper_and_pan_tilt() {
    let bot = Robot::new("locobot").expect("robot");
    let g = bot.gripper().expect("gripper");
    g.open().expect("open");
    assert_eq!(g.get_state().expect("state"), GripperState::Open);
    assert_eq!(g.close().expect("close"), GripperState::Closed);
    g.reset().expect("reset");
    assert_eq!(g.get_state().expect("state"), GripperState::Open);
    // With an object between the fingers it ends up holding it.
    let at = ferrobot_protocol::dxl::units::tick_to_rad(2300) as f64;
    bot.simulator()
        .expect("sim")
        .hw
        .chain
        .servo_mut(7)
        .expect("gripper")
        .obstacle = Some((at, true));
    assert_eq!(
        bot.gripper().expect("gripper").close().expect("close"),
        GripperState::Holding
    );

    let cam = bot.head().expect("camera");
    cam.set_pan(0.6).expect("pan");
    cam.set_tilt(-0.4).expect("tilt");
    let s = cam.get_state().expect("state");
    assert!(max_err(&s, &[0.6, -0.4]) < JOINT_TOL, "{s:?}");
    cam.set_pan_tilt(-1.0, 0.8).expect("both");
    assert!(max_err(&cam.get_state().expect("state"), &[-1.0, 0.8]) < JOINT_TOL);
    cam.reset().expect("reset");
    assert!(max_err(&cam.get_state().expect("state"), &[0.0, 0.0]) < JOINT_TOL);
    assert!(matches!(cam.set_pan(3.0), Err(Error::OutOfLimits { .. })));
}

fn base_goal_reached(bot: &Robot, goal: [f64; 3]) {
    let s = bot.base().expect("base").get_state().expect("odometry");
    assert!(
        (s[0] - goal[0]).hypot(s[1] - goal[1]) < BASE_POS_TOL,
        "odometry {s:?} for goal {goal:?}"
    );
    assert!(
        wrap(s[2] - goal[2]).abs() < BASE_ROT_TOL,
        "odometry {s:?} for goal {goal:?}"
    );
}

#[test]
fn locobot_base_velocity_and_position_goals() {
    let bot = Robot::new("locobot").expect("robot");
    let base = bot.base().expect("base");
    base.reset_odometry().expect("reset");
    base.set_vel(0.2, 0.0, 1.0).expect("drive");
    let s = base.get_state().expect("odometry");
    assert!((s[0] - 0.2).abs() < 0.03, "{s:?}");
    base.stop().expect("stop");
    base.reset_odometry().expect("reset");
    for goal in [
        [1.0, 0.0, 0.0],
        [1.0, 1.0, std::f64::consts::FRAC_PI_2],
        [0.0, 0.0, 0.0],
        [-0.5, 0.5, 3.0],
    ] {
        bot.base()
            .expect("base")
            .go_to_absolute(goal)
            .expect("reaches");
        base_goal_reached(&bot, goal);
    }
    // Relative: 0.5 m ahead of wherever it stands.
    let start = bot.base().expect("base").get_state().expect("odometry");
    bot.base()
        .expect("base")
        .go_to_relative([0.5, 0.0, 0.0])
        .expect("relative");
    let (s, c) = start[2].sin_cos();
    base_goal_reached(&bot, [start[0] + 0.5 * c, start[1] + 0.5 * s, start[2]]);
    // Over a single 1 m move, ground truth agrees with odometry to within the tolerance (over
    // metres of mixed driving the simulated Kobuki's odometry drifts, as a real one does).
    let bot = Robot::new("locobot").expect("robot");
    bot.base()
        .expect("base")
        .go_to_relative([1.0, 0.0, 0.0])
        .expect("relative");
    let truth = bot.simulator().expect("sim").base_truth().expect("base");
    let odom = bot.base().expect("base").get_state().expect("odometry");
    assert!(
        (truth[0] - odom[0]).hypot(truth[1] - odom[1]) < BASE_POS_TOL,
        "{truth:?} vs {odom:?}"
    );
    assert!(
        (truth[0] - 1.0).abs() < BASE_POS_TOL && wrap(truth[2]).abs() < BASE_ROT_TOL,
        "{truth:?}"
    );
}

#[test]
fn base_motion_is_aborted_by_the_bumper_with_an_error_that_says_so() {
    let bot = Robot::new("locobot").expect("robot");
    common::place_post(&bot, 0.8, 0.0, 0.1);
    let e = bot
        .base()
        .expect("base")
        .go_to_relative([2.0, 0.0, 0.0])
        .expect_err("bumps");
    match &e {
        Error::Fault {
            kind: FaultKind::Bumper,
            detail: Some(d),
        } => assert!(d.contains("centre bumper"), "{e}"),
        other => panic!("{other}"),
    }
    assert!(
        e.to_string().contains("Bumper") && e.to_string().contains("centre bumper"),
        "{e}"
    );
}

#[test]
fn non_blocking_motions_can_be_polled_and_cancelled() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    let mut m = arm
        .move_joints(&[1.2, 0.0, 0.0, 0.0, 0.0], MoveOptions::default())
        .expect("starts");
    let mut polls = 0;
    while m.poll().is_none() {
        polls += 1;
        if polls == 50 {
            break;
        }
    }
    assert!(!m.is_finished());
    m.cancel().expect("cancel");
    bot.wait(1.0).expect("wait");
    let q = bot.arm().expect("arm").get_joint_angles().expect("q")[0];
    assert!(q > 0.05 && q < 1.0, "cancelled halfway, at {q}");
    // A polled motion runs to completion.
    let arm = bot.arm().expect("arm");
    let mut m = arm
        .move_joints(&[0.0; 5], MoveOptions::default())
        .expect("starts");
    let r = loop {
        if let Some(r) = m.poll() {
            break r.is_ok();
        }
    };
    assert!(r);
    let base = bot.base().expect("base");
    let mut m = base.go_to_relative_async([0.3, 0.0, 0.0]).expect("starts");
    for _ in 0..20 {
        m.poll();
    }
    m.cancel().expect("cancel");
    let g = bot.gripper().expect("gripper");
    g.close_async().expect("starts").wait().expect("closes");
}

#[test]
fn bad_input_gives_typed_errors_and_moves_nothing() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    let q0 = arm.get_joint_angles().expect("q");
    assert!(matches!(
        arm.set_joint_positions(&[0.0; 4]),
        Err(Error::JointCount {
            expected: 5,
            got: 4,
            ..
        })
    ));
    assert!(matches!(
        arm.set_joint_positions(&[0.0, f64::NAN, 0.0, 0.0, 0.0]),
        Err(Error::NotFinite { .. })
    ));
    match arm.set_joint_positions(&[0.0, 0.0, 2.0, 0.0, 0.0]) {
        Err(Error::OutOfLimits { joint, .. }) => assert_eq!(joint, "joint_3"),
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        arm.set_joint_velocities(&[5.0, 0.0, 0.0, 0.0, 0.0]),
        Err(Error::OutOfLimits { .. })
    ));
    assert!(matches!(
        arm.set_joint_torques(&[0.0; 6]),
        Err(Error::JointCount { .. })
    ));
    assert!(matches!(
        arm.compute_ik([0.3, 0.0, 0.2], Orientation::Quaternion([0.0; 4]), None),
        Err(Error::OutOfRange { .. })
    ));
    assert!(matches!(
        arm.get_joint_angle("elbow"),
        Err(Error::UnknownName { .. })
    ));
    assert!(max_err(&arm.get_joint_angles().expect("q"), &q0) < JOINT_TOL);
    assert!(matches!(
        bot.base()
            .expect("base")
            .go_to_absolute([f64::INFINITY, 0.0, 0.0]),
        Err(Error::NotFinite { .. })
    ));
    assert!(matches!(
        bot.base().expect("base").set_vel(3.0, 0.0, 1.0),
        Err(Error::OutOfLimits { .. })
    ));
    // Motion during an emergency stop.
    bot.emergency_stop().expect("estop");
    assert!(matches!(
        bot.arm()
            .expect("arm")
            .set_joint_positions(&[0.3, 0.0, 0.0, 0.0, 0.0]),
        Err(Error::EmergencyStop)
    ));
    assert!(matches!(
        bot.base().expect("base").set_vel(0.1, 0.0, 0.5),
        Err(Error::EmergencyStop)
    ));
    assert!(matches!(
        bot.gripper().expect("gripper").close(),
        Err(Error::EmergencyStop)
    ));
    bot.resume().expect("resume");
    bot.arm()
        .expect("arm")
        .set_joint_positions(&[0.3, 0.0, 0.0, 0.0, 0.0])
        .expect("moves again");
    // Unknown robots, missing components.
    assert!(matches!(
        Robot::new("wall-e"),
        Err(Error::UnknownRobot { .. })
    ));
    let sawyer = Robot::new("sawyer").expect("sawyer");
    assert!(matches!(
        sawyer.base(),
        Err(Error::NoComponent {
            component: "base",
            ..
        })
    ));
    assert!(matches!(
        sawyer.gripper(),
        Err(Error::NoComponent {
            component: "gripper",
            ..
        })
    ));
    assert!(sawyer
        .arm()
        .expect("arm")
        .set_ee_pose_pitch_roll([0.5, 0.0, 0.3], 0.0, None)
        .is_err());
    let no_base = Robot::builder("locobot")
        .use_base(false)
        .build()
        .expect("robot");
    assert!(matches!(
        no_base.base(),
        Err(Error::NoComponent {
            component: "base",
            ..
        })
    ));
}

#[test]
fn sawyer_joint_control_and_ik() {
    let bot = Robot::new("sawyer").expect("robot");
    let arm = bot.arm().expect("arm");
    arm.go_home().expect("home");
    let home = [0.002, -1.182, 0.002, 2.177, 0.001, 0.567, 3.316];
    assert!(max_err(&arm.get_joint_angles().expect("q"), &home) < JOINT_TOL);
    let target = [0.3, -0.8, 0.4, 1.6, -0.5, 0.9, 2.5];
    let pose = arm.compute_fk_position(&target, "right_hand").expect("fk");
    arm.set_ee_pose(pose.position, Orientation::Matrix(pose.rotation))
        .expect("moves");
    let got = arm.get_ee_pose().expect("pose");
    assert!(
        pos_err(&got.position, &pose.position) < EE_POS_TOL,
        "{got:?}"
    );
    assert!(
        rot_err(&got.rotation, &pose.rotation) < EE_ROT_TOL,
        "{got:?} {pose:?} {:?}",
        arm.get_joint_angles()
    );
    arm.move_ee_xyz([0.0, 0.0, -0.1], 0.02).expect("line down");
    let after = arm.get_ee_pose().expect("pose");
    assert!(
        pos_err(
            &after.position,
            &[got.position[0], got.position[1], got.position[2] - 0.1]
        ) < EE_POS_TOL
    );
}

#[test]
fn builder_overrides_and_config_files() {
    let bot = Robot::builder("locobot")
        .set("arm.joint_tolerance", 0.002)
        .build()
        .expect("robot");
    assert_eq!(
        bot.config().arm.as_ref().expect("arm").joint_tolerance,
        0.002
    );
    bot.arm()
        .expect("arm")
        .set_joint_positions(&[0.1, 0.1, 0.1, 0.1, 0.1])
        .expect("moves");
    let q = bot.arm().expect("arm").get_joint_angles().expect("q");
    assert!(max_err(&q, &[0.1; 5]) < 0.002 + 1e-9, "{q:?}");
    let e = Robot::builder("locobot")
        .set("arm.speed", 3.0)
        .build()
        .expect_err("unknown key");
    assert!(
        e.to_string().contains("arm") && e.to_string().contains("speed"),
        "{e}"
    );
    // Any robot given by a URDF and a TOML file.
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    std::fs::write(
        dir.join("mybot.urdf"),
        include_str!("../../../description/robots/locobot_lite.urdf"),
    )
    .expect("urdf");
    let toml = include_str!("../../../description/robots/locobot_lite.toml")
        .replace("name = \"locobot_lite\"", "name = \"mybot\"")
        .replace("locobot_lite.urdf", "mybot.urdf");
    std::fs::write(dir.join("mybot.toml"), toml).expect("toml");
    let bot = Robot::from_config(dir.join("mybot.toml")).expect("custom robot");
    assert_eq!(bot.name(), "mybot");
    bot.arm()
        .expect("arm")
        .set_joint_positions(&[0.2, 0.0, 0.0, 0.0, 0.0])
        .expect("moves");
}

#[test]
fn a_blocked_joint_is_reported_stalled_and_a_slow_one_times_out() {
    let bot = Robot::new("locobot").expect("robot");
    // Something blocks joint_1 at 0.2 rad.
    bot.simulator()
        .expect("sim")
        .hw
        .chain
        .servo_mut(1)
        .expect("servo")
        .obstacle = Some((0.2, false));
    match bot
        .arm()
        .expect("arm")
        .set_joint_positions(&[0.8, 0.0, 0.0, 0.0, 0.0])
    {
        Err(Error::Stalled {
            joint,
            position,
            error,
        }) => {
            assert_eq!(joint, "joint_1");
            assert!(
                (position - 0.2).abs() < 0.1 && error > 0.4,
                "{position} {error}"
            );
        }
        other => panic!("{other:?}"),
    }
    bot.simulator()
        .expect("sim")
        .hw
        .chain
        .servo_mut(1)
        .expect("servo")
        .obstacle = None;
    let opts = MoveOptions {
        timeout: Some(std::time::Duration::from_millis(300)),
        ..Default::default()
    };
    match bot
        .arm()
        .expect("arm")
        .set_joint_positions_with(&[-1.0, 0.0, 0.0, 0.0, 0.0], opts)
    {
        Err(Error::Timeout { after, .. }) => {
            assert_eq!(after, std::time::Duration::from_millis(300))
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn realtime_pacing_follows_the_wall_clock() {
    let bot = Robot::builder("locobot")
        .use_base(false)
        .backend(ferrobot::Backend::Sim {
            seed: 1,
            realtime: true,
        })
        .build()
        .expect("robot");
    // Pacing keeps simulated time from running ahead of the wall clock since the link
    // started, and lets it catch up after a delay. The robot's set-up after that start, on a
    // busy machine, can leave it behind: a first wait brings it level (it sleeps off what it
    // is ahead) before the measured one.
    bot.wait(0.2).expect("wait");
    let (sim0, wall0) = (bot.time(), std::time::Instant::now());
    bot.wait(0.3).expect("wait");
    let sim = bot.time() - sim0;
    let wall = wall0.elapsed().as_secs_f64();
    assert!((sim - 0.3).abs() < 0.002, "{sim}");
    assert!((0.29..0.6).contains(&wall), "0.3 s simulated took {wall} s");
}

/// A Cartesian line of 100 waypoints: far more than the firmware's queue holds (16 knots per
/// joint), streamed as the queue makes room; it ends on the line's end and keeps the gripper's
/// orientation, and a track whose last state is NaN is refused without moving.
#[test]
fn a_long_cartesian_line_streams_through_the_firmware_queue() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    arm.set_ee_pose_pitch_roll([0.3, 0.0, 0.2], std::f64::consts::FRAC_PI_2, Some(0.0))
        .expect("start pose");
    let before = arm.get_ee_pose().expect("pose");
    arm.move_ee_xyz([0.0, 0.0, -0.05], 0.0005)
        .expect("100 waypoints");
    let after = arm.get_ee_pose().expect("pose");
    let want = [
        before.position[0],
        before.position[1],
        before.position[2] - 0.05,
    ];
    assert!(
        pos_err(&after.position, &want) < EE_POS_TOL,
        "{after:?} vs {want:?}"
    );
    assert!(
        rot_err(&after.rotation, &before.rotation) < EE_ROT_TOL,
        "{:?} vs {:?}: {}",
        after.rotation,
        before.rotation,
        rot_err(&after.rotation, &before.rotation)
    );
    let mut r =
        ferrobot::base_control::Reference::circle([0.0; 3], 0.1, 0.2, 2.0, 0.1).expect("reference");
    if let Some(x) = r.states.last_mut() {
        x[2] = f64::NAN;
    }
    let e = bot
        .base()
        .expect("base")
        .track_trajectory(r, true)
        .expect_err("NaN state");
    assert!(matches!(e, Error::NotFinite { .. }), "{e}");
}
