//! Goals on a map through the robot API: a box the map does not hold is seen by the depth
//! camera and driven round (without the camera's obstacles the base hits it), both bases; a
//! goal behind a wall that the map lacks but the camera sees fails typed.

use crate::common;
use ferrobot::nav::OccupancyGrid;
use ferrobot::{Backend, GoalOptions, Robot};
use ferrobot_protocol::FaultKind;

/// A scene file: an empty floor with the robot at the origin facing +x and `objects` (TOML
/// `[[object]]` tables).
/// The file lives in a temporary directory removed with the guard.
fn scene(name: &str, objects: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let file = dir.path().join("scene.toml");
    std::fs::write(
        &file,
        format!(
            "name = \"{name}\"\n[robot]\npose = [0.0, 0.0, 0.0]\n[floor]\nsize = [12.0, 12.0]\ncolour = [0.6, 0.6, 0.6]\n{objects}"
        ),
    )
    .expect("scene");
    (dir, file)
}

/// The robot in `scene`, its arm at home.
fn robot_at_home(name: &str, scene: &std::path::Path) -> Robot {
    Robot::builder(name)
        .scene(scene.to_str().expect("path"))
        .backend(Backend::Sim {
            seed: 3,
            realtime: false,
        })
        .build()
        .expect("robot")
}

/// The robot in `scene`, its arm stowed.
fn robot(name: &str, scene: &std::path::Path) -> Robot {
    let bot = robot_at_home(name, scene);
    common::stow(&bot);
    bot
}

/// Bumper hits reported since the last look.
fn bumps(bot: &Robot) -> usize {
    bot.take_faults()
        .iter()
        .filter(|f| f.kind == FaultKind::Bumper)
        .count()
}

/// An empty map of the area, 2 cm cells.
fn empty_map() -> OccupancyGrid {
    OccupancyGrid::new([-2.0, -3.0], 0.02, 351, 301).expect("map")
}

const BOX: &str = "[[object]]\nid = \"box\"\nshape = \"box\"\nsize = [0.4, 0.6, 0.5]\nposition = [1.5, 0.0, 0.25]\ncolour = [0.8, 0.2, 0.2]\nstatic = true\n";

#[test]
fn a_box_only_the_camera_sees_is_driven_round_and_blind_it_is_hit() {
    let (_tmp, file) = scene("box", BOX);
    for name in ["locobot", "locobot_lite"] {
        let bot = robot(name, &file);
        bot.head()
            .expect("head")
            .set_pan_tilt(0.0, 0.45)
            .expect("tilt");
        let base = bot.base().expect("base");
        let opts = GoalOptions {
            map: Some(empty_map()),
            ..Default::default()
        };
        let mut m = base
            .go_to_absolute_with([3.0, 0.0, 0.0], opts.clone())
            .expect("goal");
        let mut widest: f64 = 0.0;
        let r = loop {
            if let Some(r) = m.poll() {
                break r;
            }
            let t = bot.simulator().and_then(|s| s.base_truth()).expect("truth");
            widest = widest.max(t[1].abs());
        };
        if let Err(e) = r {
            panic!("{name}: {e}");
        }
        let t = bot.simulator().and_then(|s| s.base_truth()).expect("truth");
        // The goal is in the odometry's frame: the truth is off by the odometry's drift over a
        // 4 m drive (the Create 2's is about 2 %).
        assert!(
            (t[0] - 3.0).hypot(t[1]) < 0.1,
            "{name} ended at {t:?}, not at the goal (3, 0)"
        );
        // Round the box: its half-width 0.3 m and the base's radius.
        assert!(
            widest > 0.45,
            "{name} kept within {widest:.2} m of the line"
        );
        let bumps = bumps(&bot);
        assert_eq!(bumps, 0, "{name} bumped");
    }
    // Blind (no camera obstacles), the base drives into the box: the check above is real.
    let bot = robot("locobot", &file);
    let base = bot.base().expect("base");
    let blind = GoalOptions {
        map: Some(empty_map()),
        live_obstacles: false,
        ..Default::default()
    };
    let r = base
        .go_to_absolute_with([3.0, 0.0, 0.0], blind)
        .expect("goal")
        .wait();
    let bumped = bot
        .take_faults()
        .iter()
        .any(|f| f.kind == FaultKind::Bumper);
    assert!(
        bumped || r.is_err(),
        "blind, the base reached the goal through the box"
    );
}

