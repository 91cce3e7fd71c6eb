//! The firmware's built-in profiles (what a board runs, compiled in) are the bundled
//! descriptions': every bundled robot names a board profile, and the profile the description
//! derives equals the built-in one, joint table, base, gripper and bus alike.
//! The one field left out is the telemetry period, a setting of the link rather than of the
//! robot: a board on a serial line starts at its built-in 20 ms, the simulator links ask 10 ms.

use ferrobot_description::BUNDLED;
use ferrobot_firmware::config;
use ferrobot_profile::firmware_profile;

#[test]
fn every_bundled_robot_runs_the_built_in_profile_its_description_derives() {
    for name in BUNDLED {
        let cfg = ferrobot_profile::bundled(name).expect("bundled");
        let board = cfg.board_profile.as_deref().expect("board_profile");
        let built_in = config::by_name(board)
            .unwrap_or_else(|| panic!("{name}: the firmware has no profile {board:?}"));
        let derived = firmware_profile(&cfg);
        assert_eq!(derived.robot, built_in.robot, "{name}: robot");
        assert_eq!(
            derived.joints.len(),
            built_in.joints.len(),
            "{name}: joint count"
        );
        for (d, b) in derived.joints.iter().zip(&built_in.joints) {
            assert_eq!(d, b, "{name}: joint {}", b.name);
        }
        assert_eq!(derived.base, built_in.base, "{name}: base");
        assert_eq!(derived.gripper, built_in.gripper, "{name}: gripper");
        assert_eq!(derived.bus, built_in.bus, "{name}: bus");
        assert_eq!(derived.loop_period, built_in.loop_period, "{name}: loop");
        assert_eq!(
            derived.watchdog_period, built_in.watchdog_period,
            "{name}: watchdog"
        );
    }
}

#[test]
fn a_robot_without_a_gripper_has_no_gripper_driver() {
    let sawyer = ferrobot_profile::bundled("sawyer").expect("sawyer");
    assert!(sawyer.gripper.is_none());
    assert_eq!(firmware_profile(&sawyer).gripper, None);
    let locobot = ferrobot_profile::bundled("locobot").expect("locobot");
    let g = locobot.gripper.as_ref().expect("gripper");
    assert_eq!(
        firmware_profile(&locobot)
            .gripper
            .map(|d| (d.open_tick, d.closed_tick)),
        Some((g.open_tick, g.closed_tick))
    );
}
