//! `ferrobot hardware check`: the hardware check of a stock robot on its own cables (its
//! description's `[direct]` devices, or those given), as a table of what is wrong and how to
//! fix it. The exit code is non-zero when a row is a fault.

use ferrobot::backend::direct::check_devices;

use super::common::{load, print_json, DeviceArgs};

/// `ferrobot hardware check`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The robot and its devices.
    #[command(flatten)]
    pub devices: DeviceArgs,
    /// The report as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Check the robot's devices and print the table (or JSON); the check's error when it failed.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let cfg = load(&a.devices.robot)?;
    let (_, report) = check_devices(&cfg, &a.devices.devices(), a.devices.clock.as_deref())?;
    if report.passed() {
        if a.json {
            print_json(&report);
        } else {
            say!("{report}");
        }
        return Ok(());
    }
    let failed = report.error();
    if !a.json {
        say!("{report}");
        return Err(failed);
    }
    // One JSON object: the report with the error's fields, then exit code 1 (the robot's
    // hardware failed, not the input), without the generic error line a second object would
    // be.
    let mut v = serde_json::to_value(&report).unwrap_or_default();
    v["success"] = false.into();
    v["input_error"] = false.into();
    v["error"] = failed.to_string().into();
    print_json(&v);
    std::process::exit(1)
}
