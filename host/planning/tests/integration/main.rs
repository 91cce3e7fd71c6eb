//! `ferrobot-planning`'s integration tests as one binary: a module per former test file.

mod acm;
mod edges;
mod lanes;
mod planners;
mod timing;

use std::sync::Arc;

use ferrobot_description::RobotConfig;
use ferrobot_planning::{CheckOptions, Checker, CollisionModel, PlanningScene};

/// The LoCoBot alone (no scene), with the default check options.
fn locobot_alone() -> Checker {
    let cfg = RobotConfig::bundled("locobot").expect("locobot");
    let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
    Checker::new(model, &PlanningScene::new(), CheckOptions::default()).expect("checker")
}
