//! A short recording of the simulated LoCoBot at the tabletop scene's table, for a viewer to
//! show: the head tilts down to the table, the arm reaches over it and back while the gripper
//! closes and opens, and the base turns a little. `scripts/viewer-screenshot.sh` screenshots
//! it in Lichtblick.
//!
//! ```sh
//! cargo run -p ferrobot-record --example tabletop_recording -- out.mcap
//! ```

use std::path::PathBuf;

use ferrobot::Robot;
use ferrobot_record::{RecordOptions, Recorder};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out: PathBuf = std::env::args_os()
        .nth(1)
        .ok_or("usage: tabletop_recording OUT.mcap")?
        .into();
    let robot = Robot::builder("locobot").scene("tabletop").build()?;
    let rec = Recorder::start(&robot, &out, RecordOptions::default())?;

    robot.head()?.set_pan_tilt(0.0, 0.8)?;
    let arm = robot.arm()?;
    let gripper = robot.gripper()?;
    arm.set_joint_positions(&[0.3, 0.1, 0.4, 0.9, 0.0])?;
    gripper.close()?;
    arm.set_joint_positions(&[-0.3, 0.2, 0.3, 0.9, 0.5])?;
    gripper.open()?;
    robot.base()?.set_vel(0.0, 0.3, 0.5)?;
    arm.set_joint_positions(&[0.0, -0.3, 0.5, 0.6, 0.0])?;

    let stats = rec.finish()?;
    println!("{}: {stats:?}", out.display());
    Ok(())
}
