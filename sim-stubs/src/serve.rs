//! Real-time plant servers on pseudo-terminals: the servo chain and the base each get a PTY,
//! for the firmware in QEMU and for outside tools (the ROBOTIS SDK). Physics follows the wall
//! clock; replies go out as soon as they are computed (after the servo's return delay). In a
//! scene with bodies ([`serve_in`]) a third thread steps the physics world every millisecond
//! of wall time (the base's bumper and the gripper meet the scene's objects).

use std::io::{self, Read, Write};
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
    use std::sync::{Arc, Mutex};
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
    let (base, base_plant) = match desc.base {
        BaseModel::None => (None, None),
        kind => {
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
            (Some(path), Some(plant))
        }
    };
    if let Some(w) = world.clone() {
        let (chain, base) = (chain.clone(), base_plant.clone());
        let fixed = scene.robot_pose;
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

impl Plants {
    /// Carry out one line of the control protocol ([`crate::control`]); returns the JSON
    /// answer.
    pub fn command(&self, line: &str) -> serde_json::Value {
        if line.trim() == "bodies" {
            let w = self.world.as_ref().and_then(|w| w.lock().ok());
            return crate::control::bodies(w.as_deref());
        }
        let (Ok(mut chain), Ok(mut noise)) = (self.chain.lock(), self.servo_noise.lock()) else {
            return serde_json::json!({"error": "plants lock"});
        };
        let mut base = self.base.as_ref().and_then(|b| b.lock().ok());
        let now = chain.time_us();
        crate::control::command(&mut chain, base.as_deref_mut(), now, line, &mut |bytes| {
            noise.extend_from_slice(&bytes)
        })
    }
}

/// Commands to a running firmware server.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkControl {
    /// Close the host PTY, as pulling the USB cable would; firmware output is lost meanwhile.
    Unplug,
    /// Make a new host PTY behind the same link path, as plugging the cable back in would.
    Plug,
    /// Drop the firmware's telemetry frames from now on and pass the rest (handshakes,
    /// acknowledgements, replies), as a firmware whose control loop stopped while its link
    /// still answers would (fault injection).
    Mute,
    /// Pass the telemetry again.
    Unmute,
}

/// `out` (frames of the firmware's host link, each ended by a `0x00`) without its telemetry
/// frames; a partial frame at the end is kept in `partial` for the next call.
fn without_telemetry(partial: &mut Vec<u8>, out: &[u8]) -> Vec<u8> {
    use ferrobot_protocol::{DeviceMsg, FrameDecoder};
    partial.extend_from_slice(out);
    let mut kept = Vec::new();
    let mut start = 0;
    for (i, &b) in partial.iter().enumerate() {
        if b != 0 {
            continue;
        }
        let frame = &partial[start..=i];
        let mut decoder = FrameDecoder::new();
        // The frame ends at its one 0x00, the last byte: that is where a frame decodes.
        let telemetry = frame.iter().any(|&b| {
            matches!(
                decoder.push::<DeviceMsg>(b),
                Some(Ok(f)) if matches!(f.msg, DeviceMsg::Telemetry(_))
            )
        });
        if !telemetry {
            kept.extend_from_slice(frame);
        }
        start = i + 1;
    }
    partial.drain(..start);
    kept
}

/// A firmware core with its simulated plants, paced to the wall clock, whose host link is a
/// PTY reached through the symlink `link` (as udev's `/dev/serial/by-id` links are).
pub struct FirmwareServer {
    /// The stable path of the host link.
    pub link: std::path::PathBuf,
    control: Option<std::sync::mpsc::Sender<LinkControl>>,
    thread: Option<thread::JoinHandle<()>>,
    /// The camera served beside the link ([`crate::camera_server`]), if the robot has one.
    pub camera: Option<crate::camera_server::CameraServer>,
}

/// The robot's camera to serve beside a firmware server.
#[derive(Debug, Clone)]
pub struct CameraOptions {
    /// The description's camera.
    pub section: ferrobot_description::CameraSection,
    /// Seed of the depth noise.
    pub seed: u64,
    /// Simulate the depth noise.
    pub noise: bool,
    /// How far the camera sits off its URDF mount, in the camera link's frame
    /// ([`crate::camera::SimCamera::set_mount_error`]); identity for none.
    pub mount_error: nalgebra::Isometry3<f64>,
    /// Draw the description's hand-eye marker on the robot.
    pub marker: bool,
}

impl CameraOptions {
    /// The camera of `section` on `body` in `scene`, or `None` if the URDF has no such
    /// optical frame.
    pub fn camera(
        &self,
        scene: &crate::scene::Scene,
        body: &crate::body::RobotBody,
    ) -> Option<crate::camera::BandedCamera> {
        let mut cam =
            crate::camera::BandedCamera::new(scene, body, &self.section, self.seed, self.noise)?;
        cam.set_mount_error(body, &self.mount_error);
        cam.show_decals(self.marker);
        Some(cam)
    }
}

impl FirmwareServer {
    /// Unplug or plug the host link.
    pub fn control(&self, c: LinkControl) {
        if let Some(tx) = &self.control {
            let _ = tx.send(c);
        }
    }
}

