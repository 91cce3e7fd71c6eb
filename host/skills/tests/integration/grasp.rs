//! Grasping through the public API on the simulator backend ([`ferrobot_skills::grasp::pick`]): in
//! the `tabletop` scene the robot looks, chooses a graspable object, plans, descends, closes
//! and lifts it (judged from the simulator's ground truth); an empty table and a table of
//! objects too wide for the gripper are typed errors. (The same tool against the firmware in
//! QEMU: `hil-tests/tests/hil.rs`; many seeded trials: `ferrobot bench grasp`.)

use ferrobot::scene::Scene;
use ferrobot::{GripperState, Robot};
use ferrobot_skills::grasp::{pick, GraspFailure, GraspOptions};
use ferrobot_skills::Error;

/// The heights of the scene's movable bodies now (world, m), by the simulator's ground truth.
fn heights(bot: &Robot) -> Vec<f64> {
    let scene = bot.scene();
    let truth = bot.truth().expect("the simulator's ground truth");
    scene
        .bodies
        .iter()
        .zip(&truth.bodies)
        .filter(|(b, _)| !b.fixed)
        .map(|(_, p)| p.translation.z)
        .collect()
}

#[test]
fn the_robot_picks_an_object_off_the_tabletop() {
    let bot = Robot::builder("locobot").scene("tabletop").build().unwrap();
    let before = heights(&bot);
    let opts = GraspOptions::default();
    let g = pick(&bot, &opts).unwrap();
    assert_eq!(g.state, GripperState::Holding);
    assert!(g.objects >= 8, "{} objects seen", g.objects);
    // One object rose with the lift (0.07 m, within 1 cm), the rest stayed within 5 mm.
    let after = heights(&bot);
    let rises: Vec<f64> = after.iter().zip(&before).map(|(a, b)| a - b).collect();
    let lifted: Vec<&f64> = rises.iter().filter(|r| **r > 0.05).collect();
    assert_eq!(lifted.len(), 1, "rises {rises:?}");
    assert!((lifted[0] - opts.lift).abs() < 0.01, "rises {rises:?}");
    assert!(
        rises.iter().all(|r| *r > 0.05 || r.abs() < 0.005),
        "rises {rises:?}"
    );
    println!("grasp: {:?}, rises {rises:?}", g.grasp);
}

#[test]
fn an_empty_table_and_too_wide_objects_are_typed_errors() {
    let tabletop = Scene::bundled("tabletop").unwrap();
    let only = |ids: &[&str]| {
        let mut s = tabletop.clone();
        s.bodies.retain(|b| b.fixed || ids.contains(&b.id.as_str()));
        Robot::builder("locobot").with_scene(s).build().unwrap()
    };
    let e = pick(&only(&[]), &GraspOptions::default()).unwrap_err();
    assert!(
        matches!(e, Error::Grasp(GraspFailure::NoObject { .. })),
        "{e}"
    );
    assert!(!e.is_input());
    // The 7 cm puck and the 5 cm cube are wider than the 4.9 cm opening.
    let e = pick(
        &only(&["purple_puck", "cyan_cube"]),
        &GraspOptions::default(),
    )
    .unwrap_err();
    match e {
        Error::Grasp(GraspFailure::NoFeasibleGrasp { objects, opening }) => {
            assert_eq!(objects, 2);
            assert!((opening - 0.049).abs() < 0.001, "{opening}");
        }
        e => panic!("{e}"),
    }
}
