//! The paper's Sawyer joint-control listing, without base or camera.
//! `cargo run --release -p ferrobot --example sawyer_joint_control`
use ferrobot::Robot;

fn main() -> ferrobot::Result<()> {
    let robot = Robot::builder("sawyer")
        .use_base(false)
        .use_camera(false)
        .build()?;
    let target_joints = [
        [0.22, -0.41, 0.0, 1.1, -0.2, 0.8, 0.0],
        [-0.3, -0.5, 0.5, 0.9, 0.4, 0.4, 1.2],
    ];
    let arm = robot.arm()?;
    arm.go_home()?;
    for joints in target_joints {
        arm.set_joint_positions(&joints)?;
        println!("reached {:.3?}", arm.get_joint_angles()?);
    }
    arm.go_home()?;
    Ok(())
}
