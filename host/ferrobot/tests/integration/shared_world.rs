//! Two robots in one simulated world driven by one program ([`ferrobot::SharedWorld`]): one
//! drives into the other and its goal ends with the bumper's typed fault, the other is not
//! pushed; each camera sees the other; two threads move the two arms at once on one clock;
//! a robot placed on another, or a shared world on another backend, is refused.

use std::f64::consts::PI;

use ferrobot::{Backend, Error, FaultKind, Robot, SharedWorld};

/// A LoCoBot joining `world` at `pose` with plants seeded by `seed`.
fn join(world: &SharedWorld, pose: [f64; 3], seed: u64) -> ferrobot::Result<Robot> {
    Robot::builder("locobot")
        .shared_world(world)
        .start_pose(pose)
        .backend(Backend::Sim {
            seed,
            realtime: false,
        })
        .build()
}

/// Two LoCoBots 1.2 m apart facing each other in an empty world.
fn facing() -> (SharedWorld, Robot, Robot) {
    let world = SharedWorld::new("empty").expect("world");
    let a = join(&world, [0.0, 0.0, 0.0], 1).expect("A");
    let b = join(&world, [1.2, 0.0, PI], 2).expect("B");
    (world, a, b)
}

#[test]
fn a_robot_driving_into_another_ends_its_goal_on_the_bumper_and_leaves_the_other() {
    let (world, a, b) = facing();
    let b0 = b.truth().unwrap().root;
    let e = a
        .base()
        .unwrap()
        .go_to_relative([1.0, 0.0, 0.0])
        .expect_err("B is in the way");
    match &e {
        Error::Fault {
            kind: FaultKind::Bumper,
            ..
        } => {}
        other => panic!("{other}"),
    }
    // A stopped against B's plate (0.247 m ahead of B's centre at bumper height) with its
    // bumper ring (0.177 m): 0.424 m apart, within the bumper's travel and a few steps.
    let xa = a.truth().unwrap().root.translation.x;
    let gap = 1.2 - xa;
    println!("A stopped {gap:.4} m from B's centre: {e}");
    assert!((gap - 0.4243).abs() < 0.005, "gap {gap}");
    assert_eq!(b.truth().unwrap().root, b0, "B was pushed");
    // One clock: both robots' time is the world's.
    assert!((a.time() - world.time()).abs() < 1e-6 && (b.time() - world.time()).abs() < 1e-6);
    assert_eq!(world.robots(), 2);
    assert_eq!(world.truth(0).unwrap().others.len(), 1);
}

