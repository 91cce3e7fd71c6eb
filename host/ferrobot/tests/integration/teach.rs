//! Teach mode through the public API: the arm follows a hand (the simulator's) and stays
//! where it is left; a motion ends it; an arm whose plant does not bear its model out (the
//! Sawyer stand-in, which carries no gravity) gets a typed refusal.

use ferrobot::{Error, Robot};
use ferrobot_protocol::RejectReason;

fn max_err(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn the_arm_follows_a_hand_in_teach_mode_and_stays_where_it_is_left() -> ferrobot::Result<()> {
    let bot = Robot::new("locobot")?;
    let arm = bot.arm()?;
    arm.set_joint_positions(&[0.3, 0.6, 0.3, 0.4, 0.0])?;
    arm.set_teach_mode(true)?;
    let before = arm.get_joint_angles()?;
    // A hand lifts the shoulder for a second, then lets go over half a second.
    for k in (0..=100).rev() {
        let t = -f64::from(k.min(50)) / 50.0;
        bot.simulator()
            .expect("simulated")
            .hw
            .chain
            .set_hand_torque(1, t);
        bot.wait(if k == 100 { 1.0 } else { 0.005 })?;
    }
    let left = arm.get_joint_angles()?;
    bot.wait(5.0)?;
    let after = arm.get_joint_angles()?;
    eprintln!(
        "moved {:.3} rad by the hand, then {:.4} rad in 5 s",
        max_err(&left, &before),
        max_err(&after, &left)
    );
    assert!(left[1] < before[1] - 0.2, "{before:?} → {left:?}");
    assert!(max_err(&after, &left) < 0.02, "{left:?} → {after:?}");
    // Off: it holds; and a motion works as ever.
    arm.set_teach_mode(false)?;
    arm.set_joint_positions(&[0.0, 0.3, 0.3, 0.3, 0.0])?;
    assert!(max_err(&arm.get_joint_angles()?, &[0.0, 0.3, 0.3, 0.3, 0.0]) < 0.01);
    Ok(())
}

#[test]
fn an_arm_that_does_not_bear_its_model_out_cannot_be_taught() -> ferrobot::Result<()> {
    // The Sawyer stand-in's servos carry no gravity; its description's model says 39 N·m.
    let bot = Robot::new("sawyer")?;
    match bot.arm()?.set_teach_mode(true) {
        Err(Error::Rejected {
            reason: RejectReason::Unsupported,
            ..
        }) => {}
        other => panic!("teach mode on Sawyer's stand-in: {other:?}"),
    }
    // It still moves.
    bot.arm()?.set_joint_positions(&[0.1; 7])?;
    Ok(())
}
