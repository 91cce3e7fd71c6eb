//! The emulated backend: the real firmware for the `mps2-an386` board in QEMU, its simulated
//! plants in this process on one clock with it ([`ferrobot_sim::board`]), and the serial
//! backend on the firmware's host link. One call: `Backend::Emulated { firmware }`.
//!
//! Simulated time is granted to the firmware by the plants' conductor, so the firmware and the
//! plants agree on it however busy the machine is; the host talks to the firmware in real time
//! over a pseudo-terminal, as it would over USB.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ferrobot_sim::board::{BoardOptions, BoardPorts, BoardServer};

use super::serial::SerialLink;
use crate::error::{Error, Result};

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

/// The QEMU board's firmware ELF as `scripts/build-boards.sh` builds it, relative to the
/// repository's root: [`board_elf`] of `mps2-an386` in `boards/target`.
pub const DEFAULT_FIRMWARE: &str = "boards/target/thumbv7em-none-eabihf/release/board-mps2-an386";

/// A board's release firmware ELF in the board builds' target directory `target_dir` (both
/// boards' `.cargo/config.toml` name `boards/target`): `board-BOARD` for `thumbv7em-none-eabihf`.
pub fn board_elf(target_dir: &Path, board: &str) -> PathBuf {
    target_dir
        .join("thumbv7em-none-eabihf/release")
        .join(format!("board-{board}"))
}

/// How long the firmware may take to boot and report on its clock link (wall time).
pub const BOOT_TIMEOUT: Duration = Duration::from_secs(10);

/// QEMU's standard error, collected by a thread that ends when QEMU does.
pub struct Stderr {
    lines: Arc<Mutex<Vec<String>>>,
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Stderr {
    fn collect(r: Option<impl Read + Send + 'static>) -> Stderr {
        let lines: Arc<Mutex<Vec<String>>> = Arc::default();
        let out = lines.clone();
        let reader = r.map(|r| {
            std::thread::spawn(move || {
                for line in BufReader::new(r).lines() {
                    let Ok(line) = line else { return };
                    if let Ok(mut l) = out.lock() {
                        l.push(line);
                    }
                }
            })
        });
        Stderr { lines, reader }
    }

    /// Wait for the rest, once the process has exited.
    pub fn finish(&mut self) {
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
    }

    /// The lines so far.
    pub fn lines(&self) -> Vec<String> {
        self.lines.lock().map(|l| l.clone()).unwrap_or_default()
    }
}

/// QEMU running a firmware ELF on `mps2-an386` with its UARTs on `ports` (UART0 host link,
/// UART1 servo bus, UART2 base, UART4 virtual-time link) and UART3 (the defmt log) written to
/// `log`. Returns the child and a handle on what QEMU prints on standard error.
pub fn start_qemu(elf: &Path, ports: &BoardPorts, log: &Path) -> Result<(Child, Stderr)> {
    if !elf.is_file() {
        return Err(Error::Link(format!(
            "no firmware at {}: build it with scripts/build-boards.sh",
            elf.display()
        )));
    }
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args(QEMU_MACHINE_ARGS)
        .args(["-serial", &ports.host, "-serial", &ports.servo_bus])
        .args(["-serial", ports.base.as_deref().unwrap_or("null")])
        .arg("-serial")
        .arg(format!("file:{}", log.display()))
        .args(["-serial", &ports.clock])
        .arg("-kernel")
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    let mut qemu = cmd.spawn().map_err(|e| {
        Error::Link(format!(
            "cannot start qemu-system-arm: {e} (scripts/setup-cross.sh installs it)"
        ))
    })?;
    let err = Stderr::collect(qemu.stderr.take());
    Ok((qemu, err))
}

/// The API's error for a plant server that would not start: a scene's, or the link's.
fn plants_error(e: ferrobot_sim::serve::ServeError) -> Error {
    match e {
        ferrobot_sim::serve::ServeError::Scene(e) => Error::Scene(e),
        e => Error::Link(format!("plants: {e}")),
    }
}

/// The firmware of an emulated board: the board's ELF in QEMU, or the firmware core run on
/// this machine (the host-run firmware of a stock robot, on emulated devices).
enum BoardFirmware {
    Qemu { child: Child, stderr: Stderr },
    HostRun(super::direct::HostRunFirmware),
}

/// The emulated devices of `server` as the host-run firmware opens them: its servo bus and
/// base ports
/// (their stable links, which follow a cable pulled and plugged again).
pub fn server_devices(server: &BoardServer) -> super::direct::check::Devices {
    let wiring = server.wiring();
    super::direct::check::Devices {
        servo: wiring.link(0).map(Into::into),
        base: wiring.link(1).map(Into::into),
    }
}

/// The firmware and the plants of one emulated robot; QEMU is killed when dropped.
pub struct EmulatedBoard {
    firmware: BoardFirmware,
    /// The plants and their clock (ground truth, fault injection, diagnostics).
    pub server: BoardServer,
    /// The firmware's defmt log (UART3), a file. The board removes it when dropped, unless
    /// the thread is panicking (then it is kept, for the post-mortem).
    pub log: PathBuf,
}

impl EmulatedBoard {
    /// Serve the plants of `robot`, boot `firmware` in QEMU and wait for its first report on
    /// the clock link; the defmt log goes to `log` (removed when the board is dropped).
    pub fn start_with(
        robot: &str,
        firmware: &Path,
        opts: BoardOptions,
        log: PathBuf,
    ) -> Result<EmulatedBoard> {
        Self::start_in(
            robot,
            firmware,
            opts,
            log,
            std::sync::Arc::new(ferrobot_sim::scene::Scene::empty()),
        )
    }

