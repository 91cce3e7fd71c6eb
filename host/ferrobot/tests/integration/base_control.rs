//! Base control on both simulated bases: each controller reaches relative targets within 2 cm
//! and 2° of odometry, circle tracking ends within 5 cm of the reference, the commanded stream
//! respects the limits, and a bumper hit mid-motion stops the base with an error.

use ferrobot::base::{gains, BASE_CONTROL_PERIOD};
use ferrobot::base_control::{wrap, Limits, Reference};
use ferrobot::config::BaseController;
use ferrobot::{Error, GoalOptions, Robot};
use ferrobot_protocol::FaultKind;

use crate::common;
use common::place_post;

const TARGETS: [[f64; 3]; 4] = [
    [1.0, 0.0, 0.0],
    [0.0, 0.0, std::f64::consts::PI],
    [1.0, 1.0, std::f64::consts::FRAC_PI_2],
    [-1.0, -1.0, 0.0],
];

fn reaches(robot: &str, controller: BaseController, smooth: bool) {
    for target in TARGETS {
        let bot = Robot::builder(robot).use_arm(false).build().expect("robot");
        let opts = GoalOptions {
            controller: Some(controller),
            smooth,
            close_loop: true,
            obstacles: vec![],
            map: None,
            ..Default::default()
        };
        bot.base()
            .expect("base")
            .go_to_relative_with(target, opts)
            .expect("starts")
            .wait()
            .expect("reaches");
        let s = bot.base().expect("base").get_state().expect("odometry");
        let pos = (s[0] - target[0]).hypot(s[1] - target[1]);
        let rot = wrap(s[2] - target[2]).abs();
        assert!(
            pos < 0.02 && rot < 2f64.to_radians(),
            "{robot} {controller:?} smooth={smooth} {target:?}: odometry {s:?}"
        );
        // Every command changes by at most one control period's acceleration: the
        // proportional controller runs at 20 Hz within the configured speeds and its own
        // accelerations; the others at 10 Hz within the tracking limits. (The finisher after
        // LQR/ILQR ramps within these accelerations in time; its creep pulses start and stop
        // as single steps to and from creep speed, which are within one 10 Hz period's
        // acceleration, and the firmware times their end.)
        let cmds = bot.base_commands();
        assert!(
            cmds.len() > 10,
            "{robot} {controller:?}: {} commands",
            cmds.len()
        );
        let (lim, dt) = match controller {
            BaseController::Proportional => {
                let cfg = &bot.config().base.as_ref().expect("base config");
                (
                    Limits {
                        v: cfg.max_linear,
                        w: cfg.max_angular,
                        accel_v: gains::ACCEL_V,
                        accel_w: gains::ACCEL_W,
                    },
                    BASE_CONTROL_PERIOD.as_secs_f64(),
                )
            }
            _ => (Limits::TRACKING, 0.1),
        };
        let mut prev = (0.0, 0.0);
        for &(t, v, w) in &cmds {
            assert!(
                v.abs() <= lim.v + 1e-9 && w.abs() <= lim.w + 1e-9,
                "{robot} {controller:?} at {t} s: {v} {w}"
            );
            assert!(
                (v - prev.0).abs() <= lim.accel_v * dt + 1e-9
                    && (w - prev.1).abs() <= lim.accel_w * dt + 1e-9,
                "{robot} {controller:?} at {t} s: {v} {w} after {prev:?}"
            );
            prev = (v, w);
        }
    }
}

#[test]
fn lqr_reaches_the_targets_on_the_kobuki() {
    reaches("locobot", BaseController::Lqr, false);
    reaches("locobot", BaseController::Lqr, true);
}

#[test]
fn lqr_reaches_the_targets_on_the_create2() {
    reaches("locobot_lite", BaseController::Lqr, false);
    reaches("locobot_lite", BaseController::Lqr, true);
}

#[test]
fn proportional_reaches_the_targets_on_both_bases() {
    reaches("locobot", BaseController::Proportional, false);
    reaches("locobot_lite", BaseController::Proportional, false);
}

#[test]
fn ilqr_reaches_the_targets_on_both_bases() {
    reaches("locobot", BaseController::Ilqr, false);
    reaches("locobot_lite", BaseController::Ilqr, true);
}

