//! Arm planning through the API, in the simulator: motions around objects of the planning
//! scene, trajectories within the joints' limits, the executed motion on the planned path,
//! PyRobot's MoveIt examples, and the typed failures.

use ferrobot::arm_plan::ArmTrajectory;
use ferrobot::planning::{self as planning, CheckOptions, Checker, CollisionModel};
use ferrobot::{Error, Orientation, Robot};
use std::sync::Arc;

const IDENTITY: Orientation = Orientation::Quaternion([0.0, 0.0, 0.0, 1.0]);
/// The gripper pointing down.
const DOWN: Orientation = Orientation::YawPitchRoll([0.0, std::f64::consts::FRAC_PI_2, 0.0]);

/// A post in front of the LoCoBot's arm, between a left and a right reach: the arm moved to
/// the left one; the right one returned.
fn left_of_a_post(bot: &Robot) -> [f64; 5] {
    let arm = bot.arm().expect("arm");
    arm.add_world_object("post", [0.3, 0.0, 0.15], IDENTITY, [0.04, 0.04, 0.3])
        .expect("post");
    arm.set_joint_positions(&[0.9, 0.6, 0.3, 0.4, 0.0])
        .expect("to the left");
    [-0.9, 0.6, 0.3, 0.4, 0.0]
}

/// Every edge of the path re-checked at 1 mm of link motion against the exact geometry, in a
/// checker built independently of the robot's.
fn assert_path_free(bot: &Robot, scene: &planning::PlanningScene, traj: &ArmTrajectory) {
    let model = Arc::new(CollisionModel::from_config(bot.config()).expect("model"));
    let fine = Checker::new(
        model,
        scene,
        CheckOptions {
            resolution: 0.001,
            max_step: 0.001,
            min_step: 0.001,
            padding: 0.0,
        },
    )
    .expect("checker");
    for w in traj.path.windows(2) {
        assert!(fine.motion_free(&w[0], &w[1]), "edge {w:?} collides");
    }
}

#[allow(clippy::needless_range_loop)]
/// Velocity and acceleration limits at every 1 ms sample, 1 % of slack for the sampling.
fn assert_within_limits(bot: &Robot, traj: &ArmTrajectory) {
    let cfg = bot.config();
    let arm = cfg.arm.as_ref().expect("arm");
    let vmax: Vec<f64> = arm
        .joints
        .iter()
        .map(|n| {
            f64::from(
                cfg.joints[cfg.joint_index(n).expect("joint")]
                    .limits
                    .velocity,
            )
        })
        .collect();
    let mut t = 0.0;
    while t <= traj.duration() {
        let p = traj.trajectory.sample(t);
        for j in 0..vmax.len() {
            assert!(
                p.velocity[j].abs() <= vmax[j] * 1.01,
                "t {t}: joint {j} speed {}",
                p.velocity[j]
            );
            assert!(
                p.acceleration[j].abs() <= arm.acceleration[j] * 1.01,
                "t {t}: joint {j} acceleration {}",
                p.acceleration[j]
            );
        }
        t += 0.001;
    }
}

#[test]
fn the_arm_plans_around_a_post_within_its_limits_and_follows_the_plan() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    let right = left_of_a_post(&bot);
    let traj = arm.make_plan_joint_positions(&right).expect("plan");
    assert!(
        traj.path.len() >= 3,
        "the plan goes around: {:?}",
        traj.path
    );
    let mut scene = planning::PlanningScene::new();
    scene
        .add_object(
            "post",
            planning::Shape::Box([0.04, 0.04, 0.3]),
            bot.link_transform("base_link", "base_footprint")
                .expect("base")
                * nalgebra::Isometry3::translation(0.3, 0.0, 0.15),
        )
        .expect("post");
    assert_within_limits(&bot, &traj);
    // Executing it: the measured joints stay within 1 cm (mapped to the end effector) of the
    // planned trajectory at the time (allowing the servos' lag of one knot period).
    let motion = arm.execute(&traj).expect("execute");
    let chain = ferrobot::profile::arm_chain(bot.config()).expect("chain");
    let t0 = bot.time();
    let mut worst = 0.0f64;
    while !motion.is_finished() {
        bot.wait(0.02).expect("wait");
        let q = arm.get_joint_angles().expect("joints");
        let t = bot.time() - t0;
        let here = chain.fk(&q).translation.vector;
        // Nearest point of the planned motion within ±0.1 s.
        let mut best = f64::INFINITY;
        let mut s = (t - 0.1).max(0.0);
        while s <= t + 0.1 {
            let p = chain
                .fk(&traj.trajectory.sample(s).position)
                .translation
                .vector;
            best = best.min((p - here).norm());
            s += 0.005;
        }
        worst = worst.max(best);
    }
    motion.wait().expect("arrives");
    eprintln!(
        "executed motion: worst distance from the plan {:.4} m",
        worst
    );
    assert!(worst < 0.01, "{worst} m from the plan");
    let q = arm.get_joint_angles().expect("joints");
    for (a, b) in q.iter().zip(&right) {
        assert!((a - b).abs() < 0.02, "{q:?}");
    }
    assert_path_free(&bot, &scene, &traj);
}

