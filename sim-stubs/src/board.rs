//! The plants of an emulated board, on one clock with its firmware: the thin thread around the
//! [`Conductor`]. [`BoardServer::start`] makes a pseudo-terminal for each serial port of the
//! board (host link, servo bus, base, virtual-time link) for QEMU and one for the host, relays
//! the host link between the two, and paces simulated time to at most
//! [`BoardOptions::real_time_factor`] times the wall clock; [`BoardServer::report`] tells why a
//! test failed. Design: `docs/design/sim-stubs.md`, "board".

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ferrobot_firmware::Link;
use ferrobot_protocol::FrameDecoder;

use crate::conductor::Conductor;
use crate::hardware::Hardware;
use crate::lockstep::SimError;
use crate::robots;
use crate::scene::Scene;
use crate::serve::ServeError;

mod ports;
mod report;
mod run_loop;
mod wiring;

pub use wiring::Wiring;

use ports::{pty, Ports};
use report::LinkTrace;
use run_loop::run;

/// Entries kept per link and direction in the trace.
const TRACE_LEN: usize = 12;
/// Longest wait of the server thread between looks at its ports.
const TICK: Duration = Duration::from_millis(10);
/// How far the simulated clock may fall behind its pace before the pace is re-anchored
/// (rather than caught up at a faster rate).
const SLACK: Duration = Duration::from_millis(50);

/// Where QEMU's serial ports go (the n-th `-serial` is UART n).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BoardPorts {
    /// UART0: the board's end of the host link.
    pub host: String,
    /// UART1: the servo bus.
    pub servo_bus: String,
    /// UART2: the base, if the robot has one.
    pub base: Option<String>,
    /// UART4: the virtual-time link.
    pub clock: String,
}

/// Options of a [`BoardServer`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardOptions {
    /// Seed of the plants' noise.
    pub seed: u64,
    /// Most simulated seconds per wall-clock second (`f64::INFINITY`: unpaced).
    pub real_time_factor: f64,
    /// Serve the plants and the clock (`false` leaves the board's clock, servo and base ports
    /// unanswered and relays only the host link: what a host sees when the plants are
    /// missing).
    pub plants: bool,
}

impl Default for BoardOptions {
    fn default() -> Self {
        Self {
            seed: 1,
            real_time_factor: 1.0,
            plants: true,
        }
    }
}

struct Inner {
    conductor: Conductor,
    robot: String,
    servo: LinkTrace,
    base: LinkTrace,
    host: LinkTrace,
    host_to_board: FrameDecoder,
    board_to_host: FrameDecoder,
    host_bytes: [u64; 2],
    host_dropped: u64,
    host_connected: bool,
    first_report: Option<Instant>,
    paced_behind: u64,
    /// Simulated time the clock holds at (µs), until raised.
    hold_at: u64,
    stopped: Option<String>,
    /// The plant lines' cables, as a test sets them.
    wiring: Wiring,
}

/// The plants of an emulated robot, served to its firmware in QEMU on one clock.
pub struct BoardServer {
    /// Where QEMU's serial ports go.
    pub board: BoardPorts,
    /// The host's end of the host link: what a program opens to talk to the firmware.
    pub host: PathBuf,
    inner: Arc<Mutex<Inner>>,
    quit: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    scene: Arc<crate::scene::Scene>,
    body: Option<Arc<crate::body::RobotBody>>,
}

impl BoardServer {
    /// Make the ports and start serving the plants of `robot` in an empty world.
    pub fn start(robot: &str, opts: BoardOptions) -> Result<BoardServer, ServeError> {
        Self::start_in(robot, opts, &Scene::empty())
    }

    /// [`BoardServer::start`] in `scene`: the robot at the scene's start pose, the scene's
    /// bodies in the physics world on the conductor's clock. Fails when a scene body overlaps
    /// the robot at the start.
    pub fn start_in(
        robot: &str,
        opts: BoardOptions,
        scene: &Scene,
    ) -> Result<BoardServer, ServeError> {
        let desc = robots::by_name(robot)
            .ok_or_else(|| ServeError::Sim(SimError::UnknownRobot(robot.into())))?;
        Self::start_robot(&desc, opts, scene)
    }

