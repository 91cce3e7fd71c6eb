//! `ferrobot drive`: the host-run firmware of a stock robot (its firmware core on this
//! computer, the servo bus and the base on its own USB cables) served on a pseudo-terminal
//! behind a symlink, for programs that use the serial backend, until standard input closes.
//! Nothing runs until the hardware check passes.

use std::io::Read;
use std::path::PathBuf;

use ferrobot::backend::direct::{check::Devices, HostLink, HostRunFirmware, Ports};

use super::common::load;

/// `ferrobot drive`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path (it needs a `[direct]` section).
    pub robot: String,
    /// Path of the symlink to create for the host link.
    #[arg(long)]
    pub link: PathBuf,
    /// The servo bus's device (default: the description's, e.g. /dev/ttyUSB_dyna).
    #[arg(long)]
    pub servo: Option<PathBuf>,
    /// The base's device (default: the description's, e.g. /dev/kobuki).
    #[arg(long)]
    pub base: Option<PathBuf>,
    /// Emulated devices: the virtual-time link of the plants that serve them (a test's).
    #[arg(long, hide = true)]
    pub clock: Option<PathBuf>,
}

/// Check the devices, start the firmware, print one JSON line (the link and the check's
/// report), and serve until standard input closes.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let cfg = load(&a.robot)?;
    let ports = Ports {
        host: HostLink::Serve(a.link.clone()),
        devices: Devices {
            servo: a.servo.clone(),
            base: a.base.clone(),
        },
        clock: a.clock.clone(),
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