    /// [`EmulatedBoard::start_with`] in `scene` (the base at its start pose).
    pub fn start_in(
        robot: &str,
        firmware: &Path,
        opts: BoardOptions,
        log: PathBuf,
        scene: std::sync::Arc<ferrobot_sim::scene::Scene>,
    ) -> Result<EmulatedBoard> {
        let server = BoardServer::start_in(robot, opts, &scene).map_err(plants_error)?;
        let (child, stderr) = start_qemu(firmware, &server.board, &log)?;
        let board = EmulatedBoard {
            firmware: BoardFirmware::Qemu { child, stderr },
            server,
            log,
        };
        board.booted(&firmware.display().to_string())
    }

    /// The host-run firmware of `cfg` (its `[direct]` section: the stock robot's cables) on
    /// emulated devices: the plants of `cfg`'s robot in `scene` behind pseudo-terminals, the
    /// firmware core on this machine on their clock.
    pub fn start_host_run(
        cfg: &crate::config::RobotConfig,
        scene: std::sync::Arc<ferrobot_sim::scene::Scene>,
    ) -> Result<EmulatedBoard> {
        let direct = cfg
            .direct_config()
            .ok_or_else(|| super::direct::no_host_run(cfg))?;
        let desc = ferrobot_sim::robots::from_description(&direct);
        let server = BoardServer::start_robot(&desc, BoardOptions::default(), &scene)
            .map_err(plants_error)?;
        // The devices listen at the description's rates: bytes at another rate are garbled.
        let base_baud = direct
            .direct
            .as_ref()
            .and_then(|d| d.base.as_ref())
            .map(|b| b.baud);
        server.rewire(|w| w.baud = [Some(direct.bus.baud), base_baud]);
        let ports = super::direct::Ports {
            host: super::direct::HostLink::Open(server.board.host.clone().into()),
            devices: server_devices(&server),
            clock: Some(server.board.clock.clone().into()),
            ticks: None,
        };
        let firmware = super::direct::HostRunFirmware::start(cfg, &ports)?;
        let board = EmulatedBoard {
            firmware: BoardFirmware::HostRun(firmware),
            server,
            log: PathBuf::new(),
        };
        board.booted("the host-run firmware")
    }

