//! Owned motions: the base, the arm and the head move at the same time, one can be cancelled
//! while the others run on, a newer motion of a component preempts the older, and a robot is
//! driven from two threads. All on the in-process simulator (virtual time).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;

use ferrobot::{Error, Motion, MoveOptions, Robot};

const ARM_TARGET: [f64; 5] = [0.4, 0.3, -0.5, 0.6, -0.3];
const PAN_TILT: [f64; 2] = [0.5, 0.3];

/// The base's pose by odometry and by ground truth.
fn base_poses(bot: &Robot) -> ([f64; 3], [f64; 3]) {
    let odom = bot.base().expect("base").get_state().expect("odometry");
    let truth = bot
        .simulator()
        .expect("sim")
        .base_truth()
        .expect("base truth");
    (odom, truth)
}

/// Largest joint error of the arm from `target`, rad.
fn arm_error(bot: &Robot, target: &[f64]) -> f64 {
    let q = bot.arm().expect("arm").get_joint_angles().expect("q");
    q.iter()
        .zip(target)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

/// How long (simulated s) each motion takes alone, on a robot of its own.
fn alone() -> (f64, f64, f64) {
    let bot = Robot::new("locobot").expect("robot");
    let t0 = bot.time();
    bot.base()
        .expect("base")
        .go_to_relative([1.0, 0.0, 0.0])
        .expect("base alone");
    let base = bot.time() - t0;
    let t0 = bot.time();
    bot.arm()
        .expect("arm")
        .set_joint_positions(&ARM_TARGET)
        .expect("arm alone");
    let arm = bot.time() - t0;
    let t0 = bot.time();
    bot.head()
        .expect("camera")
        .set_pan_tilt(PAN_TILT[0], PAN_TILT[1])
        .expect("head alone");
    (base, arm, bot.time() - t0)
}

/// Start the base 1 m forward, the arm to [`ARM_TARGET`] and the head to [`PAN_TILT`], in
/// that order, without waiting: (base, arm, head).
fn start_all(bot: &Robot) -> (Motion, Motion, Motion) {
    let base = bot
        .base()
        .expect("base")
        .go_to_relative_async([1.0, 0.0, 0.0])
        .expect("base starts");
    let arm = bot
        .arm()
        .expect("arm")
        .move_joints(&ARM_TARGET, MoveOptions::default())
        .expect("arm starts");
    let head = bot
        .head()
        .expect("camera")
        .set_pan_tilt_async(PAN_TILT[0], PAN_TILT[1])
        .expect("head starts");
    (base, arm, head)
}

#[test]
fn the_base_the_arm_and_the_head_move_at_once() {
    let (base_alone, arm_alone, head_alone) = alone();
    let bot = Robot::new("locobot").expect("robot");
    let t0 = bot.time();
    let (base, arm, head) = start_all(&bot);
    // Wait on the head first: the others go on meanwhile.
    head.wait().expect("head arrives");
    let t_head = bot.time() - t0;
    let mid = base_poses(&bot).0;
    arm.wait().expect("arm arrives");
    let t_arm = bot.time() - t0;
    base.wait().expect("base arrives");
    let t_all = bot.time() - t0;

    // Each ended as it does alone, within 0.3 s (a poll or a few of the finisher's pulses).
    assert!(
        (t_head - head_alone).abs() < 0.3,
        "head {t_head} s, alone {head_alone} s"
    );
    assert!(
        (t_arm - arm_alone).abs() < 0.3,
        "arm {t_arm} s, alone {arm_alone} s"
    );
    assert!(
        (t_all - base_alone).abs() < 0.3,
        "base {t_all} s, alone {base_alone} s"
    );
    // At once, not one after the other: the base was already under way when the head arrived.
    assert!(t_all < base_alone + arm_alone, "{t_all} s");
    assert!(
        mid[0] > 0.005,
        "the base had not moved when the head arrived: {mid:?}"
    );

    // Today's tolerances: arm joints within the configuration's 0.01 rad, the head within
    // 0.01 rad, the base (LQR and the finisher) within 1 mm and 0.1° by odometry and 2 cm of
    // ground truth.
    assert!(arm_error(&bot, &ARM_TARGET) < 0.01);
    let pt = bot.head().expect("camera").get_state().expect("pan/tilt");
    assert!(
        (pt[0] - PAN_TILT[0]).abs() < 0.01 && (pt[1] - PAN_TILT[1]).abs() < 0.01,
        "{pt:?}"
    );
    let (odom, truth) = base_poses(&bot);
    assert!(
        (odom[0] - 1.0).abs() < 1e-3 && odom[1].abs() < 1e-3 && odom[2].abs() < 0.1f64.to_radians(),
        "odometry {odom:?}"
    );
    assert!((truth[0] - 1.0).hypot(truth[1]) < 0.02, "truth {truth:?}");
}

#[test]
fn cancelling_one_motion_leaves_the_others_running() {
    let bot = Robot::new("locobot").expect("robot");
    let (base, arm, head) = start_all(&bot);
    bot.wait(0.5).expect("wait");
    let before = arm_error(&bot, &ARM_TARGET);
    let at_cancel = bot.arm().expect("arm").get_joint_angles().expect("q");
    arm.cancel().expect("arm cancelled");
    // The arm stops near where it was cancelled (the servos' lag and the gravity-loaded
    // joints settling: 1 s), then holds, short of its target...
    bot.wait(1.0).expect("wait");
    let held = bot.arm().expect("arm").get_joint_angles().expect("q");
    head.wait().expect("head arrives");
    base.wait()
        .expect("base arrives after the arm was cancelled");
    let after = bot.arm().expect("arm").get_joint_angles().expect("q");
    let largest = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    };
    assert!(before > 0.1, "the arm had nearly arrived: {before}");
    assert!(
        arm_error(&bot, &ARM_TARGET) > 0.05,
        "the cancelled arm went on"
    );
    let stopping = largest(&at_cancel, &held);
    assert!(stopping < 0.05, "the arm took {stopping} rad to stop");
    let moved = largest(&held, &after);
    assert!(moved < 0.005, "the held arm moved {moved} rad");
    // ...while the base and the head reached their goals.
    let (odom, _) = base_poses(&bot);
    assert!((odom[0] - 1.0).abs() < 1e-3, "{odom:?}");
    let pt = bot.head().expect("camera").get_state().expect("pan/tilt");
    assert!((pt[0] - PAN_TILT[0]).abs() < 0.01, "{pt:?}");

    // The other way round: cancel the base, the arm goes on.
    let base = bot
        .base()
        .expect("base")
        .go_to_relative_async([1.0, 0.0, 0.0])
        .expect("base starts");
    let arm = bot
        .arm()
        .expect("arm")
        .move_joints(&[0.0; 5], MoveOptions::default())
        .expect("arm starts");
    bot.wait(1.0).expect("wait");
    let at_cancel = base_poses(&bot).0;
    base.cancel().expect("base cancelled");
    arm.wait()
        .expect("arm arrives after the base was cancelled");
    assert!(arm_error(&bot, &[0.0; 5]) < 0.01);
    // The base decelerates (0.2 m/s at 0.5 m/s²: 4 cm at most) and stays stopped.
    bot.wait(0.5).expect("wait");
    let stopped = base_poses(&bot).0;
    bot.wait(1.0).expect("wait");
    let later = base_poses(&bot).0;
    assert!(
        at_cancel[0] > 1.05 && stopped[0] - at_cancel[0] < 0.04,
        "the cancelled base went on from {at_cancel:?} to {stopped:?}"
    );
    assert!(
        (later[0] - stopped[0]).abs() < 1e-3,
        "the cancelled base kept moving: {stopped:?} -> {later:?}"
    );
}

