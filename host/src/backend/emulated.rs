//! The emulated backend: the real firmware for the `mps2-an386` board in QEMU, the simulated
//! plants behind pseudo-terminals (in this process, in real time), and the serial backend on
//! the firmware's host UART. One call: `Backend::Emulated { firmware }`.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{channel, Receiver};
use std::time::{Duration, Instant};

use ferrobot_protocol::{DeviceInfo, DeviceMsg, Fault, HostMsg, Telemetry};

use super::serial::SerialLink;
use super::Link;
use crate::error::{Error, Result};

fn lines_of(r: impl Read + Send + 'static) -> Receiver<String> {
    let (tx, rx) = channel();
    std::thread::spawn(move || {
        for line in BufReader::new(r).lines() {
            let Ok(line) = line else { return };
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    rx
}

/// `qemu-system-arm` arguments for the board the firmware targets: MPS2 AN386 (Cortex-M4),
/// no display, no monitor.
pub const QEMU_MACHINE_ARGS: [&str; 8] = [
    "-machine",
    "mps2-an386",
    "-cpu",
    "cortex-m4",
    "-display",
    "none",
    "-monitor",
    "none",
];

/// QEMU running a firmware ELF on `mps2-an386`: UART0 (host) on a new PTY, UART1 and UART2 on
/// the given servo-bus and base PTYs, UART3 (the defmt log) into `log`. Returns the child and
/// the host PTY's path.
pub fn start_qemu(
    elf: &Path,
    servo_bus: &str,
    base: Option<&str>,
    log: &Path,
) -> Result<(Child, PathBuf)> {
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args(QEMU_MACHINE_ARGS)
        .args([
            "-serial",
            "pty",
            "-serial",
            servo_bus,
            "-serial",
            base.unwrap_or("null"),
        ])
        .arg("-serial")
        .arg(format!("file:{}", log.display()))
        .arg("-kernel")
        .arg(elf)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut qemu = cmd
        .spawn()
        .map_err(|e| Error::Link(format!("cannot start qemu-system-arm: {e}")))?;
    let out = qemu.stdout.take().map(lines_of);
    let err = qemu.stderr.take().map(lines_of);
    // QEMU prints "char device redirected to /dev/pts/N (label serial0)".
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        for rx in [&out, &err].into_iter().flatten() {
            if let Ok(l) = rx.recv_timeout(Duration::from_millis(20)) {
                if let Some(p) = l
                    .split("redirected to ")
                    .nth(1)
                    .and_then(|r| r.split_whitespace().next())
                {
                    return Ok((qemu, PathBuf::from(p)));
                }
            }
        }
        if Instant::now() > deadline || matches!(qemu.try_wait(), Ok(Some(_))) {
            let _ = qemu.kill();
            let _ = qemu.wait();
            return Err(Error::Link("QEMU did not report its host PTY".into()));
        }
    }
}

/// QEMU and the plants of one emulated robot; killed when dropped.
pub struct EmulatedBoard {
    qemu: Child,
    /// The plants (ground truth, fault injection).
    pub plants: ferrobot_sim::serve::Plants,
    /// The firmware's host link.
    pub host: PathBuf,
}

impl EmulatedBoard {
    /// Serve the plants of `robot` and boot `firmware` in QEMU.
    pub fn start(robot: &str, firmware: &Path) -> Result<EmulatedBoard> {
        let (served, plants) = ferrobot_sim::serve::serve(robot, 1)
            .map_err(|e| Error::Link(format!("plants: {e}")))?;
        let log =
            std::env::temp_dir().join(format!("ferrobot-emulated-{}.defmt", std::process::id()));
        let (qemu, host) = start_qemu(firmware, &served.servo_bus, served.base.as_deref(), &log)?;
        Ok(EmulatedBoard { qemu, plants, host })
    }
}

impl Drop for EmulatedBoard {
    fn drop(&mut self) {
        let _ = self.qemu.kill();
        let _ = self.qemu.wait();
    }
}

/// The serial backend on an [`EmulatedBoard`] it keeps alive.
pub struct EmulatedLink {
    serial: SerialLink,
    /// The board (dropped after the link).
    pub board: EmulatedBoard,
}

impl EmulatedLink {
    /// Start the board and connect.
    pub fn start(robot: &str, firmware: &Path) -> Result<Self> {
        let board = EmulatedBoard::start(robot, firmware)?;
        let serial = SerialLink::open(&board.host, Duration::from_secs(20))?;
        Ok(EmulatedLink { serial, board })
    }
}

impl Link for EmulatedLink {
    fn info(&self) -> &DeviceInfo {
        self.serial.info()
    }
    fn command(&mut self, msg: &HostMsg, what: &str) -> Result<()> {
        self.serial.command(msg, what)
    }
    fn request(&mut self, msg: &HostMsg, accept: &dyn Fn(&DeviceMsg) -> bool) -> Result<DeviceMsg> {
        self.serial.request(msg, accept)
    }
    fn telemetry(&mut self) -> Result<Telemetry> {
        self.serial.telemetry()
    }
    fn wait(&mut self, dt: Duration) {
        self.serial.wait(dt)
    }
    fn now(&self) -> Duration {
        self.serial.now()
    }
    fn take_faults(&mut self) -> Vec<Fault> {
        self.serial.take_faults()
    }
    fn simulator(&mut self) -> Option<&mut ferrobot_sim::LockstepSim> {
        None
    }
}