#[test]
fn a_wall_the_map_lacks_is_seen_and_the_goal_behind_it_fails_typed() {
    // A wall across the way, 4 m wide, closed at both ends by walls back to behind the robot.
    let walls = "[[object]]\nid = \"w1\"\nshape = \"box\"\nsize = [0.1, 4.0, 0.6]\nposition = [1.2, 0.0, 0.3]\ncolour = [0.7, 0.7, 0.6]\nstatic = true\n\
                 [[object]]\nid = \"w2\"\nshape = \"box\"\nsize = [2.4, 0.1, 0.6]\nposition = [0.0, 2.0, 0.3]\ncolour = [0.7, 0.7, 0.6]\nstatic = true\n\
                 [[object]]\nid = \"w3\"\nshape = \"box\"\nsize = [2.4, 0.1, 0.6]\nposition = [0.0, -2.0, 0.3]\ncolour = [0.7, 0.7, 0.6]\nstatic = true\n\
                 [[object]]\nid = \"w4\"\nshape = \"box\"\nsize = [0.1, 4.0, 0.6]\nposition = [-1.2, 0.0, 0.3]\ncolour = [0.7, 0.7, 0.6]\nstatic = true\n";
    let (_tmp, file) = scene("walled", walls);
    let bot = robot("locobot", &file);
    bot.head()
        .expect("head")
        .set_pan_tilt(0.0, 0.45)
        .expect("tilt");
    let base = bot.base().expect("base");
    let opts = GoalOptions {
        map: Some(empty_map()),
        ..Default::default()
    };
    let e = base
        .go_to_absolute_with([2.5, 0.0, 0.0], opts)
        .expect("goal")
        .wait()
        .expect_err("walled in");
    assert!(
        matches!(
            e,
            ferrobot::Error::Navigation(
                ferrobot::nav::Error::NoPath { .. } | ferrobot::nav::Error::Stalled { .. }
            )
        ),
        "{e}"
    );
    let bumps = bumps(&bot);
    assert_eq!(bumps, 0, "bumped a wall it should have seen");
}