    /// [`BoardServer::start_in`] for the robot `desc` (a description's: its bus at the rate
    /// the description gives).
    pub fn start_robot(
        desc: &robots::SimRobot,
        opts: BoardOptions,
        scene: &Scene,
    ) -> Result<BoardServer, ServeError> {
        let robot = desc.name.as_str();
        let hw = Hardware::in_scene(desc, opts.seed, scene).map_err(ServeError::Scene)?;
        let body = desc.body.clone();
        let scene = Arc::new(scene.clone());
        let has_base = hw.base.is_some();
        let board_host = pty(true)?;
        let servo = pty(true)?;
        let base = if has_base { Some(pty(true)?) } else { None };
        let clock = pty(true)?;
        let host = pty(false)?;
        let board = BoardPorts {
            host: board_host.path.clone(),
            servo_bus: servo.path.clone(),
            base: base.as_ref().map(|p| p.path.clone()),
            clock: clock.path.clone(),
        };
        let host_path = PathBuf::from(&host.path);
        let inner = Arc::new(Mutex::new(Inner {
            conductor: Conductor::new(hw),
            robot: robot.to_string(),
            servo: LinkTrace::default(),
            base: LinkTrace::default(),
            host: LinkTrace::default(),
            host_to_board: FrameDecoder::new(),
            board_to_host: FrameDecoder::new(),
            host_bytes: [0; 2],
            host_dropped: 0,
            host_connected: false,
            first_report: None,
            paced_behind: 0,
            hold_at: u64::MAX,
            stopped: None,
            wiring: Wiring::new(&servo.path, base.as_ref().map(|b| b.path.as_str()))
                .map_err(ServeError::Io)?,
        }));
        let quit = Arc::new(AtomicBool::new(false));
        let ports = Ports {
            board_host,
            lines: [Some(servo), base],
            clock,
            host,
        };
        let thread = {
            let inner = inner.clone();
            let quit = quit.clone();
            std::thread::Builder::new()
                .name(format!("ferrobot-board-{robot}"))
                .spawn(move || {
                    let why = run(ports, &inner, &quit, opts);
                    if let Ok(mut i) = inner.lock() {
                        i.stopped = Some(why);
                    }
                })
                .map_err(ServeError::Io)?
        };
        Ok(BoardServer {
            board,
            host: host_path,
            inner,
            quit,
            thread: Some(thread),
            scene,
            body,
        })
    }

    /// The world's ground truth now ([`crate::lockstep::truth_of`]).
    pub fn truth(&self) -> crate::lockstep::Truth {
        self.with_hardware(|hw, now| {
            crate::lockstep::truth_of(hw, now, &self.scene, self.body.as_deref())
        })
    }

    /// Serve the robot's camera of this world on a new Unix socket at `path`
    /// ([`crate::camera_server`]); dropping the returned server stops it.
    pub fn serve_camera(
        &self,
        path: &std::path::Path,
        camera: &crate::camera_server::CameraOptions,
    ) -> Result<crate::camera_server::CameraServer, ServeError> {
        let body = self.body.clone().ok_or_else(|| {
            ServeError::Io(std::io::Error::other(
                "the robot has no body to mount a camera on",
            ))
        })?;
        let cam = camera.camera(&self.scene, &body).ok_or_else(|| {
            ServeError::Io(std::io::Error::other(format!(
                "the URDF has no camera frame {:?}",
                camera.section.frame
            )))
        })?;
        let (inner, scene) = (self.inner.clone(), self.scene.clone());
        let truth = move || {
            let mut i = inner.lock().ok()?;
            let now = i.conductor.now_us();
            let hw = i.conductor.hardware();
            hw.chain.advance_to(now);
            Some(crate::lockstep::truth_of(hw, now, &scene, Some(&body)))
        };
        crate::camera_server::serve_camera(path, cam, camera.section.rate, truth)
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.lock().conductor.now_us()
    }

