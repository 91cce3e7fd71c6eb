//! The quickstart: `cargo run --release -p ferrobot --example quickstart`.
use ferrobot::Robot;

fn main() -> ferrobot::Result<()> {
    let bot = Robot::new("locobot")?; // in-process simulator by default
    bot.arm()?.set_joint_positions(&[0.0, 0.4, 0.2, 0.5, 0.0])?;
    bot.gripper()?.close()?;
    bot.base()?.go_to_absolute([1.0, 1.0, 0.0])?;
    println!(
        "odometry {:?}, gripper {:?}",
        bot.base()?.get_state()?,
        bot.gripper()?.get_state()?
    );
    Ok(())
}