/// A 3 m x 2.5 m room with textured walls, a table and a door into a 2 m x 2.5 m closet: the
/// robot explores until no frontier is left, without a bump, and its map agrees with the floor
/// plan's reachable part.
#[test]
fn exploring_a_small_flat_maps_it_and_ends() {
    let walls = [
        ([-1.0, -1.25], [4.0, -1.25], "noise", 0.2),
        ([4.0, -1.25], [4.0, 1.25], "tiles", 0.3),
        ([4.0, 1.25], [-1.0, 1.25], "noise", 0.12),
        ([-1.0, 1.25], [-1.0, -1.25], "checker", 0.4),
    ];
    let mut scene_text = String::new();
    for (a, b, pattern, scale) in walls {
        scene_text += &format!(
            "[[wall]]\nfrom = [{}, {}]\nto = [{}, {}]\ncolour = [0.85, 0.8, 0.7]\ntexture = {{ pattern = \"{pattern}\", scale = {scale}, colour = [0.5, 0.45, 0.4] }}\n",
            a[0], a[1], b[0], b[1]
        );
    }
    // The dividing wall at x = 2, a 0.9 m door from y = -0.45.
    scene_text += "[[wall]]\nfrom = [2.0, -1.25]\nto = [2.0, 1.25]\ncolour = [0.8, 0.85, 0.9]\ntexture = { pattern = \"noise\", scale = 0.25, colour = [0.6, 0.62, 0.7] }\ndoors = [{ at = 0.8, width = 0.9, height = 2.0 }]\n";
    scene_text += "[[object]]\nid = \"table\"\nshape = \"box\"\nsize = [0.6, 0.4, 0.45]\nposition = [0.6, 0.9, 0.225]\ncolour = [0.45, 0.3, 0.2]\ntexture = { pattern = \"noise\", scale = 0.04, colour = [0.3, 0.2, 0.1] }\nstatic = true\n";
    let (_tmp, file) = scene("flat", &scene_text);
    let bot = robot("locobot", &file);
    bot.head()
        .expect("head")
        .set_pan_tilt(0.0, 0.45)
        .expect("tilt");
    let start = bot.simulator().and_then(|s| s.base_truth()).expect("truth");
    bot.start_slam(start, None).expect("slam");
    bot.wait(0.5).expect("first frames");
    let base = bot.base().expect("base");
    base.explore().expect("explores");
    let bumps = bumps(&bot);
    assert_eq!(bumps, 0, "bumped while exploring");
    let map = bot.slam_occupancy_map().expect("map").expect("keyframes");
    // No frontier the robot can reach is left.
    let here = base
        .get_state_from(ferrobot::Source::Slam)
        .expect("slam pose");
    let left = ferrobot::nav::frontiers(
        &map,
        [here[0], here[1]],
        &ferrobot::nav::FrontierSettings::new(0.177),
    )
    .expect("frontiers");
    assert!(left.len() <= 1, "frontiers left: {left:?}");
    // The closet was entered or seen: its free cells are on the map.
    let plan = bot
        .scene()
        .floor_plan(0.02, [0.1, 0.8], false)
        .expect("floor plan");
    let truth = ferrobot::nav::MapImage::from_occupied(
        plan.origin,
        plan.resolution,
        plan.width,
        plan.height,
        &plan.occupied,
    );
    let part = ferrobot::slam::reachable_part(&truth, [start[0], start[1]]).expect("part");
    let iou = ferrobot::slam::map_iou_seen(&map, &part, &truth, 1).expect("iou");
    assert!(iou.free > 0.8, "free IoU {:.3}", iou.free);
}

/// Goals in SLAM's map, SLAM's own map and exploration without SLAM running: typed errors at
/// once, nothing moves; hostile maps and circles with a map are refused before any work.
#[test]
fn slam_goals_without_slam_and_hostile_maps_are_refused() {
    let (_tmp, file) = scene("refuse", "");
    // Refused before the arm's reach matters.
    let bot = robot_at_home("locobot", &file);
    let base = bot.base().expect("base");
    for opts in [
        GoalOptions {
            map: Some(empty_map()),
            frame: ferrobot::Source::Slam,
            ..Default::default()
        },
        GoalOptions {
            use_map: true,
            ..Default::default()
        },
    ] {
        let e = base
            .go_to_absolute_with([1.0, 0.0, 0.0], opts)
            .expect_err("no SLAM");
        assert!(matches!(e, ferrobot::Error::Usage(_)), "{e}");
    }
    let e = base.explore_async().expect_err("no SLAM");
    assert!(matches!(e, ferrobot::Error::Usage(_)), "{e}");
    // A map whose cells do not match its shape, huge or non-finite circles.
    let mut bad = empty_map();
    bad.width = usize::MAX / 2;
    let e = base
        .go_to_absolute_with(
            [1.0, 0.0, 0.0],
            GoalOptions {
                map: Some(bad),
                ..Default::default()
            },
        )
        .expect_err("bad map");
    assert!(e.is_input(), "{e}");
    for c in [[f64::NAN, 0.0, 0.1], [1.0, 1.0, 1e300], [1.0, 1.0, -1.0]] {
        let e = base
            .go_to_absolute_with(
                [1.0, 0.0, 0.0],
                GoalOptions {
                    map: Some(empty_map()),
                    obstacles: vec![c],
                    ..Default::default()
                },
            )
            .expect_err("bad circle");
        assert!(e.is_input(), "{c:?}: {e}");
    }
    let odo = base.get_state().expect("odometry");
    assert!(odo[0].abs() < 1e-3, "the base moved: {odo:?}");
}
