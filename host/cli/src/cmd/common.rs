//! Helpers shared by the subcommands: loading a robot, its arm chain, checking joint angles,
//! rounding for display.

use ferrobot::kinematics::Chain;
use ferrobot::{validate, RobotConfig};
use serde::Serialize;

/// A bundled robot by name, or the configuration file at a path (ending `.toml` or holding
/// a `/`).
pub fn load(robot: &str) -> ferrobot::Result<RobotConfig> {
    Ok(if robot.ends_with(".toml") || robot.contains('/') {
        ferrobot::profile::from_file(robot)?
    } else {
        ferrobot::profile::bundled(robot)?
    })
}

/// The arm's kinematic chain, or the error that the robot has no arm.
pub fn arm_chain(cfg: &RobotConfig) -> ferrobot::Result<Chain> {
    ferrobot::profile::arm_chain(cfg).ok_or_else(|| ferrobot::Error::NoComponent {
        robot: cfg.name.clone(),
        component: "arm",
    })
}

/// Joint angles for `chain`: its count, each finite and within ±`validate::MAX_ANGLE`.
pub fn check_q(chain: &Chain, q: &[f64]) -> ferrobot::Result<()> {
    if q.len() != chain.dof() {
        return Err(ferrobot::Error::JointCount {
            what: "joint angles",
            expected: chain.dof(),
            got: q.len(),
        });
    }
    Ok(validate::angles("joint angles", q)?)
}

/// `v` rounded to 3 decimals, for text output.
pub fn round(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| (x * 1000.0).round() / 1000.0).collect()
}

/// Print `value` as one line of compact JSON.
///
/// Every `--json` output is a struct deriving `Serialize` whose fields are declared in
/// alphabetical order: the order the objects of `serde_json::Value` used to print.
pub fn print_json<T: Serialize>(value: &T) {
    say!("{}", to_json(value));
}

/// Print one line on standard output (the [`say!`] macro). A reader that has gone away
/// (`ferrobot demo | head -1`) ends the program quietly and successfully, as Unix tools do,
/// instead of a panic; any other write error ends it with exit code 1 and a message.
pub fn say(args: std::fmt::Arguments) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.write_all(b"\n")) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: cannot write to standard output: {e}");
        std::process::exit(1);
    }
}

/// `value` as compact JSON.
pub fn to_json<T: Serialize>(value: &T) -> String {
    // Plain structs of numbers, strings and sequences: serialising them cannot fail.
    serde_json::to_string(value).expect("a plain struct serialises")
}

/// A planning error as the API's: a refused description, object or value is the input's
/// fault (a configuration error naming `file` and what was refused); anything else (a start
/// in collision, no path in time) is the world's.
pub fn planning_error(file: &std::path::Path, e: ferrobot::planning::Error) -> ferrobot::Error {
    match e {
        ferrobot::planning::Error::Invalid { what, why } => ferrobot::Error::Config {
            file: file.to_path_buf(),
            key: what,
            problem: why,
        },
        other => ferrobot::Error::Planning(other),
    }
}

/// A builder for `robot`: a configuration file when it looks like a path (ends in `.toml` or
/// holds a `/`), else a bundled robot's name.
pub fn robot_builder(robot: &str) -> ferrobot::RobotBuilder {
    if robot.ends_with(".toml") || robot.contains('/') {
        ferrobot::Robot::builder_from_config(robot)
    } else {
        ferrobot::Robot::builder(robot)
    }
}

/// The board firmware's ELF that `--backend emulated` boots in QEMU by default, relative to
/// the repository's root (`scripts/build-boards.sh` builds it).
pub use ferrobot::backend::emulated::DEFAULT_FIRMWARE;

