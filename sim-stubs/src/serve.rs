//! Real-time plant servers on pseudo-terminals: the servo chain and the base each get a PTY,
//! for the firmware in QEMU and for outside tools (the ROBOTIS SDK). Physics follows the wall
//! clock; replies go out as soon as they are computed (after the servo's return delay). In a
//! scene with bodies ([`serve_in`]) a third thread steps the physics world every millisecond
//! of wall time (the base's bumper and the gripper meet the scene's objects).

use std::io::{self, Read, Write};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};

use crate::bases::BasePlant;
use crate::chain::ServoChain;
use crate::lockstep::SimError;
use crate::robots::{self, BaseModel};
use crate::scene::{Scene, SceneError};
use crate::world::World;

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
    /// Something already exists at the link path: it is never removed or replaced.
    LinkExists(std::path::PathBuf),
    /// The scene does not fit the robot (an object overlaps it at the start).
    Scene(SceneError),
}

impl std::fmt::Display for ServeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ServeError::Sim(e) => write!(f, "{e}"),
            ServeError::Io(e) => write!(f, "cannot create a pseudo-terminal: {e}"),
            ServeError::Scene(e) => write!(f, "{e}"),
            ServeError::LinkExists(p) => write!(
                f,
                "{} already exists; refusing to replace it (remove it or choose another --link)",
                p.display()
            ),
        }
    }
}

impl std::error::Error for ServeError {}

pub(crate) fn pty() -> Result<(TTYPort, TTYPort, String), ServeError> {
    let (mut master, slave) =
        TTYPort::pair().map_err(|e| ServeError::Io(io::Error::other(e.to_string())))?;
    let name = slave.name().unwrap_or_default();
    master
        .set_timeout(Duration::from_micros(500))
        .map_err(|e| ServeError::Io(io::Error::other(e.to_string())))?;
    Ok((master, slave, name))
}

pub(crate) fn micros(start: Instant) -> u64 {
    start.elapsed().as_micros() as u64
}

/// The plants being served, shared with whoever controls them (tests, the command reader).
#[derive(Clone)]
pub struct Plants {
    /// The servo chain.
    pub chain: std::sync::Arc<std::sync::Mutex<ServoChain>>,
    /// The base.
    pub base: Option<std::sync::Arc<std::sync::Mutex<BasePlant>>>,
    /// Bytes to put on the servo bus towards the firmware (line noise).
    pub servo_noise: std::sync::Arc<std::sync::Mutex<Vec<u8>>>,
    /// The physics world, when the scene has bodies (locked after the chain and the base).
    pub world: Option<std::sync::Arc<std::sync::Mutex<World>>>,
}

/// Start serving `robot` (plants seeded by `seed`) on fresh PTYs; the threads run for the life
/// of the process.
pub fn serve(robot: &str, seed: u64) -> Result<(Served, Plants), ServeError> {
    serve_in(robot, seed, &Scene::empty())
}

/// [`serve`] in `scene`: the base at the scene's start pose, and the scene's bodies in a
/// physics world stepped in real time. Fails when a scene body overlaps the robot.
pub fn serve_in(robot: &str, seed: u64, scene: &Scene) -> Result<(Served, Plants), ServeError> {
    let desc = robots::by_name(robot)
        .ok_or_else(|| ServeError::Sim(SimError::UnknownRobot(robot.into())))?;
    let world = if scene.bodies.is_empty() {
        None
    } else {
        let theta: Vec<f64> = desc.servos.iter().map(|m| m.initial).collect();
        let w = World::new(scene, desc.body.as_ref(), scene.robot_pose, &theta)
            .map_err(ServeError::Scene)?;
        Some(Arc::new(Mutex::new(w)))
    };
    let start = Instant::now();
    let (servo_path, chain, noise) = serve_chain(&desc, seed, start)?;
    let (base, base_plant) = match desc.base {
        BaseModel::None => (None, None),
        kind => {
            let (path, plant) = serve_base(kind, seed, scene, world.clone(), start)?;
            (Some(path), Some(plant))
        }
    };
    if let Some(w) = world.clone() {
        step_world(
            w,
            chain.clone(),
            base_plant.clone(),
            scene.robot_pose,
            start,
        );
    }
    Ok((
        Served {
            servo_bus: servo_path,
            base,
        },
        Plants {
            chain,
            base: base_plant,
            servo_noise: noise,
            world,
        },
    ))
}

