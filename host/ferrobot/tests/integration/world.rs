//! The world through the public API on the simulator backend: the base stops at a wall with
//! the bumper fault, the gripper grasps, lifts and drops a cube, an object where the robot
//! stands is a typed error. (The same physics through the firmware in QEMU:
//! `hil-tests/tests/hil.rs`; at the plants' level: `sim-stubs/tests/integration/physics.rs`.)

use std::f64::consts::FRAC_PI_2;

use ferrobot::{Error, GripperState, Robot};
use ferrobot_protocol::FaultKind;
use nalgebra::Vector3;

/// A scene file in a scratch directory removed with the guard.
fn scene_file(name: &str, text: &str) -> (tempfile::TempDir, String) {
    let tmp = tempfile::tempdir().expect("temporary directory");
    let p = tmp.path().join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    let p = p.to_str().unwrap().to_string();
    (tmp, p)
}

/// Where scene body `id` is now (world, m), by the simulator's ground truth.
fn body(bot: &Robot, id: &str) -> Vector3<f64> {
    let sim = bot.simulator().unwrap();
    let i = sim.scene().body_index(id).unwrap();
    sim.truth().bodies[i].translation.vector
}

#[test]
fn the_base_stops_at_a_wall_with_the_bumper_fault() {
    // The wall's face is at x = 0.55 m; the Kobuki's radius is 0.175 m.
    let (_tmp, wall) = scene_file(
        "wall",
        "name = \"wall\"\n[floor]\nsize = [4.0, 4.0]\n[[wall]]\nfrom = [0.6, -1.5]\nto = [0.6, 1.5]\n",
    );
    let bot = Robot::builder("locobot")
        .scene(&wall)
        .use_arm(false)
        .build()
        .unwrap();
    let r = bot.base().unwrap().set_vel(0.2, 0.0, 10.0);
    assert!(
        matches!(
            r,
            Err(Error::Fault {
                kind: FaultKind::Bumper,
                ..
            })
        ),
        "{r:?}"
    );
    let x0 = bot.simulator().unwrap().base_truth().unwrap()[0];
    bot.wait(2.0).unwrap();
    let x1 = bot.simulator().unwrap().base_truth().unwrap()[0];
    println!(
        "base stopped at x = {x1:.4} m (front at {:.4} m)",
        x1 + 0.175
    );
    assert!((x1 - x0).abs() < 1e-3, "the base went on: {x0} -> {x1}");
    assert!(
        x1 + 0.175 <= 0.552 && x1 + 0.175 > 0.5,
        "base front at {}",
        x1 + 0.175
    );
}

#[test]
fn an_object_where_the_robot_stands_is_a_typed_error() {
    let (_tmp, crowded) = scene_file(
        "crowded",
        "name = \"crowded\"\n[floor]\nsize = [4.0, 4.0]\n[[object]]\nid = \"crate\"\n\
         shape = \"box\"\nsize = [0.3, 0.3, 0.3]\nposition = [0.0, 0.0, 0.15]\n\
         colour = [0.5, 0.4, 0.3]\nmass = 2.0\n",
    );
    let e = Robot::builder("locobot")
        .scene(&crowded)
        .build()
        .unwrap_err();
    assert!(matches!(e, Error::Scene(_)) && e.is_input(), "{e}");
    assert!(e.to_string().contains("crate"), "{e}");
    // Moved away from the crate by the start pose, the robot fits.
    Robot::builder("locobot")
        .scene(&crowded)
        .start_pose([-1.0, 0.0, 0.0])
        .build()
        .expect("fits beside the crate");
}

/// Pointing down over the 3 cm red cube, closing reports an object in hand, lifting 10 cm
/// carries the cube (its height follows within 5 mm), opening drops it back on the table.
#[test]
fn the_gripper_grasps_lifts_and_drops_a_cube() {
    let bot = Robot::builder("locobot").scene("tabletop").build().unwrap();
    let (arm, gripper) = (bot.arm().unwrap(), bot.gripper().unwrap());
    let c0 = body(&bot, "red_cube");
    gripper.open().unwrap();
    // base_link is 10.2 mm above the floor; the gripper link's origin 22 cm above the floor
    // puts the fingers' tips 1.5 cm above the table.
    let x = c0.x - 0.005;
    arm.set_ee_pose_pitch_roll([x, 0.0, 0.32 - 0.0102], FRAC_PI_2, Some(0.0))
        .unwrap();
    arm.move_ee_xyz([0.0, 0.0, -0.10], 0.01).unwrap();
    assert_eq!(gripper.close().unwrap(), GripperState::Holding);
    let c1 = body(&bot, "red_cube");
    let g0 = arm.get_ee_pose().unwrap().position;
    arm.move_ee_xyz([0.0, 0.0, 0.10], 0.01).unwrap();
    let g1 = arm.get_ee_pose().unwrap().position;
    let c2 = body(&bot, "red_cube");
    println!(
        "lift: gripper +{:.4} m, cube +{:.4} m",
        g1[2] - g0[2],
        c2.z - c1.z
    );
    assert!(((c2.z - c1.z) - (g1[2] - g0[2])).abs() < 0.005);
    assert!(
        (c2.z - c1.z - 0.10).abs() < 0.01,
        "cube rose {}",
        c2.z - c1.z
    );
    assert_eq!(gripper.get_state().unwrap(), GripperState::Holding);
    gripper.open().unwrap();
    bot.wait(1.0).unwrap();
    let c3 = body(&bot, "red_cube");
    println!("dropped: cube at {c3:?}");
    assert!((c3.z - 0.115).abs() < 0.002, "cube at {c3:?}");
}