    /// Wait for the firmware (`what`) to report on its clock link.
    fn booted(mut self, what: &str) -> Result<EmulatedBoard> {
        let deadline = Instant::now() + BOOT_TIMEOUT;
        while !self.server.board_reported() {
            if let Some(why) = self.qemu_exited() {
                return Err(Error::Link(why));
            }
            if Instant::now() >= deadline {
                return Err(Error::Link(format!(
                    "{what} did not report on its virtual-time link within {BOOT_TIMEOUT:?}; \
                     QEMU said: {:?}",
                    self.qemu_stderr()
                )));
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        Ok(self)
    }

    /// [`EmulatedBoard::start_with`] with seed 1, real-time pace and a log in the temporary
    /// directory.
    pub fn start(robot: &str, firmware: &Path) -> Result<EmulatedBoard> {
        Self::start_with(robot, firmware, BoardOptions::default(), temp_log())
    }

    /// `Some(why)` once the firmware has stopped (QEMU exited).
    pub fn qemu_exited(&mut self) -> Option<String> {
        let (child, stderr) = match &mut self.firmware {
            BoardFirmware::Qemu { child, stderr } => (child, stderr),
            BoardFirmware::HostRun(f) => return f.stopped(),
        };
        match child.try_wait() {
            Ok(Some(status)) => {
                stderr.finish();
                Some(format!(
                    "QEMU exited ({status}): {}",
                    stderr.lines().join(" / ")
                ))
            }
            Ok(None) => None,
            Err(e) => Some(format!("QEMU cannot be waited for: {e}")),
        }
    }

    /// What QEMU printed on standard error so far (nothing for the host-run firmware).
    pub fn qemu_stderr(&self) -> Vec<String> {
        match &self.firmware {
            BoardFirmware::Qemu { stderr, .. } => stderr.lines(),
            BoardFirmware::HostRun(_) => Vec::new(),
        }
    }
}

/// A fresh path for a board's defmt log in the temporary directory.
fn temp_log() -> PathBuf {
    super::direct::temp_link("emulated").with_extension("defmt")
}

impl Drop for EmulatedBoard {
    fn drop(&mut self) {
        if let BoardFirmware::Qemu { child, .. } = &mut self.firmware {
            let _ = child.kill();
            let _ = child.wait();
            if !std::thread::panicking() {
                let _ = std::fs::remove_file(&self.log);
            }
        }
    }
}

/// The serial backend on an [`EmulatedBoard`] it keeps alive, and the board's world's camera
/// on a Unix socket.
pub struct EmulatedLink {
    serial: SerialLink,
    /// The camera served from the board's world, if the robot has one.
    pub camera: Option<ferrobot_sim::camera_server::CameraServer>,
    /// The board (dropped after the link).
    pub board: EmulatedBoard,
}

impl EmulatedLink {
    /// Start the board in an empty world and connect.
    pub fn start(robot: &str, firmware: &Path) -> Result<Self> {
        Self::start_in(
            robot,
            firmware,
            std::sync::Arc::new(ferrobot_sim::scene::Scene::empty()),
            None,
        )
    }

    /// Start the board in `scene`, serve its camera (`camera`) on a Unix socket in the
    /// temporary directory, and connect.
    pub fn start_in(
        robot: &str,
        firmware: &Path,
        scene: std::sync::Arc<ferrobot_sim::scene::Scene>,
        camera: Option<ferrobot_sim::camera_server::CameraOptions>,
    ) -> Result<Self> {
        let board =
            EmulatedBoard::start_in(robot, firmware, BoardOptions::default(), temp_log(), scene)?;
        Self::connect(board, camera)
    }
}

impl EmulatedLink {
    /// The host-run firmware of `cfg` on emulated devices in `scene`
    /// ([`EmulatedBoard::start_host_run`]), its camera (`camera`) served on a Unix socket,
    /// and the serial backend connected to it.
    pub fn start_host_run(
        cfg: &crate::config::RobotConfig,
        scene: std::sync::Arc<ferrobot_sim::scene::Scene>,
        camera: Option<ferrobot_sim::camera_server::CameraOptions>,
    ) -> Result<Self> {
        let board = EmulatedBoard::start_host_run(cfg, scene)?;
        Self::connect(board, camera)
    }

    /// Serve `board`'s camera and connect to its host link.
    fn connect(
        board: EmulatedBoard,
        camera: Option<ferrobot_sim::camera_server::CameraOptions>,
    ) -> Result<Self> {
        let camera = match camera {
            Some(c) => {
                let path = super::direct::temp_link("camera");
                Some(
                    board
                        .server
                        .serve_camera(&path, &c)
                        .map_err(|e| Error::Link(format!("camera: {e}")))?,
                )
            }
            None => None,
        };
        // The link's timeouts count the board's time: a busy machine slows it, not loses it.
        let time = super::timebase::Timebase::board(std::sync::Arc::new(board.server.clock()));
        let serial = SerialLink::open_on(&board.server.host, Duration::from_secs(10), time)?;
        Ok(EmulatedLink {
            serial,
            camera,
            board,
        })
    }

    /// The simulated plants' ground truth now.
    pub fn truth(&self) -> ferrobot_sim::lockstep::Truth {
        self.board.server.truth()
    }
}

link_through_serial!(EmulatedLink);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_firmware_is_the_qemu_boards_elf_in_the_boards_target_directory() {
        assert_eq!(
            board_elf(Path::new("boards/target"), "mps2-an386"),
            Path::new(DEFAULT_FIRMWARE)
        );
    }
}