/// Where a tool's robot runs (`--backend`, `--firmware`, `--port`, `--seed`): the same
/// program drives the in-process simulator, the real firmware in QEMU, or a serial port.
#[derive(clap::Args, Debug, Clone)]
pub struct BackendArgs {
    /// sim (in-process simulator, the default), emulated (the real firmware in QEMU with
    /// simulated plants; --firmware), serial (a board or `ferrobot sim-firmware` on --port),
    /// direct (the host-run firmware on the robot's own cables; --servo, --base, --camera) or
    /// direct-emulated (the host-run firmware on emulated devices).
    #[arg(long, value_enum, default_value_t = BackendKind::Sim)]
    pub backend: BackendKind,
    /// The board firmware's ELF for --backend emulated.
    #[arg(long, default_value = DEFAULT_FIRMWARE)]
    pub firmware: std::path::PathBuf,
    /// The serial port for --backend serial (e.g. /dev/ttyACM0).
    #[arg(long)]
    pub port: Option<std::path::PathBuf>,
    /// Seed of the simulated plants' noise (sim backend).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The servo bus's device for --backend direct (default: the description's).
    #[arg(long)]
    pub servo: Option<std::path::PathBuf>,
    /// The base's device for --backend direct (default: the description's).
    #[arg(long)]
    pub base: Option<std::path::PathBuf>,
    /// A camera server's Unix socket for --backend direct (a RealSense served by
    /// host/peers/realsense/serve_realsense.py).
    #[arg(long)]
    pub camera: Option<std::path::PathBuf>,
}

/// The kinds of backend a tool can drive ([`BackendArgs`]).
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum BackendKind {
    /// The in-process lockstep simulator.
    Sim,
    /// The real firmware in QEMU with simulated plants.
    Emulated,
    /// A serial port.
    Serial,
    /// The host-run firmware on the robot's own cables.
    Direct,
    /// The host-run firmware on emulated devices.
    DirectEmulated,
}

impl BackendArgs {
    /// The API's backend, or a typed error when --backend serial has no --port.
    pub fn backend(&self) -> ferrobot::Result<ferrobot::Backend> {
        Ok(match self.backend {
            BackendKind::Sim => ferrobot::Backend::Sim {
                seed: self.seed,
                realtime: false,
            },
            BackendKind::Emulated if !self.firmware.is_file() => {
                return Err(ferrobot::Error::Usage(format!(
                    "no firmware at {} for --backend emulated: build it with \
                     scripts/build-boards.sh, or give --firmware",
                    self.firmware.display()
                )))
            }
            BackendKind::Emulated => ferrobot::Backend::Emulated {
                firmware: self.firmware.clone(),
            },
            BackendKind::Direct => ferrobot::Backend::Direct {
                servo: self.servo.clone(),
                base: self.base.clone(),
                camera: self.camera.clone(),
            },
            BackendKind::DirectEmulated => ferrobot::Backend::DirectEmulated,
            BackendKind::Serial => ferrobot::Backend::Serial {
                path: self.port.clone().ok_or_else(|| {
                    ferrobot::Error::Usage("--backend serial needs --port".into())
                })?,
            },
        })
    }
}

/// Where a stock robot's devices are (`ferrobot drive`, `ferrobot hardware check`).
#[derive(clap::Args, Debug, Clone)]
pub struct DeviceArgs {
    /// Robot name or configuration path (it needs a `[direct]` section).
    pub robot: String,
    /// The servo bus's device (default: the description's, e.g. /dev/ttyUSB_dyna).
    #[arg(long)]
    pub servo: Option<std::path::PathBuf>,
    /// The base's device (default: the description's, e.g. /dev/kobuki).
    #[arg(long)]
    pub base: Option<std::path::PathBuf>,
    /// Emulated devices: the virtual-time link of the plants that serve them (a test's).
    #[arg(long, hide = true)]
    pub clock: Option<std::path::PathBuf>,
}

impl DeviceArgs {
    /// The devices as the host-run firmware takes them.
    pub fn devices(&self) -> ferrobot::backend::direct::check::Devices {
        ferrobot::backend::direct::check::Devices {
            servo: self.servo.clone(),
            base: self.base.clone(),
        }
    }
}
