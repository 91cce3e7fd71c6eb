//! The host-run firmware backend, for a stock robot without a controller board (a LoCoBot's
//! NUC with a U2D2 on its Dynamixel bus and the Kobuki's or Create 2's own cable): the
//! firmware core runs on this computer, its servo bus and base on serial devices
//! ([`device`]), its host link a pseudo-terminal that the serial backend talks to, as it
//! talks to a board. The same core, the same protocol, the same safety: the watchdog, the
//! limits and the emergency stop run in the firmware core here as on a board.
//!
//! `Backend::Direct` runs it in this process; `ferrobot drive` serves it to other processes.
//! Before anything moves, the hardware check ([`check`]) must pass. On emulated devices
//! (`Backend::DirectEmulated`) the simulated plants answer on pseudo-terminals and grant the
//! firmware its time ([`clock`]), as they do for the board in QEMU.

pub mod check;
mod check_base;
mod check_report;
pub mod clock;
pub mod device;
pub mod runtime;
pub mod wires;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use serialport::{SerialPort, TTYPort};

use self::clock::{Clock, VirtualClock};
use self::runtime::{HostEnd, HostRun};
use self::wires::Wires;
use super::serial::SerialLink;

use crate::config::RobotConfig;
use crate::error::{Error, Result};

/// Where the host-run firmware's host link goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HostLink {
    /// A new pseudo-terminal behind this symlink, for a host to open (`ferrobot drive`).
    Serve(PathBuf),
    /// An existing port, opened by path (an emulated board's end of its host link).
    Open(PathBuf),
}

/// The host-run firmware's ports.
#[derive(Debug, Clone)]
pub struct Ports {
    /// The host link.
    pub host: HostLink,
    /// The devices, where not where the description's `[direct]` section says.
    pub devices: check::Devices,
    /// A virtual-time link from a conductor (emulated devices), or `None` for the wall clock.
    pub clock: Option<PathBuf>,
    /// Where to log the instant of every servo-loop tick (the loop-period benchmark).
    pub ticks: Option<runtime::TickLog>,
}

/// The host-run firmware on its own thread; stopped when dropped.
pub struct HostRunFirmware {
    /// The host link's path: what a host opens.
    pub link: PathBuf,
    /// The hardware check it passed.
    pub check: check::Report,
    served: bool,
    quit: Arc<AtomicBool>,
    thread: Option<JoinHandle<String>>,
}

fn open_port(path: &Path) -> Result<TTYPort> {
    let (port, _) = device::open(path, 115_200).map_err(|e| Error::Link(e.to_string()))?;
    Ok(port)
}

/// The error of a robot without a `[direct]` section asked to run on its own cables.
pub fn no_host_run(cfg: &RobotConfig) -> Error {
    Error::Usage(format!(
        "{} has no [direct] section: it has no host-run firmware",
        cfg.name
    ))
}

/// Open the devices of `cfg` (where `devices` says, else where its `[direct]` section says)
/// and run the hardware check on them: the report, and the wires ready for the firmware when
/// the servo bus opened. An error only when the check itself cannot run.
pub fn check_devices(
    cfg: &RobotConfig,
    devices: &check::Devices,
    clock: Option<&Path>,
) -> Result<(Option<Wires>, check::Report)> {
    let (rows, servo, base) = check::open_devices(cfg, devices);
    let Some(servo) = servo else {
        let report = check::Report {
            robot: cfg.name.clone(),
            rows,
        };
        return Ok((None, report));
    };
    let clock = match clock {
        Some(path) => Clock::Virtual(Box::new(VirtualClock::new(open_port(path)?))),
        None => Clock::Wall(std::time::Instant::now()),
    };
    let mut wires = Wires::new(servo, base, clock);
    let report = check::run(&mut wires, cfg, rows).map_err(Error::Link)?;
    Ok((Some(wires), report))
}

