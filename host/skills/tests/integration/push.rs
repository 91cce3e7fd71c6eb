//! Pushing through the public API on the simulator: the tabletop's objects placed at random
//! (seed 1), the robot pushes one, and the simulated world's ground truth says it moved at
//! least 5 cm along the push while every other object stayed within 1 cm. An empty table is a
//! typed error. (The same program through the firmware in QEMU: `hil-tests/tests/hil.rs`;
//! the benchmark: `ferrobot bench push`.)

use ferrobot::perception::PerceptionError;
use ferrobot::scene::Scene;
use ferrobot::{Error, Robot};
use ferrobot_skills::{PushOptions, Skills};
use nalgebra::Vector3;

#[test]
fn one_object_is_pushed_5_cm_and_the_others_stay_put() {
    let mut scene = Scene::bundled("tabletop").unwrap();
    ferrobot_sim::placement::scatter_on(&mut scene, "table", 1, 0.03).unwrap();
    let bot = Robot::builder("locobot").with_scene(scene).build().unwrap();
    let before = bot.truth().unwrap();
    let pushed = bot.push_object(&PushOptions::default()).unwrap();
    bot.wait(2.0).unwrap();
    let after = bot.truth().unwrap();
    let scene = bot.scene();
    // The scene body nearest the object the robot chose (base_link is the world's frame
    // here, up to its height: the robot stands at the origin facing +x).
    let c = pushed.objects[pushed.plan.target].centroid;
    let movable: Vec<usize> = (0..scene.bodies.len())
        .filter(|&i| !scene.bodies[i].fixed)
        .collect();
    let dist = |i: usize| (before.bodies[i].translation.vector.xy() - c.coords.xy()).norm();
    let target = *movable
        .iter()
        .min_by(|&&a, &&b| dist(a).total_cmp(&dist(b)))
        .unwrap();
    assert!(
        dist(target) < 0.03,
        "no body where the robot saw its target"
    );
    let d = Vector3::new(pushed.plan.direction[0], pushed.plan.direction[1], 0.0);
    let moved = |i: usize| after.bodies[i].translation.vector - before.bodies[i].translation.vector;
    let along = moved(target).dot(&d);
    println!(
        "{} pushed {along:.4} m along {:?}",
        scene.bodies[target].id, pushed.plan.direction
    );
    assert!(
        along >= 0.05,
        "{} moved {along} m along the push",
        scene.bodies[target].id
    );
    for &i in movable.iter().filter(|&&i| i != target) {
        let m = moved(i).norm();
        assert!(m < 0.01, "{} moved {m} m", scene.bodies[i].id);
    }
}

#[test]
fn an_empty_table_is_a_typed_error() {
    let mut scene = Scene::bundled("tabletop").unwrap();
    scene.bodies.retain(|b| b.fixed);
    let bot = Robot::builder("locobot").with_scene(scene).build().unwrap();
    let e = bot.push_object(&PushOptions::default()).unwrap_err();
    assert!(
        matches!(e, Error::Perception(PerceptionError::NoObjectOnTable)),
        "{e}"
    );
    assert!(!e.is_input());
}

/// The only object stands 0.2 m from the far edge, out of the arm's reach from the near side
/// and both ends: the robot drives round the table (its body clear of the table all the way)
/// and pushes it from the far side; nothing else touched the table.
#[test]
fn an_object_out_of_reach_is_pushed_from_the_far_side() {
    let mut scene = Scene::bundled("tabletop").unwrap();
    scene.bodies.retain(|b| b.fixed || b.id == "cyan_cube");
    let cube = scene.body_index("cyan_cube").unwrap();
    let z = scene.bodies[cube].pose.translation.z;
    scene.bodies[cube].pose.translation.vector = Vector3::new(0.68, 0.0, z);
    let bot = Robot::builder("locobot").with_scene(scene).build().unwrap();
    {
        let mut sim = bot.simulator().expect("simulator");
        let links = sim.hw.world().expect("world").robot_links();
        sim.hw.watch_robot_contacts(&links).expect("watch");
    }
    let before = bot.truth().unwrap();
    let pushed = bot.push_object(&PushOptions::default()).unwrap();
    bot.wait(2.0).unwrap();
    let after = bot.truth().unwrap();
    // Only the wheels on the floor and the gripper on the cube.
    let contacts = bot.simulator().expect("simulator").hw.take_robot_contacts();
    let touched: Vec<_> = contacts
        .iter()
        .filter(|c| c.body != "floor" && c.body != "cyan_cube")
        .collect();
    assert!(touched.is_empty(), "{touched:?}");
    assert_eq!(pushed.side, ferrobot::stance::Side::Far);
    // The push's direction in the world: the base faces -x there.
    let d =
        after.root.rotation * Vector3::new(pushed.plan.direction[0], pushed.plan.direction[1], 0.0);
    let moved = after.bodies[cube].translation.vector - before.bodies[cube].translation.vector;
    println!(
        "cube moved {moved:?} along {d:?}; base at {:?}",
        after.root.translation
    );
    assert!(moved.dot(&d) >= 0.05, "the cube moved {moved:?}");
}
