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