/// [`check_devices`], refused ([`Error::HardwareCheck`]) unless the check passed.
pub fn checked_wires(
    cfg: &RobotConfig,
    devices: &check::Devices,
    clock: Option<&Path>,
) -> Result<(Wires, check::Report)> {
    match check_devices(cfg, devices, clock)? {
        (Some(wires), report) if report.passed() => Ok((wires, report)),
        (_, report) => Err(report.error()),
    }
}

impl HostRunFirmware {
    /// Open the devices of `cfg`, check them ([`checked_wires`]: refused unless the check
    /// passes) and start its firmware (`[direct]`'s profile) on them.
    pub fn start(cfg: &RobotConfig, ports: &Ports) -> Result<HostRunFirmware> {
        let profile = ferrobot_profile::direct_profile(cfg).ok_or_else(|| no_host_run(cfg))?;
        let (wires, report) = checked_wires(cfg, &ports.devices, ports.clock.as_deref())?;
        let (host, link, served) = match &ports.host {
            HostLink::Open(path) => (HostEnd::opened(open_port(path)?), path.clone(), false),
            HostLink::Serve(link) => (HostEnd::master(serve_pty(link)?), link.clone(), true),
        };
        let quit = Arc::new(AtomicBool::new(false));
        let mut run = HostRun::new(profile, host, wires);
        run.ticks = ports.ticks.clone();
        let thread = {
            let quit = quit.clone();
            std::thread::Builder::new()
                .name("ferrobot-host-run".into())
                .spawn(move || run.run(&quit))
                .map_err(|e| Error::Link(format!("cannot start the firmware's thread: {e}")))?
        };
        Ok(HostRunFirmware {
            link,
            check: report,
            served,
            quit,
            thread: Some(thread),
        })
    }

    /// Why the firmware stopped, once it has (`None` while it runs).
    pub fn stopped(&mut self) -> Option<String> {
        if self.thread.as_ref().is_some_and(|t| t.is_finished()) {
            return self.thread.take().map(|t| {
                t.join()
                    .unwrap_or_else(|_| "the firmware's thread panicked".into())
            });
        }
        None
    }
}

impl Drop for HostRunFirmware {
    fn drop(&mut self) {
        self.quit.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        if self.served {
            let _ = std::fs::remove_file(&self.link);
        }
    }
}

/// A new pseudo-terminal whose slave is reached through the symlink `link` (which must not
/// exist); returns the master.
fn serve_pty(link: &Path) -> Result<TTYPort> {
    let (mut master, slave) =
        TTYPort::pair().map_err(|e| Error::Link(format!("cannot make a pseudo-terminal: {e}")))?;
    let name = slave
        .name()
        .ok_or_else(|| Error::Link("the pseudo-terminal has no name".into()))?;
    std::os::unix::fs::symlink(&name, link).map_err(|e| match e.kind() {
        std::io::ErrorKind::AlreadyExists => Error::PathExists {
            path: link.to_path_buf(),
        },
        _ => Error::Link(format!("cannot link {} to {name}: {e}", link.display())),
    })?;
    master
        .set_timeout(Duration::from_millis(20))
        .map_err(|e| Error::Link(e.to_string()))?;
    Ok(master)
}

/// The serial backend on a host-run firmware it keeps alive.
pub struct DirectLink {
    serial: SerialLink,
    /// The firmware (dropped after the link).
    pub firmware: HostRunFirmware,
}

/// A fresh path for a served host link in the temporary directory.
pub fn temp_link(tag: &str) -> PathBuf {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!("ferrobot-{tag}-{}-{n}", std::process::id()))
}

impl DirectLink {
    /// Check the devices of `cfg` and start its firmware on `ports` ([`HostRunFirmware::start`]),
    /// and connect to it.
    pub fn start(cfg: &RobotConfig, ports: &Ports) -> Result<Self> {
        let firmware = HostRunFirmware::start(cfg, ports)?;
        let serial = SerialLink::open(&firmware.link, Duration::from_secs(10))?;
        Ok(DirectLink { serial, firmware })
    }
}

link_through_serial!(DirectLink);
