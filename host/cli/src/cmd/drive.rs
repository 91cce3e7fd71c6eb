//! `ferrobot drive`: the host-run firmware of a stock robot (its firmware core on this
//! computer, the servo bus and the base on its own USB cables) served on a pseudo-terminal
//! behind a symlink, for programs that use the serial backend, until standard input closes.
//! Nothing runs until the hardware check passes.

use std::io::Read;
use std::path::PathBuf;

use ferrobot::backend::direct::{HostLink, HostRunFirmware, Ports};

use super::common::{load, DeviceArgs};

/// `ferrobot drive`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The robot and its devices.
    #[command(flatten)]
    pub devices: DeviceArgs,
    /// Path of the symlink to create for the host link.
    #[arg(long)]
    pub link: PathBuf,
}

/// Check the devices, start the firmware, print one JSON line (the link and the check's
/// report), and serve until standard input closes.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let cfg = load(&a.devices.robot)?;
    let ports = Ports {
        host: HostLink::Serve(a.link.clone()),
        devices: a.devices.devices(),
        clock: a.devices.clock.clone(),
        ticks: None,
    };
    let mut firmware = HostRunFirmware::start(&cfg, &ports)?;
    let line = serde_json::json!({"link": firmware.link, "check": firmware.check});
    say!("{line}");
    let mut sink = [0u8; 256];
    let mut stdin = std::io::stdin();
    while stdin.read(&mut sink).is_ok_and(|n| n > 0) {}
    match firmware.stopped() {
        Some(why) => Err(ferrobot::Error::Link(why)),
        None => Ok(()),
    }
}