    /// A reader of simulated time (µs) that outlives borrows of the server: for a program's
    /// timeouts counted in the board's time ([`BoardServer::now_us`] each call).
    pub fn clock(&self) -> impl Fn() -> u64 + Send + Sync + 'static {
        let inner = self.inner.clone();
        move || {
            inner
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .conductor
                .now_us()
        }
    }

    /// Whether the firmware has reported on its clock link at least once.
    pub fn board_reported(&self) -> bool {
        self.lock().first_report.is_some()
    }

    /// Why the server thread stopped, if it has.
    pub fn stopped(&self) -> Option<String> {
        self.lock().stopped.clone()
    }

    /// Wait up to `timeout` (wall time) for the firmware's first report on its clock link.
    pub fn wait_for_board(&self, timeout: Duration) -> Result<(), ServeError> {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            if self.board_reported() {
                return Ok(());
            }
            if let Some(why) = self.stopped() {
                return Err(ServeError::Io(std::io::Error::other(why)));
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        Err(ServeError::Io(std::io::Error::other(format!(
            "the firmware did not report on its virtual-time link (UART4, {}) within {timeout:?}: \
             is QEMU running this tree's mps2-an386 firmware with its fifth -serial on that port?",
            self.board.clock
        ))))
    }

    /// Let the clock run up to `t_us` and hold there; blocks until it is there and the board
    /// has settled (or `timeout` of wall time passed: false). Holding keeps the board at that
    /// instant for a snapshot.
    ///
    /// Settled means what [`Conductor::poll`] means: the board reported idle at `t_us`, and
    /// every byte it sent until then has reached the plants. The board's idle report and the
    /// bytes it sent just before travel on different pseudo-terminals, so the report alone
    /// may come first; a snapshot then would miss those bytes on a busy machine.
    pub fn run_to(&self, t_us: u64, timeout: Duration) -> bool {
        self.lock().hold_at = t_us;
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            let mut i = self.lock();
            let settled = i.conductor.now_us() == t_us && i.conductor.poll().is_some();
            if settled || i.conductor.now_us() > t_us || i.stopped.is_some() {
                return settled;
            }
            drop(i);
            std::thread::sleep(Duration::from_millis(1));
        }
        false
    }

    /// The plant lines' cables ([`Wiring`]): their stable links, plugged or not, and the rate
    /// their devices listen at.
    pub fn wiring(&self) -> Wiring {
        self.lock().wiring.clone()
    }

    /// Change the plant lines' cables (fault injection): the server unplugs and plugs them
    /// at its next pass.
    pub fn rewire(&self, f: impl FnOnce(&mut Wiring)) {
        f(&mut self.lock().wiring);
    }

    /// Let the clock run freely again after [`BoardServer::run_to`].
    pub fn release(&self) {
        self.lock().hold_at = u64::MAX;
    }

    /// Run `f` on the plants at the current simulated time (ground truth, fault injection).
    pub fn with_hardware<T>(&self, f: impl FnOnce(&mut Hardware, u64) -> T) -> T {
        let mut inner = self.lock();
        let now = inner.conductor.now_us();
        let hw = inner.conductor.hardware();
        hw.chain.advance_to(now);
        f(hw, now)
    }

    /// Carry out one control line ([`crate::console`]); returns the JSON answer.
    pub fn command(&self, line: &str) -> serde_json::Value {
        self.with_hardware(|hw, now| {
            if line.trim() == "bodies" {
                return crate::console::bodies(hw.world());
            }
            let mut noise = Vec::new();
            let answer =
                crate::console::command(&mut hw.chain, hw.base.as_mut(), now, line, &mut |b| {
                    noise.extend_from_slice(&b)
                });
            hw.inject_to_firmware(Link::Servo, now, &noise);
            answer
        })
    }
}

impl Drop for BoardServer {
    fn drop(&mut self) {
        self.quit.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.lock().wiring.remove_links();
    }
}