#[test]
fn dwa_reaches_the_targets_on_both_bases() {
    reaches("locobot", BaseController::Dwa, false);
    reaches("locobot_lite", BaseController::Dwa, false);
}

/// A 0.1 m-radius post on the straight line to a goal 2 m ahead: LQR drives into it (see the
/// bumper test below); the dynamic window, told about it, goes around it without touching it
/// (the simulated bumper would abort the motion) and still ends within 2 cm and 2°.
#[test]
fn dwa_goes_around_an_obstacle_on_both_bases() {
    for robot in ["locobot", "locobot_lite"] {
        let bot = Robot::builder(robot).use_arm(false).build().expect("robot");
        place_post(&bot, 1.0, 0.0, 0.1);
        let opts = GoalOptions {
            obstacles: vec![[1.0, 0.0, 0.1]],
            ..GoalOptions::default()
        };
        bot.base()
            .expect("base")
            .go_to_absolute_with([2.0, 0.0, 0.0], opts)
            .expect("starts")
            .wait()
            .unwrap_or_else(|e| panic!("{robot}: {e}"));
        let s = bot.base().expect("base").get_state().expect("odometry");
        assert!(
            (s[0] - 2.0).hypot(s[1]) < 0.02 && wrap(s[2]).abs() < 2f64.to_radians(),
            "{robot}: odometry {s:?}"
        );
    }
}

/// Boxed in by obstacles on every side, the dynamic window refuses with a typed error.
#[test]
fn dwa_boxed_in_is_unreachable() {
    let bot = Robot::builder("locobot")
        .use_arm(false)
        .build()
        .expect("robot");
    let ring: Vec<[f64; 3]> = (0..12)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 12.0;
            [0.3 * a.cos(), 0.3 * a.sin(), 0.1]
        })
        .collect();
    let opts = GoalOptions {
        obstacles: ring,
        ..GoalOptions::default()
    };
    let e = bot
        .base()
        .expect("base")
        .go_to_absolute_with([2.0, 0.0, 0.0], opts)
        .expect("starts")
        .wait()
        .expect_err("boxed in");
    assert!(matches!(e, Error::Unreachable { .. }), "{e}");
}

/// A goal on top of an obstacle is refused before anything moves.
#[test]
fn dwa_refuses_a_goal_inside_an_obstacle() {
    let bot = Robot::builder("locobot")
        .use_arm(false)
        .build()
        .expect("robot");
    let opts = GoalOptions {
        obstacles: vec![[1.0, 0.0, 0.1]],
        ..GoalOptions::default()
    };
    let e = bot
        .base()
        .expect("base")
        .go_to_absolute_with([1.1, 0.1, 0.0], opts)
        .expect_err("refused");
    assert!(matches!(e, Error::Unreachable { .. }), "{e}");
    assert!(bot.base_commands().is_empty());
}

#[test]
fn circle_tracking_ends_within_5_cm_of_the_reference() {
    for robot in ["locobot", "locobot_lite"] {
        let bot = Robot::builder(robot).use_arm(false).build().expect("robot");
        let r = Reference::circle([0.0; 3], 0.1, 0.25, 25.0, 0.1).expect("reference");
        let end = r.end();
        bot.base()
            .expect("base")
            .track_trajectory(r, true)
            .expect("tracks");
        let s = bot.base().expect("base").get_state().expect("odometry");
        let d = (s[0] - end[0]).hypot(s[1] - end[1]);
        assert!(
            d < 0.05,
            "{robot}: ended {d} m from the reference end {end:?}: {s:?}"
        );
    }
}

#[test]
fn a_bumper_hit_stops_lqr_tracking_with_an_error() {
    let bot = Robot::new("locobot").expect("robot");
    place_post(&bot, 0.8, 0.0, 0.1);
    let opts = GoalOptions {
        controller: Some(BaseController::Lqr),
        smooth: false,
        close_loop: true,
        obstacles: vec![],
        map: None,
        ..Default::default()
    };
    let e = bot
        .base()
        .expect("base")
        .go_to_relative_with([2.0, 0.0, 0.0], opts)
        .expect("starts")
        .wait()
        .expect_err("bumps");
    assert!(
        matches!(
            e,
            Error::Fault {
                kind: FaultKind::Bumper,
                ..
            }
        ),
        "{e}"
    );
    bot.wait(0.3).expect("wait");
    let speed = bot
        .simulator()
        .expect("sim")
        .hw
        .base
        .as_ref()
        .expect("base")
        .drive
        .speed;
    assert_eq!(speed, (0.0, 0.0));
}

