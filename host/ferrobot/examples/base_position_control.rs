//! The paper's base position-control listing: drive the LoCoBot to (1, 1) facing +x, and
//! compare odometry with the simulator's ground truth.
//! `cargo run --release -p ferrobot --example base_position_control`
use ferrobot::Robot;

fn main() -> ferrobot::Result<()> {
    let robot = Robot::new("locobot")?;
    let target_position = [1.0, 1.0, 0.0];
    robot.base()?.go_to_absolute(target_position)?;
    let odom = robot.base()?.get_state()?;
    let truth = robot.simulator().and_then(|s| s.base_truth());
    println!("odometry {odom:.4?}, ground truth {truth:.4?}");
    Ok(())
}
