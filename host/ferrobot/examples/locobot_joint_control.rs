//! The paper's LoCoBot joint-control listing: home, two joint targets, home.
//! `cargo run --release -p ferrobot --example locobot_joint_control`
use ferrobot::{MoveOptions, Robot};

fn main() -> ferrobot::Result<()> {
    let robot = Robot::new("locobot")?;
    let target_joints = [
        [0.408, 0.721, -0.471, -1.4, 0.920],
        [-0.675, 0.0, 0.23, 1.0, -0.70],
    ];
    let arm = robot.arm()?;
    arm.go_home()?;
    for joints in target_joints {
        // PyRobot's `plan=False`: the target at once; the firmware limits the joint speeds.
        arm.set_joint_positions_with(
            &joints,
            MoveOptions {
                plan: false,
                ..Default::default()
            },
        )?;
        let q = arm.get_joint_angles()?;
        println!(
            "reached {q:.3?}; end effector at {:.3?}",
            arm.get_ee_pose()?.position
        );
    }
    arm.go_home()?;
    Ok(())
}