/// Serve the servo chain of `desc` on a fresh PTY in real time from `start`: its path, the
/// chain, and the line noise to inject.
#[allow(clippy::type_complexity)]
fn serve_chain(
    desc: &robots::SimRobot,
    seed: u64,
    start: Instant,
) -> Result<(String, Arc<Mutex<ServoChain>>, Arc<Mutex<Vec<u8>>>), ServeError> {
    let (mut master, slave, servo_path) = pty()?;
    let chain = Arc::new(Mutex::new(ServoChain::new(&desc.servos, &desc.arm, seed)));
    let noise = Arc::new(Mutex::new(Vec::new()));
    {
        let chain = chain.clone();
        let noise = noise.clone();
        thread::spawn(move || {
            let _keep_open = slave;
            let mut buf = [0u8; 1024];
            loop {
                let now = micros(start);
                if let Ok(mut c) = chain.lock() {
                    c.advance_to(now);
                }
                if let Ok(mut n) = noise.lock() {
                    if !n.is_empty() {
                        let _ = master.write_all(&n);
                        n.clear();
                    }
                }
                match master.read(&mut buf) {
                    Ok(n) if n > 0 => {
                        let t = micros(start);
                        let replies = chain
                            .lock()
                            .map(|mut c| c.on_bytes(t, &buf[..n]))
                            .unwrap_or_default();
                        for r in replies {
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
    }
    Ok((servo_path, chain, noise))
}

/// Serve a base plant of model `kind` on a fresh PTY in real time from `start`, at the
/// scene's start pose among the world's bodies: its path and the plant.
fn serve_base(
    kind: BaseModel,
    seed: u64,
    scene: &Scene,
    world: Option<Arc<Mutex<World>>>,
    start: Instant,
) -> Result<(String, Arc<Mutex<BasePlant>>), ServeError> {
    let (mut master, slave, path) = pty()?;
    let mut b = if kind == BaseModel::Kobuki {
        BasePlant::kobuki(seed)
    } else {
        BasePlant::create2(seed)
    };
    b.drive.truth = scene.robot_pose;
    let plant = Arc::new(Mutex::new(b));
    let p = plant.clone();
    let w = world.clone();
    thread::spawn(move || {
        let _keep_open = slave;
        let mut buf = [0u8; 512];
        loop {
            let now = micros(start);
            let out = p
                .lock()
                .map(|mut b| {
                    // Lock order: chain, base, world.
                    let world = w.as_ref().and_then(|w| w.lock().ok());
                    b.advance_among(now, world.as_deref().map(|w| w as _));
                    b.take_output()
                })
                .unwrap_or_default();
            if !out.is_empty() {
                let _ = master.write_all(&out);
            }
            match master.read(&mut buf) {
                Ok(n) if n > 0 => {
                    if let Ok(mut b) = p.lock() {
                        b.on_bytes(micros(start), &buf[..n]);
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
    Ok((path, plant))
}

/// Step world `w` in real time from `start` with the chain and the base (or the robot fixed
/// at `fixed`) on a thread of its own. Lock order: chain, base, world.
fn step_world(
    w: Arc<Mutex<World>>,
    chain: Arc<Mutex<ServoChain>>,
    base: Option<Arc<Mutex<BasePlant>>>,
    fixed: [f64; 3],
    start: Instant,
) {
    thread::spawn(move || loop {
        let now = micros(start);
        // Lock order: chain, base, world.
        if let Ok(mut c) = chain.lock() {
            let mut b = base.as_ref().and_then(|b| b.lock().ok());
            if let Ok(mut w) = w.lock() {
                while w.next_step() <= now {
                    let t = w.next_step();
                    c.advance_to(t);
                    let pose = match b.as_deref_mut() {
                        Some(b) => {
                            b.advance_among(t, Some(&*w));
                            b.drive.truth
                        }
                        None => fixed,
                    };
                    w.step(pose, &mut c);
                }
            }
        }
        thread::sleep(Duration::from_millis(1));
    });
}

impl Plants {
    /// Carry out one line of the control protocol ([`crate::console`]); returns the JSON
    /// answer.
    pub fn command(&self, line: &str) -> serde_json::Value {
        if line.trim() == "bodies" {
            let w = self.world.as_ref().and_then(|w| w.lock().ok());
            return crate::console::bodies(w.as_deref());
        }
        let (Ok(mut chain), Ok(mut noise)) = (self.chain.lock(), self.servo_noise.lock()) else {
            return serde_json::json!({"error": "plants lock"});
        };
        let mut base = self.base.as_ref().and_then(|b| b.lock().ok());
        let now = chain.time_us();
        crate::console::command(&mut chain, base.as_deref_mut(), now, line, &mut |bytes| {
            noise.extend_from_slice(&bytes)
        })
    }
}