/// The median depth (m) of the 21 × 21 pixels at the centre of `robot`'s depth image, valid
/// pixels only (0 when none is).
fn centre_depth(robot: &Robot) -> f32 {
    let d = robot.camera().unwrap().get_depth().unwrap();
    let (w, h) = (d.width as usize, d.height as usize);
    let mut v: Vec<f32> = (h / 2 - 10..=h / 2 + 10)
        .flat_map(|r| (w / 2 - 10..=w / 2 + 10).map(move |c| (r, c)))
        .filter_map(|(r, c)| d.get(r, c))
        .filter(|z| *z > 0.0)
        .collect();
    v.sort_by(f32::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

#[test]
fn each_robots_camera_sees_the_other() {
    let (_world, a, b) = facing();
    for bot in [&a, &b] {
        bot.head().unwrap().set_pan_tilt(0.0, 0.1).unwrap();
    }
    let (da, db) = (centre_depth(&a), centre_depth(&b));
    // The other's mast and plates stand 1.2 m away less their reach towards the camera; the
    // camera sits behind its own base's centre.
    println!("centre depth: A sees {da} m, B sees {db} m");
    for d in [da, db] {
        assert!((0.7..1.4).contains(&d), "{d}");
    }
    // Alone in the same world, the same view reaches beyond where the other stood.
    let world = SharedWorld::new("empty").expect("world");
    let alone = join(&world, [0.0, 0.0, 0.0], 1).expect("alone");
    alone.head().unwrap().set_pan_tilt(0.0, 0.1).unwrap();
    let d = centre_depth(&alone);
    println!("alone: {d} m");
    assert!(d == 0.0 || d > 1.5, "{d}");
}

#[test]
fn two_threads_move_two_arms_at_once_on_one_clock() {
    let (world, a, b) = facing();
    let targets = [[0.4, 0.3, -0.3, 0.2, 0.0], [-0.4, 0.2, 0.3, -0.2, 0.0]];
    let t0 = world.time();
    std::thread::scope(|s| {
        for (bot, q) in [(&a, targets[0]), (&b, targets[1])] {
            s.spawn(move || bot.arm().unwrap().set_joint_positions(&q).unwrap());
        }
    });
    for (bot, q) in [(&a, targets[0]), (&b, targets[1])] {
        let got = bot.arm().unwrap().get_joint_angles().unwrap();
        for (g, w) in got.iter().zip(q) {
            assert!((g - w).abs() < 0.02, "{got:?} vs {q:?}");
        }
    }
    // Both waited on one clock: the world's time passed once for both motions (each about
    // 2-4 s), not once per robot one after the other beyond it.
    let dt = world.time() - t0;
    println!("both arms moved in {dt:.2} s of world time");
    assert!(dt < 10.0, "{dt}");
    assert!((a.time() - b.time()).abs() < 1e-6);
}

#[test]
fn a_robot_placed_on_another_or_off_the_simulator_is_refused_typed() {
    let (world, _a, _b) = facing();
    match join(&world, [0.1, 0.0, 0.0], 3) {
        Err(Error::Scene(e)) => assert!(e.to_string().contains("robot 0"), "{e}"),
        Err(other) => panic!("{other}"),
        Ok(_) => panic!("joined on top of robot 0"),
    }
    assert_eq!(world.robots(), 2);
    for pose in [
        [f64::NAN, 0.0, 0.0],
        [0.0, f64::INFINITY, 0.0],
        [3.0, 0.0, 1e300],
    ] {
        match join(&world, pose, 4) {
            Err(e) => assert!(
                matches!(e, Error::NotFinite { .. } | Error::OutOfRange { .. }),
                "{pose:?}: {e}"
            ),
            Ok(_) => panic!("{pose:?} joined"),
        }
    }
    #[cfg(feature = "emulated")]
    {
        let e = Robot::builder("locobot")
            .shared_world(&world)
            .backend(Backend::DirectEmulated)
            .build()
            .expect_err("refused");
        assert!(matches!(e, Error::Usage(_)), "{e}");
    }
    assert_eq!(world.robots(), 2);
}

/// One thread: only A waits, and B's motions (a closed-loop base goal, an arm move) run to
/// their ends meanwhile, stepped by A's waits as by B's own.
#[test]
fn one_robots_wait_steps_the_others_motions() {
    let (_world, a, b) = facing();
    let start = b.truth().unwrap().root.translation.vector;
    // B faces −x: half a metre back takes it to x = 1.7 m.
    let drive = b
        .base()
        .unwrap()
        .go_to_relative_async([-0.5, 0.0, 0.0])
        .unwrap();
    let q = [0.4, 0.3, -0.3, 0.2, 0.0];
    let arm = b
        .arm()
        .unwrap()
        .move_joints(&q, ferrobot::MoveOptions::default())
        .unwrap();
    a.wait(8.0).unwrap();
    assert!(drive.is_finished() && arm.is_finished());
    drive.wait().expect("B's drive ended well");
    arm.wait().expect("B's arm move ended well");
    let moved = b.truth().unwrap().root.translation.vector - start;
    println!("B moved {moved:?} while only A waited");
    assert!(
        (moved.x - 0.5).abs() < 0.02 && moved.y.abs() < 0.02,
        "{moved:?}"
    );
    let got = b.arm().unwrap().get_joint_angles().unwrap();
    for (g, w) in got.iter().zip(q) {
        assert!((g - w).abs() < 0.02, "{got:?}");
    }
}