impl Drop for FirmwareServer {
    /// Stop serving and remove the link this server made.
    fn drop(&mut self) {
        self.camera = None;
        self.control = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A new PTY behind the symlink `link`, which must not exist (creating a symlink never
/// replaces anything): nothing at that path is ever removed or replaced, except the symlink
/// this server made itself.
fn host_pty(link: &std::path::Path) -> Result<(TTYPort, TTYPort, String), ServeError> {
    let (master, slave, name) = pty()?;
    std::os::unix::fs::symlink(&name, link).map_err(|e| match e.kind() {
        io::ErrorKind::AlreadyExists => ServeError::LinkExists(link.to_path_buf()),
        _ => ServeError::Io(e),
    })?;
    Ok((master, slave, name))
}

/// Close the host PTY, if open, and remove `link` if it is still the symlink to it this server
/// made.
fn unplug(port: &mut Option<(TTYPort, TTYPort, String)>, link: &std::path::Path) {
    if let Some((_, _, name)) = port.take() {
        if std::fs::read_link(link).is_ok_and(|t| t.as_os_str() == name.as_str()) {
            let _ = std::fs::remove_file(link);
        }
    }
}

/// Serve `sim`'s host link on a PTY behind `link`, in real time, on a thread of its own, and
/// its world's camera (`camera`) on the Unix socket `LINK.camera`
/// ([`crate::camera_server::socket_beside`]).
pub fn serve_firmware(
    mut sim: crate::LockstepSim,
    link: std::path::PathBuf,
    camera: Option<CameraOptions>,
) -> Result<FirmwareServer, ServeError> {
    let (tx, rx) = std::sync::mpsc::channel();
    let (tap, truth_rx) = std::sync::mpsc::channel();
    let camera = match (camera, sim.body()) {
        (Some(c), Some(body)) => {
            let Some(cam) = c.camera(sim.scene(), body) else {
                return Err(ServeError::Io(io::Error::other(format!(
                    "the URDF has no camera frame {:?}",
                    c.section.frame
                ))));
            };
            Some(crate::camera_server::serve_camera(
                &crate::camera_server::socket_beside(&link),
                cam,
                c.section.rate,
                crate::camera_server::tap_truth(tap),
            )?)
        }
        _ => None,
    };
    let mut port = Some(host_pty(&link)?);
    let path = link.clone();
    let thread = thread::spawn(move || {
        let start = Instant::now();
        let t0 = sim.now_us();
        let mut buf = [0u8; 1024];
        // While muted, the end of the output not yet passed (a frame without its delimiter
        // yet); passed on when the telemetry is unmuted.
        let mut muted = false;
        let mut held = Vec::new();
        loop {
            match rx.try_recv() {
                Ok(LinkControl::Unplug) => unplug(&mut port, &path),
                Ok(LinkControl::Plug) if port.is_none() => port = host_pty(&path).ok(),
                Ok(LinkControl::Mute) => muted = true,
                Ok(LinkControl::Unmute) => muted = false,
                Ok(_) => {}
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    unplug(&mut port, &path);
                    return;
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => {}
            }
            match port.as_mut() {
                Some((master, _, _)) => match master.read(&mut buf) {
                    Ok(n) if n > 0 => sim.write_host(&buf[..n]),
                    _ => {}
                },
                None => thread::sleep(Duration::from_millis(1)),
            }
            sim.run_until(t0 + micros(start));
            crate::camera_server::answer_truth_requests(&truth_rx, || sim.truth());
            let mut out = sim.take_host_output();
            if muted {
                out = without_telemetry(&mut held, &out);
            } else if !held.is_empty() {
                held.append(&mut out);
                out = std::mem::take(&mut held);
            }
            if let Some((master, _, _)) = port.as_mut() {
                if !out.is_empty() {
                    let _ = master.write_all(&out);
                }
            }
        }
    });
    Ok(FirmwareServer {
        link,
        control: Some(tx),
        thread: Some(thread),
        camera,
    })
}

/// Serve `sim` behind the symlink `link` (see [`serve_firmware`]), announce it with one JSON
/// line on standard output, then obey `unplug`, `plug`, `mute` and `unmute` lines
/// ([`LinkControl`]) on standard input until it
/// closes. The body of `ferrobot sim-firmware` and of the HIL measurements.
pub fn run_firmware_server(
    sim: crate::LockstepSim,
    robot: &str,
    link: std::path::PathBuf,
    camera: Option<CameraOptions>,
) -> Result<(), ServeError> {
    use std::io::BufRead;
    let server = serve_firmware(sim, link.clone(), camera)?;
    let camera = server.camera.as_ref().map(|c| c.path.display().to_string());
    println!(
        "{}",
        serde_json::json!({"robot": robot, "host": link.display().to_string(), "camera": camera})
    );
    for line in std::io::stdin().lock().lines() {
        match line.as_deref().map(str::trim) {
            Ok("unplug") => server.control(LinkControl::Unplug),
            Ok("plug") => server.control(LinkControl::Plug),
            Ok("mute") => server.control(LinkControl::Mute),
            Ok("unmute") => server.control(LinkControl::Unmute),
            Ok(_) => {}
            Err(_) => break,
        }
    }
    Ok(())
}
