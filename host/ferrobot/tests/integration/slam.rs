//! SLAM beside the simulated LoCoBot through the public API: started with the robot, fed by
//! whatever lets time pass, the base's pose from `Source::Slam` against the simulator's ground
//! truth, the maps, a saved map reloaded, and the refusals.

use crate::common;
use ferrobot::slam::optimise::{planar, to_planar};
use ferrobot::slam::Map;
use ferrobot::{Backend, Error, Robot, Source};

fn apartment(seed: u64) -> Robot {
    Robot::builder("locobot")
        .scene("apartment")
        .backend(Backend::Sim {
            seed,
            realtime: false,
        })
        .build()
        .expect("robot")
}

fn truth(bot: &Robot) -> [f64; 3] {
    bot.simulator().and_then(|s| s.base_truth()).expect("truth")
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

#[test]
fn slam_beside_the_robot_follows_it_within_a_centimetre() {
    let bot = apartment(1);
    let base = bot.base().expect("base");
    // Before SLAM runs, its pose is an error, not a guess.
    assert!(matches!(
        base.get_state_from(Source::Slam),
        Err(Error::Usage(_))
    ));
    bot.head()
        .expect("head")
        .set_pan_tilt(0.0, 0.3)
        .expect("head");
    // The map's frame is the world's: the robot is told where it starts.
    let start = truth(&bot);
    bot.start_slam(start, None).expect("slam");
    // A drive through the API's own waits: SLAM sees every frame that time passes.
    base.go_to_relative([0.8, 0.0, 0.0]).expect("drive");
    base.go_to_relative([0.0, 0.0, 1.2]).expect("turn");
    bot.wait(0.5).expect("wait");
    let slam = base.get_state_from(Source::Slam).expect("slam pose");
    let t = truth(&bot);
    assert!(dist(slam, t) < 0.01, "SLAM {slam:?} vs truth {t:?}");
    assert!(
        (slam[2] - t[2]).abs() < 0.01,
        "SLAM {slam:?} vs truth {t:?}"
    );
    // The odometry's pose is in its own frame: the same motion from zero.
    let odo = base.get_state_from(Source::Odometry).expect("odometry");
    let odo_world = to_planar(&(planar(start) * planar(odo)));
    assert!(
        dist(odo_world, t) < 0.05,
        "odometry {odo_world:?} vs truth {t:?}"
    );
    let cloud = bot.slam_map_3d(0.05).expect("cloud");
    assert!(cloud.len() > 1000);
    let grid = bot
        .slam_occupancy_map()
        .expect("grid")
        .expect("some keyframe");
    assert_eq!(grid.resolution, 0.02);
    // Saved, reloaded, and found again by a robot not told where it is.
    let map = bot.stop_slam().expect("map");
    let file_dir = tempfile::tempdir().expect("temporary directory");
    let file = file_dir.path().join("api-slam.slam");
    map.save(&file).expect("save");
    let bot2 = apartment(2);
    bot2.head()
        .expect("head")
        .set_pan_tilt(0.0, 0.3)
        .expect("head");
    bot2.start_slam([0.0; 3], Some(Map::load(&file).expect("load")))
        .expect("slam");
    bot2.wait(1.0).expect("wait");
    let found = bot2
        .base()
        .expect("base")
        .get_state_from(Source::Slam)
        .expect("localised");
    assert!(
        dist(found, truth(&bot2)) < 0.02,
        "{found:?} vs {:?}",
        truth(&bot2)
    );
    // In a world the map does not hold (the empty scene: no feature to match), it stays lost,
    // and says so, typed: no made-up pose.
    let bot3 = Robot::builder("locobot")
        .scene("empty")
        .build()
        .expect("robot");
    bot3.start_slam([0.0; 3], Some(Map::load(&file).expect("load")))
        .expect("slam");
    bot3.wait(0.5).expect("wait");
    match bot3.base().expect("base").get_state_from(Source::Slam) {
        Err(Error::SlamLost { frames }) => assert!(frames >= 10, "{frames} frames"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn slam_refuses_what_it_cannot_do() {
    let bot = apartment(3);
    assert!(matches!(bot.slam_report(), Err(Error::Usage(_))));
    assert!(matches!(bot.slam_map_3d(0.05), Err(Error::Usage(_))));
    assert!(bot.start_slam([f64::NAN, 0.0, 0.0], None).is_err());
    bot.start_slam([0.0; 3], None).expect("slam");
    assert!(bot.slam_map_3d(f64::NAN).is_err());
    assert!(bot.slam_map_3d(0.0).is_err());
    // Sawyer has no camera or base.
    let sawyer = Robot::new("sawyer").expect("sawyer");
    assert!(matches!(
        sawyer.start_slam([0.0; 3], None),
        Err(Error::NoComponent { .. })
    ));
}

#[test]
fn go_to_absolute_on_the_slam_map_passes_a_door_and_a_goal_no_path_reaches_is_typed() {
    for robot in ["locobot", "locobot_lite"] {
        let bot = Robot::builder(robot)
            .scene("apartment")
            .backend(Backend::Sim {
                seed: 1,
                realtime: false,
            })
            .build()
            .expect("robot");
        common::stow(&bot);
        let base = bot.base().expect("base");
        bot.head()
            .expect("head")
            .set_pan_tilt(0.0, 0.3)
            .expect("head");
        // The map in the odometry's frame (goals are given in it).
        bot.start_slam(base.get_state().expect("odometry"), None)
            .expect("slam");
        // Look about: the wall ahead (x = 0 in the world, 3 m ahead) and its door.
        base.go_to_relative([0.0, 0.0, 0.5]).expect("turn");
        base.go_to_relative([0.0, 0.0, -0.5]).expect("turn");
        let grid = bot
            .slam_occupancy_map()
            .expect("map")
            .expect("keyframes")
            .to_grid(false)
            .expect("grid");
        assert!(grid.occupied.iter().filter(|&&o| o).count() > 100);
        // Through the door into the kitchen: world (0.7, -1.6), the start at (-3, -2, 0); 0.41 m
        // from the kitchen island, which the camera saw from the start (its cells count since
        // they are stamped where they overlap the map's; at (0.8, -1.55), 0.30 m from the
        // island, the island as seen from 3 m away left less than the base's radius).
        // The goal is given in the odometry's frame.
        let opts = ferrobot::GoalOptions {
            map: Some(grid.clone()),
            ..Default::default()
        };
        base.go_to_absolute_with([3.7, 0.4, 0.0], opts.clone())
            .expect("goal")
            .wait()
            .expect("through the door");
        let t = truth(&bot);
        assert!(t[0] > 0.5, "{robot} did not pass the door: {t:?}");
        assert!(bot
            .take_faults()
            .iter()
            .all(|f| f.kind != ferrobot_protocol::FaultKind::Bumper));
        // A goal walled in on the map: refused at once, typed, no time spent.
        let mut walled = grid.clone();
        // World (-1.0, -0.4): open floor 0.6 m from the ball.
        let goal = [2.0, 1.6];
        for j in 0..walled.height {
            for i in 0..walled.width {
                let c = walled.centre(i, j);
                let r = (c[0] - goal[0]).hypot(c[1] - goal[1]);
                if (0.5..0.6).contains(&r) {
                    walled.occupied[j * walled.width + i] = true;
                }
            }
        }
        let t0 = bot.time();
        let e = base
            .go_to_absolute_with(
                [goal[0], goal[1], 0.0],
                ferrobot::GoalOptions {
                    map: Some(walled),
                    ..Default::default()
                },
            )
            .expect_err("walled in");
        assert!(
            matches!(e, Error::Navigation(ferrobot::nav::Error::NoPath { .. })),
            "{e}"
        );
        assert!(bot.time() - t0 < 0.05);
        // A goal inside a wall of the map: refused, typed.
        let e = base
            .go_to_absolute_with([3.0, 0.0, 0.0], opts)
            .map(|_| ())
            .expect_err("in the wall");
        assert!(
            e.is_input() || matches!(e, Error::Unreachable { .. } | Error::Navigation(_)),
            "{e}"
        );
    }
}
