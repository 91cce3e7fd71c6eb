//! Base control on both simulated bases: each controller reaches relative targets within 2 cm
//! and 2° of odometry, circle tracking ends within 5 cm of the reference, the commanded stream
//! respects the limits, and a bumper hit mid-motion stops the base with an error.

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

fn reaches(robot: &str, controller: BaseController, smooth: bool) {
    for target in TARGETS {
        let mut bot = Robot::builder(robot).use_arm(false).build().expect("robot");
        let opts = GoalOptions {
            controller: Some(controller),
            smooth,
            close_loop: true,
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
        let cmds = bot.base_commands();
        let lim = Limits::TRACKING;
        let mut prev = (0.0, 0.0);
        for &(_, v, w) in cmds {
            assert!(
                v.abs() <= lim.v + 1e-9 && w.abs() <= lim.w + 1e-9,
                "{v} {w}"
            );
            assert!(
                (v - prev.0).abs() <= lim.accel_v * 0.1 + 1e-9
                    && (w - prev.1).abs() <= lim.accel_w * 0.1 + 1e-9
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
    bot.simulator()
        .expect("sim")
        .base
        .as_mut()
        .expect("base")
        .drive
        .obstacles
        .push(ferrobot_sim::diff_drive::Obstacle {
            x: 0.8,
            y: 0.0,
            r: 0.1,
        });
    let opts = GoalOptions {
        controller: Some(BaseController::Lqr),
        smooth: false,
        close_loop: true,
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