/// A calibration more than 10 % from the nominal geometry is refused, by the configuration
/// (naming the key) and by the API, and changes nothing.
#[test]
fn implausible_odometry_geometry_is_refused() {
    let mut table = toml::Table::new();
    table.insert("left_radius".into(), 0.05.into());
    table.insert("right_radius".into(), 0.036.into());
    table.insert("track".into(), 0.235.into());
    let e = Robot::builder("locobot_lite")
        .set("base.odometry", toml::Value::Table(table))
        .build()
        .expect_err("refused");
    assert!(e.to_string().contains("base.odometry"), "{e}");
    let bot = Robot::builder("locobot_lite")
        .use_arm(false)
        .build()
        .expect("robot");
    let base = bot.base().expect("base");
    let before = base.odometry_geometry();
    let bad = ferrobot::odometry_calibration::WheelGeometry {
        left_radius: 0.036,
        right_radius: 0.036,
        track: f64::NAN,
    };
    let e = base.set_odometry_geometry(bad).expect_err("refused");
    assert!(matches!(e, Error::Calibration { .. }), "{e}");
    assert_eq!(base.odometry_geometry(), before);
}

/// A wall across the way with a door off to the side, given as an occupancy-grid map (5 cm
/// cells) and built from posts in the simulated world: the navigator, told only the map,
/// drives through the door to the goal behind the wall without touching it (the simulated
/// bumper would abort the motion) and ends within 2 cm and 2°. A goal inside the wall and a
/// malformed map are refused before anything moves.
#[test]
fn the_navigator_drives_through_a_door_in_a_map_on_both_bases() {
    use ferrobot::base_control::OccupancyGrid;
    // Posts of 5 cm radius every 7 cm along x = 1 m, for y in [-1.5, 1.5] m, except the door
    // at y in (0.3, 1.1) m.
    let posts: Vec<[f64; 3]> = (0..=43)
        .map(|k| [1.0, -1.5 + 0.07 * k as f64, 0.05])
        .filter(|p| !(p[1] > 0.25 && p[1] < 1.15))
        .collect();
    let mut map = OccupancyGrid::new([-0.5, -2.0], 0.05, 71, 81).expect("map");
    for p in &posts {
        map.fill_circle(*p);
    }
    for robot in ["locobot", "locobot_lite"] {
        let bot = Robot::builder(robot).build().expect("robot");
        common::stow(&bot);
        for p in &posts {
            place_post(&bot, p[0], p[1], p[2]);
        }
        let opts = GoalOptions {
            map: Some(map.clone()),
            ..GoalOptions::default()
        };
        bot.base()
            .expect("base")
            .go_to_absolute_with([2.0, 0.0, 0.0], opts)
            .expect("starts")
            .wait()
            .unwrap_or_else(|e| panic!("{robot}: {e}"));
        let s = bot.base().expect("base").get_state().expect("odometry");
        assert!(
            (s[0] - 2.0).hypot(s[1]) < 0.02 && wrap(s[2]).abs() < 2f64.to_radians(),
            "{robot}: odometry {s:?}"
        );
        let opts = GoalOptions {
            map: Some(map.clone()),
            ..GoalOptions::default()
        };
        let e = bot
            .base()
            .expect("base")
            .go_to_absolute_with([1.0, -1.0, 0.0], opts)
            .expect_err("inside the wall");
        assert!(
            matches!(
                e,
                Error::Navigation(ferrobot::nav::Error::Blocked { what: "goal", .. })
            ),
            "{robot}: {e}"
        );
    }
    let mut bad = map.clone();
    bad.occupied.truncate(10);
    let bot = Robot::builder("locobot")
        .use_arm(false)
        .build()
        .expect("robot");
    let e = bot
        .base()
        .expect("base")
        .go_to_absolute_with(
            [2.0, 0.0, 0.0],
            GoalOptions {
                map: Some(bad),
                ..GoalOptions::default()
            },
        )
        .expect_err("malformed map");
    assert!(matches!(e, Error::InvalidMap { .. }), "{e}");
    assert!(bot.base_commands().is_empty());
}
