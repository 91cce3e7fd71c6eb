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