#[test]
fn a_newer_motion_of_a_component_preempts_the_older() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    let first = arm
        .move_joints(&ARM_TARGET, MoveOptions::default())
        .expect("first starts");
    bot.wait(0.3).expect("wait");
    let second = arm
        .move_joints(&[0.0; 5], MoveOptions::default())
        .expect("second starts");
    assert!(
        matches!(first.wait(), Err(Error::Preempted { .. })),
        "the first motion was not preempted"
    );
    second.wait().expect("second arrives");
    assert!(arm_error(&bot, &[0.0; 5]) < 0.01);
    // A motion of other joints (the head) does not preempt the arm's.
    let arm_motion = arm
        .move_joints(&ARM_TARGET, MoveOptions::default())
        .expect("arm starts");
    bot.head()
        .expect("camera")
        .set_pan_tilt(0.2, 0.1)
        .expect("head moves");
    arm_motion.wait().expect("the arm motion was not preempted");
}

#[test]
fn a_dropped_motion_runs_on() {
    let bot = Robot::new("locobot").expect("robot");
    drop(
        bot.arm()
            .expect("arm")
            .move_joints(&ARM_TARGET, MoveOptions::default())
            .expect("arm starts"),
    );
    bot.wait(5.0).expect("wait");
    assert!(arm_error(&bot, &ARM_TARGET) < 0.01);
}

