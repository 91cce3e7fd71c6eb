//! Base control on both simulated bases: each controller reaches relative targets within 2 cm
//! and 2° of odometry, circle tracking ends within 5 cm of the reference, the commanded stream
//! respects the limits, and a bumper hit mid-motion stops the base with an error.

use ferrobot::base::{gains, BASE_CONTROL_PERIOD};
use ferrobot::base_control::{wrap, Limits, Reference};
use ferrobot::config::BaseController;
use ferrobot::{Error, GoalOptions, Robot};
use ferrobot_protocol::FaultKind;

const TARGETS: [[f64; 3]; 4] = [
    [1.0, 0.0, 0.0],
    [0.0, 0.0, std::f64::consts::PI],
    [1.0, 1.0, std::f64::consts::FRAC_PI_2],
    [-1.0, -1.0, 0.0],
];

/// A round post of radius `r` at `(x, y)` (m, world frame) in the simulated base's world.
fn place_post(bot: &mut Robot, x: f64, y: f64, r: f64) {
    bot.simulator()
        .expect("sim")
        .base
        .as_mut()
        .expect("base")
        .drive
        .obstacles
        .push(ferrobot_sim::diff_drive::Obstacle { x, y, r });
}

fn reaches(robot: &str, controller: BaseController, smooth: bool) {
    for target in TARGETS {
        let mut bot = Robot::builder(robot).use_arm(false).build().expect("robot");
        let opts = GoalOptions {
            controller: Some(controller),
            smooth,
            close_loop: true,
            obstacles: vec![],
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
        // accelerations; the others at 10 Hz within the tracking limits.
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
        for &(t, v, w) in cmds {
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
        let mut bot = Robot::builder(robot).use_arm(false).build().expect("robot");
        place_post(&mut bot, 1.0, 0.0, 0.1);
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
    let mut bot = Robot::builder("locobot")
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
    let mut bot = Robot::builder("locobot")
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
        .err()
        .expect("refused");
    assert!(matches!(e, Error::Unreachable { .. }), "{e}");
    assert!(bot.base_commands().is_empty());
}

#[test]
fn circle_tracking_ends_within_5_cm_of_the_reference() {
    for robot in ["locobot", "locobot_lite"] {
        let mut bot = Robot::builder(robot).use_arm(false).build().expect("robot");
        let r = Reference::circle([0.0; 3], 0.1, 0.25, 25.0, 0.1);
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
    let mut bot = Robot::new("locobot").expect("robot");
    place_post(&mut bot, 0.8, 0.0, 0.1);
    let opts = GoalOptions {
        controller: Some(BaseController::Lqr),
        smooth: false,
        close_loop: true,
        obstacles: vec![],
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
    bot.wait(0.3);
    let speed = bot
        .simulator()
        .expect("sim")
        .base
        .as_ref()
        .expect("base")
        .drive
        .speed;
    assert_eq!(speed, (0.0, 0.0));
}

/// The calibrated bases: after 2 m straight (LQR, closed loop) the Kobuki's odometry is off
/// ground truth by about the 15 mm PyRobot reports (10 to 25 mm), its gyro keeps the heading
/// within 0.3°, and the gyro-less Create 2 drifts further than the Kobuki.
#[test]
fn odometry_drifts_like_the_real_bases() {
    use ferrobot::bench_base::{run_trial, Category};
    let gap = |robot: &str| {
        let t = run_trial(
            robot,
            BaseController::Lqr,
            Category::Linear,
            [2.0, 0.0, 0.0],
            GoalOptions::default(),
            7,
        )
        .expect("trial");
        assert!(t.success, "{robot}: {t:?}");
        (
            (t.truth[0] - t.odometry[0]).hypot(t.truth[1] - t.odometry[1]),
            wrap(t.truth[2] - t.odometry[2]).abs(),
        )
    };
    let (kobuki, kobuki_th) = gap("locobot");
    let (create, _) = gap("locobot_lite");
    assert!((0.010..0.025).contains(&kobuki), "Kobuki gap {kobuki} m");
    assert!(
        kobuki_th < 0.3f64.to_radians(),
        "Kobuki heading gap {kobuki_th} rad"
    );
    assert!(
        create > kobuki,
        "Create 2 gap {create} m vs Kobuki {kobuki} m"
    );
}

/// The LoCoBots' default, LQR with the finisher, meets the benchmark's goal against odometry
/// on every target of the paper's protocol on both bases: within 1 mm and 0.1°.
#[test]
fn lqr_with_the_finisher_is_within_1_mm_and_0_1_deg_by_odometry() {
    use ferrobot::bench_base::{run_trial, Category};
    for robot in ["locobot", "locobot_lite"] {
        for cat in Category::ALL {
            for target in cat.targets() {
                let t = run_trial(
                    robot,
                    BaseController::Lqr,
                    cat,
                    target,
                    GoalOptions::default(),
                    3,
                )
                .expect("trial");
                let (xy, th) = t.errors(t.odometry);
                assert!(
                    t.success && xy < 0.001 && th < 0.1f64.to_radians(),
                    "{robot} {target:?}: {xy} m, {th} rad: {t:?}"
                );
            }
        }
    }
}
