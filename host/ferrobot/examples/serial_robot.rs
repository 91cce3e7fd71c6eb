//! A LoCoBot whose firmware runs behind a serial port (a board over USB, or `ferrobot
//! sim-firmware` behind a PTY), built without the simulator:
//! `cargo run -p ferrobot --no-default-features --features serial --example serial_robot -- /dev/ttyACM0`.

use ferrobot::{Backend, Robot};

fn main() -> ferrobot::Result<()> {
    let port = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "/dev/ttyACM0".into());
    let bot = Robot::builder("locobot")
        .backend(Backend::Serial { path: port.into() })
        .build()?;
    let arm = bot.arm()?;
    println!("arm at {:?}", arm.get_joint_angles()?);
    arm.go_home()?;
    println!("base at {:?}", bot.base()?.get_state()?);
    Ok(())
}
