//! `ferrobot hardware check`: the hardware check of a stock robot on its own cables (its
//! description's `[direct]` devices, or those given), as a table of what is wrong and how to
//! fix it. The exit code is non-zero when a row is a fault.

use std::path::PathBuf;

use ferrobot::backend::direct::{check::Devices, check_devices};

use super::common::{load, print_json};

/// `ferrobot hardware check`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// The servo bus's device (default: the description's, e.g. /dev/ttyUSB_dyna).
    #[arg(long)]
    pub servo: Option<PathBuf>,
    /// The base's device (default: the description's, e.g. /dev/kobuki).
    #[arg(long)]
    pub base: Option<PathBuf>,
    /// Emulated devices: the virtual-time link of the plants that serve them (a test's).
    #[arg(long, hide = true)]
    pub clock: Option<PathBuf>,
    /// The report as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Check the robot's devices and print the table (or JSON); the check's error when it failed.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let cfg = load(&a.robot)?;
    let devices = Devices {
        servo: a.servo.clone(),
        base: a.base.clone(),
    };
    let (_, report) = check_devices(&cfg, &devices, a.clock.as_deref())?;
    if a.json {
        print_json(&report);
    } else {
        say!("{report}");
    }
    if report.passed() {
        Ok(())
    } else {
        Err(ferrobot::Error::HardwareCheck {
            faults: report.faults().iter().map(|p| p.to_string()).collect(),
            table: report.to_string(),
        })
    }
}
