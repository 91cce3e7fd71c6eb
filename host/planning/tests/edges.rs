//! Proven edges against exact distances that must never be too large.

use std::sync::Arc;

use ferrobot_description::RobotConfig;
use ferrobot_planning::{CheckOptions, Checker, CollisionModel, PlanningScene};

/// A LoCoBot edge whose elbow box grazes the camera mast's box (both nearly parallel) for 0.7 %
/// of its length, 0.09 mm deep. parry's cuboid–cuboid distance said 2.7 cm a little before the
/// contact (it is 0.2 mm), so conservative advancement stepped over it and "proved" the edge;
/// FCL (`plan_peer.py check`) found the contact in an exported path.
#[test]
fn an_edge_grazing_a_fixed_link_is_not_proven() {
    let cfg = RobotConfig::bundled("locobot").expect("locobot");
    let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
    let c = Checker::new(model, &PlanningScene::new(), CheckOptions::default()).expect("checker");
    let a = [0.48181393, -0.57703693, 0.2663449, 0.38923935, 0.26541771];
    let b = [0.32535412, -0.33525868, 0.0118354, 0.10592515, 0.39710595];
    let at = |t: f64| -> Vec<f64> { a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect() };
    assert!(c.is_free(&a) && c.is_free(&b));
    let touching = c.contact(&at(0.2233)).expect("the elbow touches the mast");
    assert_eq!(
        (touching.a.as_str(), touching.b.as_str()),
        ("elbow_link", "cam_mount")
    );
    assert!(!c.motion_proven(&a, &b));
    // 0.2 mm from the mast: not 2 cm clear.
    assert!(c.near_world(&at(0.205), 0.001));
}

/// A LoCoBot edge on which the elbow touches the camera mast 1.5 µm deep, for 0.05 mm of its
/// 0.72 m of motion: shorter than `min_step`, so stepping `min_step` with contact checks alone
/// (as the checker did below `min_step` of clearance) stepped over it; FCL found it in an
/// exported path. Steps near contact now need the clearances at both ends to cover them.
#[test]
fn a_contact_shorter_than_min_step_is_not_stepped_over() {
    let cfg = RobotConfig::bundled("locobot").expect("locobot");
    let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
    let c = Checker::new(model, &PlanningScene::new(), CheckOptions::default()).expect("checker");
    let a = [
        -0.9596562766769012,
        -0.9364069903152136,
        1.2529021401964529,
        -1.1660013381586636,
        -1.256280984874232,
    ];
    let b = [
        -0.4462602862963767,
        -0.5214767713804918,
        0.9718089959412842,
        -1.0422980335527063,
        -0.893607127945518,
    ];
    assert!(c.is_free(&a) && c.is_free(&b));
    assert!(!c.motion_proven(&a, &b));
    // The same edge shortened so that it ends before the contact is proven.
    let short: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + (y - x) * 0.99).collect();
    assert!(c.motion_proven(&a, &short));
}
