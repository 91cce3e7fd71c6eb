//! Real-time plant servers on pseudo-terminals: the servo chain and the base each get a PTY,
//! for the firmware in QEMU and for outside tools (the ROBOTIS SDK). Physics follows the wall
//! clock; replies go out as soon as they are computed (after the servo's return delay).

use std::io::{self, Read, Write};
use std::thread;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};

use crate::bases::BasePlant;
use crate::chain::ServoChain;
use crate::lockstep::SimError;
use crate::robots::{self, BaseModel};

/// Paths of the served ports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Served {
    /// The servo bus PTY.
    pub servo_bus: String,
    /// The base PTY, if the robot has a base.
    pub base: Option<String>,
}

/// Errors of the server.
#[derive(Debug)]
pub enum ServeError {
    /// No such robot.
    Sim(SimError),
    /// A PTY could not be made.
    Io(io::Error),
}

impl std::fmt::Display for ServeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ServeError::Sim(e) => write!(f, "{e}"),
            ServeError::Io(e) => write!(f, "cannot create a pseudo-terminal: {e}"),
        }
    }
}

impl std::error::Error for ServeError {}

fn pty() -> Result<(TTYPort, TTYPort, String), ServeError> {
    let (mut master, slave) =
        TTYPort::pair().map_err(|e| ServeError::Io(io::Error::other(e.to_string())))?;
    let name = slave.name().unwrap_or_default();
    master
        .set_timeout(Duration::from_micros(500))
        .map_err(|e| ServeError::Io(io::Error::other(e.to_string())))?;
    Ok((master, slave, name))
}

fn micros(start: Instant) -> u64 {
    start.elapsed().as_micros() as u64
}

/// Start serving `robot` (plants seeded by `seed`) on fresh PTYs; the threads run for the life
/// of the process.
pub fn serve(robot: &str, seed: u64) -> Result<Served, ServeError> {
    let desc = robots::by_name(robot)
        .ok_or_else(|| ServeError::Sim(SimError::UnknownRobot(robot.into())))?;
    let start = Instant::now();
    let (mut master, slave, servo_path) = pty()?;
    let mut chain = ServoChain::new(&desc.servos, &desc.arm, seed);
    thread::spawn(move || {
        let _keep_open = slave;
        let mut buf = [0u8; 1024];
        loop {
            let now = micros(start);
            chain.advance_to(now);
            match master.read(&mut buf) {
                Ok(n) if n > 0 => {
                    let t = micros(start);
                    for r in chain.on_bytes(t, &buf[..n]) {
                        let due = t + r.delay_us;
                        while micros(start) < due {
                            std::hint::spin_loop();
                        }
                        let _ = master.write_all(&r.bytes);
                    }
                }
                Ok(_) => {}
                Err(e)
                    if e.kind() == io::ErrorKind::TimedOut
                        || e.kind() == io::ErrorKind::WouldBlock => {}
                Err(_) => thread::sleep(Duration::from_millis(1)),
            }
        }
    });
    let base = match desc.base {
        BaseModel::None => None,
        kind => {
            let (mut master, slave, path) = pty()?;
            let mut plant = if kind == BaseModel::Kobuki {
                BasePlant::kobuki(seed)
            } else {
                BasePlant::create2(seed)
            };
            thread::spawn(move || {
                let _keep_open = slave;
                let mut buf = [0u8; 512];
                loop {
                    let now = micros(start);
                    plant.advance_to(now);
                    let out = plant.take_output();
                    if !out.is_empty() {
                        let _ = master.write_all(&out);
                    }
                    match master.read(&mut buf) {
                        Ok(n) if n > 0 => plant.on_bytes(micros(start), &buf[..n]),
                        Ok(_) => {}
                        Err(e)
                            if e.kind() == io::ErrorKind::TimedOut
                                || e.kind() == io::ErrorKind::WouldBlock => {}
                        Err(_) => thread::sleep(Duration::from_millis(1)),
                    }
                }
            });
            Some(path)
        }
    };
    Ok(Served {
        servo_bus: servo_path,
        base,
    })
}

/// Commands to a running firmware server.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkControl {
    /// Close the host PTY, as pulling the USB cable would; firmware output is lost meanwhile.
    Unplug,
    /// Make a new host PTY behind the same link path, as plugging the cable back in would.
    Plug,
}

/// A firmware core with its simulated plants, paced to the wall clock, whose host link is a
/// PTY reached through the symlink `link` (as udev's `/dev/serial/by-id` links are).
pub struct FirmwareServer {
    /// The stable path of the host link.
    pub link: std::path::PathBuf,
    control: std::sync::mpsc::Sender<LinkControl>,
}

impl FirmwareServer {
    /// Unplug or plug the host link.
    pub fn control(&self, c: LinkControl) {
        let _ = self.control.send(c);
    }
}

fn host_pty(link: &std::path::Path) -> Result<(TTYPort, TTYPort), ServeError> {
    let (master, slave, name) = pty()?;
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(&name, link).map_err(ServeError::Io)?;
    Ok((master, slave))
}

/// Serve `sim`'s host link on a PTY behind `link`, in real time, on a thread of its own.
pub fn serve_firmware(
    mut sim: crate::LockstepSim,
    link: std::path::PathBuf,
) -> Result<FirmwareServer, ServeError> {
    let (tx, rx) = std::sync::mpsc::channel();
    let mut port = Some(host_pty(&link)?);
    let path = link.clone();
    thread::spawn(move || {
        let start = Instant::now();
        let t0 = sim.now_us();
        let mut buf = [0u8; 1024];
        loop {
            match rx.try_recv() {
                Ok(LinkControl::Unplug) => {
                    port = None;
                    let _ = std::fs::remove_file(&path);
                }
                Ok(LinkControl::Plug) if port.is_none() => port = host_pty(&path).ok(),
                Ok(_) => {}
                Err(std::sync::mpsc::TryRecvError::Disconnected) => return,
                Err(std::sync::mpsc::TryRecvError::Empty) => {}
            }
            match port.as_mut() {
                Some((master, _)) => match master.read(&mut buf) {
                    Ok(n) if n > 0 => sim.write_host(&buf[..n]),
                    _ => {}
                },
                None => thread::sleep(Duration::from_millis(1)),
            }
            sim.run_until(t0 + micros(start));
            let out = sim.take_host_output();
            if let Some((master, _)) = port.as_mut() {
                if !out.is_empty() {
                    let _ = master.write_all(&out);
                }
            }
        }
    });
    Ok(FirmwareServer { link, control: tx })
}
