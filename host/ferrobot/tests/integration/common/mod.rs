//! Helpers shared by the host's integration tests.

use ferrobot::Robot;

/// A round post of radius `r` at `(x, y)` (m, world frame) in the simulated base's world.
pub fn place_post(bot: &Robot, x: f64, y: f64, r: f64) {
    bot.simulator()
        .expect("sim")
        .hw
        .base
        .as_mut()
        .expect("base")
        .drive
        .obstacles
        .push(ferrobot_sim::diff_drive::Obstacle { x, y, r });
}

/// Folds the arm into its travel pose ([`ferrobot::Arm::stow`]), as a user does before a drive
/// on a map: with the arm out, the navigator takes its reach as the robot's radius.
pub fn stow(bot: &Robot) {
    bot.arm().expect("arm").stow().expect("stow");
}