/// The arm's `planning_range` (`[arm]` of its configuration) is the planner's extension step
/// unless the caller gives one: the same problem and seed give the same path as that range
/// given explicitly, and another path with OMPL's default (a fifth of the joint box's
/// diagonal).
#[test]
fn the_configured_planning_range_is_the_default_step() {
    use ferrobot::arm_plan::PlanningOptions;
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    let right = left_of_a_post(&bot);
    let range = bot
        .config()
        .arm
        .as_ref()
        .and_then(|a| a.planning_range)
        .expect("the LoCoBot's configuration sets one");
    let with = |range: Option<f64>| {
        let mut o = PlanningOptions::default();
        o.plan.range = range;
        arm.plan_to(&right, &o).expect("plan").path
    };
    let by_default = with(None);
    assert_eq!(by_default, with(Some(range)));
    let model = CollisionModel::from_config(bot.config()).expect("model");
    let fifth = 0.2
        * model
            .limits()
            .iter()
            .map(|(lo, hi)| (hi - lo).powi(2))
            .sum::<f64>()
            .sqrt();
    assert_ne!(by_default, with(Some(fifth)));
}

#[test]
fn move_ee_xyz_down_from_home_as_pyrobots_moveit_example() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    arm.go_home().expect("home");
    let before = arm.get_ee_pose().expect("pose");
    arm.move_ee_xyz([0.0, 0.0, -0.15], 0.01).expect("down");
    let after = arm.get_ee_pose().expect("pose");
    let want = [
        before.position[0],
        before.position[1],
        before.position[2] - 0.15,
    ];
    let err: f64 = (0..3)
        .map(|i| (after.position[i] - want[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(err < 0.02, "{err} m");
    // Orientation similarity (|⟨q1, q2⟩|) above 0.98, as PyRobot's test asks.
    let dot: f64 = (0..4)
        .map(|i| before.quaternion[i] * after.quaternion[i])
        .sum::<f64>()
        .abs();
    assert!(dot > 0.98, "{dot}");
}

#[test]
fn set_ee_pose_around_a_table_and_an_attached_object() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    arm.add_table([0.45, 0.0, 0.1], [0.3, 0.8, 0.1])
        .expect("table");
    arm.set_ee_pose_pitch_roll([0.4, 0.0, 0.3], std::f64::consts::FRAC_PI_2, Some(0.0))
        .expect("above the table");
    assert!(arm.get_collision_state().expect("state").is_none());
    arm.attach_arm_object("held", [0.12, 0.0, 0.0], IDENTITY, [0.04, 0.04, 0.04])
        .expect("attach");
    // The held box (12 cm below the gripper's frame) may not go into the table; the gripper
    // alone, 12 cm above the table top, may.
    let low = arm.compute_ik([0.4, 0.0, 0.22], DOWN, None).expect("ik");
    match arm.make_plan_joint_positions(&low) {
        Err(Error::Planning(planning::Error::GoalInCollision { a, b })) => {
            assert!(a == "held" || b == "held", "{a} {b}");
        }
        other => panic!("expected the held box in collision, got {other:?}"),
    }
    arm.detach_arm_object("held").expect("detach");
    arm.make_plan_joint_positions(&low)
        .expect("free without the box");
    // PyRobot's set_ee_pose with a full orientation, over the table.
    let want = [0.38, 0.05, 0.25];
    arm.set_ee_pose(want, DOWN).expect("set_ee_pose");
    let got = arm.get_ee_pose().expect("pose");
    let err: f64 = (0..3)
        .map(|i| (got.position[i] - want[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(err < 0.01, "{err} m");
    assert!(arm.get_collision_state().expect("state").is_none());
}

/// A point cloud's voxels are obstacles like any other: a goal among them is refused, naming
/// the voxel, and the goal is free again when they are gone.
#[test]
fn point_cloud_voxels_are_obstacles() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    let goal = arm.compute_ik([0.3, 0.0, 0.15], DOWN, None).expect("ik");
    let here = arm
        .compute_fk_position(&goal, "gripper_link")
        .expect("fk")
        .position;
    // A 10 cm cube of points around the goal's gripper, 1 cm apart.
    let mut cloud = Vec::new();
    for i in 0..10 {
        for j in 0..10 {
            for k in 0..10 {
                cloud.push([
                    here[0] - 0.05 + 0.01 * f64::from(i),
                    here[1] - 0.05 + 0.01 * f64::from(j),
                    here[2] - 0.05 + 0.01 * f64::from(k),
                ]);
            }
        }
    }
    arm.set_point_cloud(Some(&cloud), 0.02).expect("voxels");
    match arm.make_plan_joint_positions(&goal) {
        Err(Error::Planning(planning::Error::GoalInCollision { b, .. })) => {
            assert!(b.starts_with("voxel"), "{b}")
        }
        other => panic!("{other:?}"),
    }
    arm.set_point_cloud(None, 0.02).expect("no voxels");
    arm.make_plan_joint_positions(&goal).expect("free again");
    // The same cube in 5 mm voxels with two points 900 m out (a box of about 10¹⁷ cells: the
    // checker keeps the cells as a list) is still in the way.
    cloud.push([900.0, -900.0, 900.0]);
    cloud.push([-900.0, 900.0, -900.0]);
    arm.set_point_cloud(Some(&cloud), 0.005)
        .expect("voxels spread far");
    match arm.make_plan_joint_positions(&goal) {
        Err(Error::Planning(planning::Error::GoalInCollision { b, .. })) => {
            assert!(b.starts_with("voxel"), "{b}")
        }
        other => panic!("{other:?}"),
    }
    assert!(arm.get_collision_state().expect("state").is_none());
    arm.set_point_cloud(None, 0.02).expect("no voxels");
}

#[test]
fn planning_failures_are_typed() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    for (size, pos) in [
        ([-0.1, 0.1, 0.1], [0.3, 0.0, 0.1]),
        ([0.1, f64::NAN, 0.1], [0.3, 0.0, 0.1]),
        ([0.1, 0.1, 0.1], [f64::INFINITY, 0.0, 0.1]),
        ([1e9, 0.1, 0.1], [0.3, 0.0, 0.1]),
    ] {
        let e = arm
            .add_world_object("bad", pos, IDENTITY, size)
            .unwrap_err();
        assert!(e.is_input(), "{e}");
    }
    assert!(arm
        .add_world_object("", [0.3, 0.0, 0.1], IDENTITY, [0.1; 3])
        .is_err());
    assert!(arm.remove_world_object("nothing").unwrap_err().is_input());
    assert!(arm.detach_arm_object("nothing").is_err());
    // A goal inside an object.
    arm.add_world_object("block", [0.3, 0.0, 0.1], IDENTITY, [0.1, 0.2, 0.2])
        .expect("block");
    let goal = arm.compute_ik([0.3, 0.0, 0.15], DOWN, None).expect("ik");
    match arm.make_plan_joint_positions(&goal) {
        Err(Error::Planning(planning::Error::GoalInCollision { b, .. })) => assert_eq!(b, "block"),
        other => panic!("{other:?}"),
    }
    // A pose inside the block: no collision-free IK solution.
    match arm.make_plan_pose([0.3, 0.0, 0.15], DOWN) {
        Err(Error::Planning(planning::Error::NoFreeIk { .. })) | Err(Error::Unreachable { .. }) => {
        }
        other => panic!("{other:?}"),
    }
    // An unreachable pose.
    assert!(arm.make_plan_pose([2.0, 0.0, 0.2], IDENTITY).is_err());
    // The start in collision: the arm moved into the block without planning.
    arm.remove_all_objects().expect("clear");
    let q = arm.get_joint_angles().expect("q");
    let here = arm.compute_fk_position(&q, "gripper_link").expect("fk");
    arm.add_world_object("around", here.position, IDENTITY, [0.05; 3])
        .expect("around");
    let c = arm
        .get_collision_state()
        .expect("state")
        .expect("a contact");
    assert_eq!(c.b, "around");
    match arm.make_plan_joint_positions(&[0.5, 0.0, 0.0, 0.0, 0.0]) {
        Err(Error::Planning(planning::Error::StartInCollision { b, .. })) => {
            assert_eq!(b, "around")
        }
        other => panic!("{other:?}"),
    }
    assert!(arm.make_plan_joint_positions(&[0.0; 4]).is_err());
    assert!(arm.make_plan_joint_positions(&[f64::NAN; 5]).is_err());
    assert!(arm.make_plan_joint_positions(&[9.0; 5]).is_err());
}

/// Executing planned motions among the tabletop's objects (imported from the simulated world)
/// makes no contact between the arm and anything in the physics engine.
#[test]
fn planned_motions_in_the_tabletop_touch_nothing_in_the_physics_engine() {
    let bot = Robot::builder("locobot")
        .scene("tabletop")
        .build()
        .expect("robot");
    let arm = bot.arm().expect("arm");
    assert!(arm.add_scene_objects().expect("objects") > 5);
    let links = [
        "shoulder_link",
        "elbow_link",
        "forearm_link",
        "wrist_link",
        "gripper_link",
        "finger_r",
        "finger_l",
        "ar_tag",
    ];
    bot.simulator()
        .expect("simulator")
        .hw
        .watch_robot_contacts(&links)
        .expect("watch");
    let down = std::f64::consts::FRAC_PI_2;
    // Above the objects, from one side of the table to the other, and back home.
    let mut moves = 0;
    for target in [
        [0.36, 0.0, 0.26],
        [0.34, 0.15, 0.26],
        [0.34, -0.15, 0.26],
        [0.4, 0.08, 0.24],
        [0.4, -0.08, 0.24],
    ] {
        arm.set_ee_pose_pitch_roll(target, down, Some(0.0))
            .unwrap_or_else(|e| panic!("to {target:?}: {e}"));
        moves += 1;
    }
    // Joint targets low over the table's sides.
    for q in [[0.9, 0.1, 0.3, 0.6, 0.0], [-0.9, 0.1, 0.3, 0.6, 0.0]] {
        arm.set_joint_positions(&q).expect("joint target");
        moves += 1;
    }
    arm.go_home().expect("home");
    let contacts = bot.simulator().expect("simulator").hw.take_robot_contacts();
    eprintln!(
        "{moves} planned motions and home: {} contacts",
        contacts.len()
    );
    assert!(contacts.is_empty(), "{contacts:?}");
}

/// The LoCoBot's arm moved without planning to where two of its own links touch (as
/// one that sagged while its servos were off).
fn sag(arm: &ferrobot::arm::Arm) {
    arm.set_joint_positions_with(
        &[0.0, 1.55, 0.0, 0.0, 0.0],
        ferrobot::MoveOptions {
            plan: false,
            ..Default::default()
        },
    )
    .expect("sag");
}

/// An arm that starts with two of its own links touching (as one that sagged while its servos
/// were off) still plans out; a start touching an object stays an error (see above).
#[test]
fn a_start_in_self_collision_is_left() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    sag(&arm);
    let c = arm.get_collision_state().expect("state");
    assert!(c.is_some(), "the sagged arm touches itself");
    arm.set_joint_positions(&[0.0; 5]).expect("plans out");
}

/// A goal where the start's self-contact persists is refused (the pairs a start in
/// self-contact is allowed were once unchecked for the whole plan, goal included).
#[test]
fn a_start_in_self_collision_may_not_end_in_it() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    sag(&arm);
    let c = arm.get_collision_state().expect("state").expect("touching");
    // Turning the base joint keeps the same two links touching.
    match arm.make_plan_joint_positions(&[0.3, 1.55, 0.0, 0.0, 0.0]) {
        Err(Error::Planning(planning::Error::GoalInCollision { a, b })) => {
            assert_eq!((a.as_str(), b.as_str()), (c.a.as_str(), c.b.as_str()))
        }
        other => panic!("{other:?}"),
    }
    arm.make_plan_joint_positions(&[0.0; 5]).expect("plans out");
}

