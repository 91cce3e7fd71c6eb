//! The arm's travel pose and what navigation makes of the arm: the stow pose of each bundled
//! mobile robot is collision-free with room to spare, out of the camera's view, and folds the
//! arm's reach in; a map goal takes the arm's reach as the robot's radius, so with the arm out
//! a door is too narrow (a typed error at once), and stowed the base passes it without a bump.

use std::sync::Arc;

use ferrobot::nav::OccupancyGrid;
use ferrobot::perception::DepthRange;
use ferrobot::{Backend, GoalOptions, Robot};
use ferrobot_description::RobotConfig;
use ferrobot_planning::{CheckOptions, Checker, CollisionModel, PlanningScene};
use ferrobot_protocol::FaultKind;

/// Each joint of the stow pose may be this far off (rad) and the arm still touches nothing.
const SPARE: f64 = 0.05;

fn robot(name: &str, scene: &str) -> Robot {
    Robot::builder(name)
        .scene(scene)
        .depth_noise(false)
        .backend(Backend::Sim {
            seed: 5,
            realtime: false,
        })
        .build()
        .expect("robot")
}

#[test]
fn stow_pose_is_folded_free_and_out_of_view() {
    for (name, most) in [("locobot", 0.26), ("locobot_lite", 0.174)] {
        let cfg = RobotConfig::bundled(name).expect("config");
        let stow = cfg.arm.as_ref().and_then(|a| a.stow.clone()).expect("stow");
        // Free with SPARE on joints 2-4 either way (27 poses round it), head level.
        let checker = Checker::new(
            Arc::new(CollisionModel::from_config(&cfg).expect("model")),
            &PlanningScene::new(),
            CheckOptions::default(),
        )
        .expect("checker");
        for k in 0..27 {
            let mut q = stow.clone();
            for (j, d) in [k % 3, (k / 3) % 3, k / 9].into_iter().enumerate() {
                q[j + 1] += SPARE * (d as f64 - 1.0);
            }
            assert!(
                checker.contact(&q).is_none(),
                "{name}: {q:?} touches: {:?}",
                checker.contact(&q)
            );
        }

        let bot = robot(name, "empty");
        bot.head()
            .expect("head")
            .set_pan_tilt(0.0, 0.45)
            .expect("tilt");
        let arm = bot.arm().expect("arm");
        let home = arm.reach().expect("reach");
        // At home the LoCoBot arm reaches 0.41 m ahead at gripper height.
        assert!(home > 0.45, "{name}: home reach {home}");
        arm.stow().expect("stow");
        let reach = arm.reach().expect("reach");
        assert!(reach <= most, "{name}: stowed reach {reach} m > {most} m");
        assert!(arm.get_collision_state().expect("state").is_none());
        // On the empty floor every point the camera sees is the floor: none of the arm.
        let cloud = bot
            .camera()
            .expect("camera")
            .get_current_pcd_in(DepthRange::new(0.01, 5.0).expect("range"), false)
            .expect("cloud");
        assert!(cloud.len() > 1000, "{name}: {} points", cloud.len());
        let above = cloud.points.iter().filter(|p| p.z > 0.03).count();
        assert_eq!(
            above, 0,
            "{name}: {above} points above the floor (the arm in view)"
        );
    }
}

/// A wall across the way at x = 1.5 m with a 0.7 m door, in the world and on the map (2 cm cells).
/// The scene file lives in a temporary directory removed with the guard.
fn door_scene() -> (tempfile::TempDir, std::path::PathBuf, OccupancyGrid) {
    let (door, wall) = ([-0.35, 0.35], 0.1);
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    let file = dir.join("scene.toml");
    let piece = |id: &str, y0: f64, y1: f64| {
        format!(
            "[[object]]\nid = \"{id}\"\nshape = \"box\"\nsize = [{wall}, {}, 0.8]\nposition = [1.5, {}, 0.4]\ncolour = [0.7, 0.6, 0.5]\nstatic = true\n",
            y1 - y0,
            0.5 * (y0 + y1)
        )
    };
    std::fs::write(
        &file,
        format!(
            "name = \"door\"\n[robot]\npose = [0.0, 0.0, 0.0]\n[floor]\nsize = [12.0, 12.0]\ncolour = [0.6, 0.6, 0.6]\n{}{}",
            piece("left", door[1], 3.0),
            piece("right", -3.0, door[0])
        ),
    )
    .expect("scene");
    let mut map = OccupancyGrid::new([-1.0, -3.0], 0.02, 250, 300).expect("map");
    for j in 0..map.height {
        for i in 0..map.width {
            let c = map.centre(i, j);
            if (c[0] - 1.5).abs() <= 0.5 * wall + 0.01 && !(door[0]..=door[1]).contains(&c[1]) {
                map.occupied[j * map.width + i] = true;
            }
        }
    }
    (tmp, file, map)
}

#[test]
fn a_map_goal_takes_the_arm_s_reach_as_the_robot_s_radius() {
    let (_tmp, file, map) = door_scene();
    let bot = robot("locobot", file.to_str().expect("path"));
    let base = bot.base().expect("base");
    let opts = GoalOptions {
        map: Some(map),
        ..Default::default()
    };
    // The arm at home reaches 0.5 m: through a 0.7 m door there is no way, refused at once.
    let t0 = bot.time();
    let e = base
        .go_to_absolute_with([3.0, 0.0, 0.0], opts.clone())
        .expect_err("arm out");
    match e {
        ferrobot::Error::Navigation(ferrobot::nav::Error::NoPath { radius, .. }) => {
            assert!(radius > 0.45, "radius {radius}")
        }
        e => panic!("not NoPath: {e}"),
    }
    assert!(bot.time() - t0 < 0.5, "took {} s", bot.time() - t0);
    // Stowed, the base passes the door.
    bot.arm().expect("arm").stow().expect("stow");
    base.go_to_absolute_with([3.0, 0.0, 0.0], opts)
        .expect("goal")
        .wait()
        .expect("through the door");
    let t = bot.simulator().and_then(|s| s.base_truth()).expect("truth");
    assert!((t[0] - 3.0).hypot(t[1]) < 0.1, "ended at {t:?}");
    let bumps = bot
        .take_faults()
        .iter()
        .filter(|f| f.kind == FaultKind::Bumper)
        .count();
    assert_eq!(bumps, 0, "bumped");
}
