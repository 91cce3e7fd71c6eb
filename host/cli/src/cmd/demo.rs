//! `ferrobot demo`: the quickstart on the simulated robot, narrated.

use ferrobot::Robot;

use super::common::{round, BackendArgs};

/// `ferrobot demo`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot (default locobot).
    #[arg(long, default_value = "locobot")]
    pub robot: String,
    /// Where it runs (the in-process simulator by default).
    #[command(flatten)]
    pub backend: BackendArgs,
}

/// Run the quickstart on the robot (the simulated one by default): arm, gripper, camera and
/// base.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let robot = a.robot.as_str();
    let wall = std::time::Instant::now();
    let backend = a.backend.backend()?;
    let narrated = match backend {
        ferrobot::Backend::Sim { .. } => "firmware core and simulated plants in lockstep",
        ferrobot::Backend::DirectEmulated => "host-run firmware on emulated devices",
        ferrobot::Backend::Direct { .. } => "host-run firmware on the robot's own cables",
        _ => "firmware behind a serial port",
    };
    let bot = Robot::builder(robot).backend(backend).build()?;
    say!("Ferrobot demo: {robot} ({narrated})");
    let arm = bot.arm()?;
    arm.set_joint_positions(&[0.4, 0.3, -0.5, 0.6, -0.3])?;
    say!("arm     joints {:?}", round(&arm.get_joint_angles()?));
    arm.set_ee_pose_pitch_roll([0.35, 0.0, 0.15], std::f64::consts::FRAC_PI_2, Some(0.0))?;
    let p = arm.get_ee_pose()?;
    say!(
        "arm     gripper pointing down at {:?} m",
        round(&p.position)
    );
    arm.move_ee_xyz([0.0, 0.0, 0.1], 0.01)?;
    say!(
        "arm     straight up 10 cm, now at {:?} m",
        round(&arm.get_ee_pose()?.position)
    );
    let gripper = bot.gripper()?;
    say!("gripper close -> {:?}", gripper.close()?);
    gripper.open()?;
    say!("gripper open  -> {:?}", gripper.get_state()?);
    let head = bot.head()?;
    head.set_pan_tilt(0.5, 0.3)?;
    say!("head    pan/tilt {:?} rad", round(&head.get_state()?));
    let frame = bot.camera()?.get_frame()?;
    let cloud = frame.cloud(bot.camera()?.depth_range()?, false)?;
    say!(
        "camera  {}x{} colour and depth at t = {:.3} s, {:.0} % valid depth, {} points in base_link",
        frame.rgb.width,
        frame.rgb.height,
        frame.time.as_secs_f64(),
        100.0 * frame.depth.valid_fraction(),
        cloud.len()
    );
    bot.arm()?.go_home()?;
    bot.base()?.go_to_absolute([1.0, 1.0, 0.0])?;
    let odom = bot.base()?.get_state()?;
    match bot.simulator().and_then(|s| s.base_truth()) {
        Some(truth) => say!(
            "base    go_to_absolute([1, 1, 0]): odometry {:?}, ground truth {:?}",
            round(&odom),
            round(&truth)
        ),
        None => say!(
            "base    go_to_absolute([1, 1, 0]): odometry {:?}",
            round(&odom)
        ),
    }
    let t = bot.time();
    say!(
        "done: {t:.1} s of the robot's time in {:.2} s",
        wall.elapsed().as_secs_f64()
    );
    Ok(())
}