/// `execute` runs a trajectory only while it holds: one planned before the arm moved, or
/// before an object was put on its path, is `StalePlan`; malformed ones (other joints, an
/// empty path, 13 joints, ends that differ from the path's) are typed errors, never a panic;
/// the same trajectory, fresh, runs.
#[test]
fn execute_refuses_stale_and_malformed_trajectories() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    let right = left_of_a_post(&bot);
    let traj = arm.make_plan_joint_positions(&right).expect("plan");
    // An object across the planned path (at its middle waypoint's gripper).
    let mid = &traj.path[traj.path.len() / 2];
    let p = arm
        .compute_fk_position(mid, "gripper_link")
        .expect("fk")
        .position;
    arm.add_world_object("dropped", p, IDENTITY, [0.08, 0.08, 0.08])
        .expect("object");
    match arm.execute(&traj) {
        Err(Error::StalePlan { why }) => assert!(why.contains("touches"), "{why}"),
        other => panic!("{other:?}"),
    }
    arm.remove_world_object("dropped").expect("removed");
    // Malformed.
    let mut other = traj.clone();
    other.joints[0] = "joint_9".into();
    let mut empty = traj.clone();
    empty.path.clear();
    let mut wide = traj.clone();
    for q in &mut wide.path {
        q.resize(13, 0.0);
    }
    let mut bent = traj.clone();
    let n = bent.path.len();
    bent.path[n - 1][0] += 0.1;
    for (what, bad) in [
        ("joints", other),
        ("empty", empty),
        ("13", wide),
        ("ends", bent),
    ] {
        match arm.execute(&bad) {
            Err(Error::Planning(planning::Error::Invalid { .. }) | Error::JointCount { .. }) => {}
            other => panic!("{what}: {other:?}"),
        }
    }
    // The arm moves elsewhere: the plan's start is stale.
    arm.set_joint_positions_with(
        &[0.9, 0.3, 0.3, 0.4, 0.0],
        ferrobot::MoveOptions {
            plan: false,
            ..Default::default()
        },
    )
    .expect("moved");
    match arm.execute(&traj) {
        Err(Error::StalePlan { why }) => assert!(why.contains("rad from"), "{why}"),
        other => panic!("{other:?}"),
    }
    arm.set_joint_positions_with(
        &traj.path[0],
        ferrobot::MoveOptions {
            plan: false,
            ..Default::default()
        },
    )
    .expect("back");
    arm.execute(&traj).expect("fresh").wait().expect("runs");
}

/// An object may not take a link's name (a contact names its two bodies): adding or attaching
/// one is an error that adds nothing.
#[test]
fn objects_named_as_links_are_refused() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    for r in [
        arm.add_world_object("gripper_link", [0.4, 0.0, 0.1], IDENTITY, [0.05; 3]),
        arm.attach_arm_object("elbow_link", [0.0; 3], IDENTITY, [0.02; 3]),
    ] {
        match r {
            Err(Error::Planning(planning::Error::Invalid { what, why })) => {
                assert!(
                    what.contains("_link") && why.contains("link"),
                    "{what}: {why}"
                )
            }
            other => panic!("{other:?}"),
        }
    }
    assert!(arm.get_collision_state().expect("state").is_none());
    assert!(
        arm.remove_world_object("gripper_link").is_err(),
        "nothing was added"
    );
}