#[test]
fn one_robot_is_driven_from_two_threads() {
    let bot = Robot::new("locobot").expect("robot");
    let done = Arc::new(AtomicBool::new(false));
    // A monitor reads state while the program moves the robot.
    let monitor = {
        let bot = bot.clone();
        let done = done.clone();
        thread::spawn(move || {
            let mut times = Vec::new();
            let mut last_t = 0.0;
            while !done.load(Ordering::SeqCst) {
                let q = bot
                    .arm()
                    .expect("arm")
                    .get_joint_angles()
                    .expect("joint angles");
                let pose = bot.base().expect("base").get_state().expect("odometry");
                let t = bot.telemetry().expect("telemetry").time_us as f64 * 1e-6;
                assert!(q.len() == 5 && q.iter().chain(&pose).all(|v| v.is_finite()));
                assert!(t >= last_t, "time went back: {last_t} -> {t}");
                if t > last_t {
                    times.push(t);
                }
                last_t = t;
                thread::yield_now();
            }
            times
        })
    };
    // A second commanding thread moves the head while this one moves the arm and the base.
    let head = {
        let bot = bot.clone();
        thread::spawn(move || {
            for k in 0..4 {
                let pan = if k % 2 == 0 { 0.4 } else { -0.4 };
                bot.head()
                    .expect("camera")
                    .set_pan_tilt(pan, 0.2)
                    .expect("head moves");
            }
        })
    };
    bot.arm()
        .expect("arm")
        .set_joint_positions(&ARM_TARGET)
        .expect("arm moves");
    bot.base()
        .expect("base")
        .go_to_relative([0.3, 0.0, 0.0])
        .expect("base moves");
    head.join().expect("head thread");
    done.store(true, Ordering::SeqCst);
    let end = bot.time();
    let times = monitor.join().expect("monitor thread");
    // The monitor read while the robot moved, not only before or after: it saw the clock at
    // several instants, spread over the motions.
    assert!(times.len() >= 3, "the monitor saw the clock at {times:?}");
    assert!(
        times.iter().any(|&t| t > 0.2 * end) && times.iter().any(|&t| t < 0.8 * end),
        "the monitor saw {times:?} of {end} s"
    );
    assert!(arm_error(&bot, &ARM_TARGET) < 0.01);
    let pt = bot.head().expect("camera").get_state().expect("pan/tilt");
    assert!((pt[0] + 0.4).abs() < 0.01, "{pt:?}");
    let odom = bot.base().expect("base").get_state().expect("odometry");
    assert!((odom[0] - 0.3).abs() < 1e-3, "{odom:?}");
}

#[test]
fn robots_and_handles_are_send_and_sync() {
    fn is<T: Send + Sync + Clone>() {}
    is::<Robot>();
    is::<ferrobot::arm::Arm>();
    is::<ferrobot::base::Base>();
    is::<ferrobot::gripper::Gripper>();
    is::<ferrobot::head::Head>();
    is::<ferrobot::camera::Camera>();
    fn send<T: Send>() {}
    send::<ferrobot::Motion>();
}

#[test]
fn a_plan_the_arm_outran_while_another_thread_let_time_pass_is_made_again() {
    // While one thread plans, another lets the simulated time pass, as time passes on a real
    // robot while it plans. The arm is driven by an older, unplanned motion meanwhile: the
    // start the plan was made from is left behind before it could run. The planned motion
    // must start from where the arm is, never refuse itself as stale nor run the old start.
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    let older = arm
        .move_joints(
            &ARM_TARGET,
            MoveOptions {
                plan: false,
                ..MoveOptions::default()
            },
        )
        .expect("older motion starts");
    let done = Arc::new(AtomicBool::new(false));
    let clock = {
        let bot = bot.clone();
        let done = done.clone();
        thread::spawn(move || {
            while !done.load(Ordering::SeqCst) {
                bot.wait(0.002).expect("wait");
            }
        })
    };
    let t0 = bot.time();
    let result = arm.set_joint_positions(&[0.0; 5]);
    let elapsed = bot.time() - t0;
    done.store(true, Ordering::SeqCst);
    clock.join().expect("clock thread");
    result.expect("the planned motion arrives");
    // The older motion arrived before the planned one started, or was preempted by it.
    let older = older.wait();
    assert!(
        matches!(older, Ok(()) | Err(Error::Preempted { .. })),
        "the older motion ended {older:?}"
    );
    assert!(arm_error(&bot, &[0.0; 5]) < 0.01, "ended {elapsed} s later");
}
