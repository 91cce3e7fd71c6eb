use ferrobot_description::RobotConfig;
use ferrobot_planning::*;
use std::sync::Arc;

#[test]
fn explore() {
    for robot in ["locobot", "sawyer"] {
        let cfg = RobotConfig::bundled(robot).unwrap();
        let t = std::time::Instant::now();
        let m = CollisionModel::from_config(&cfg).unwrap();
        println!("{robot}: model+acm {:?}", t.elapsed());
        for (a, b, r) in m.acm().entries() {
            println!("  {a} {b} {r:?}");
        }
        println!("reach {:?}", m.reach(&[]));
        let c = Checker::new(Arc::new(m), &PlanningScene::new(), CheckOptions::default()).unwrap();
        println!("pairs {:?}", c.self_pairs());
        let home = cfg.arm.as_ref().unwrap().home.clone();
        println!("home contact {:?}", c.contact(&home));
    }
}
