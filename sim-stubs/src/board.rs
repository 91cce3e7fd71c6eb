//! The plants of an emulated board, on one clock with its firmware: the thin thread around the
//! [`Conductor`].
//!
//! [`BoardServer::start`] makes a pseudo-terminal for each serial port of the board (host
//! link, servo bus, base, virtual-time link) for QEMU to open, and one more for the host: the
//! server relays the host link between the two, so it can record every frame, and drops what
//! the firmware sends while no host has the port open, as a USB serial port would. One thread
//! runs it all: it reads what the board sends, steps the conductor, and paces simulated time
//! to at most [`BoardOptions::real_time_factor`] times the wall clock (the host on the other
//! end is a real-time program with its own heartbeats). When the machine is too slow for that
//! pace, simulated time simply runs slower; the firmware and the plants still agree on it.
//!
//! Everything needed to tell why a test failed is kept: counters of the conductor, the plants
//! and the lines, and the last frames on each link ([`BoardServer::report`]).

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::os::fd::AsRawFd;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ferrobot_firmware::Link;
use ferrobot_protocol::{DeviceMsg, Frame, FrameDecoder, HostMsg};
use nix::poll::{poll, PollFd, PollFlags};
use serialport::{SerialPort, TTYPort};

use crate::conductor::{Conductor, LINES};
use crate::hardware::Hardware;
use crate::lockstep::SimError;
use crate::robots;
use crate::scene::Scene;
use crate::serve::ServeError;

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

/// What went over one link, newest last.
#[derive(Default)]
struct LinkTrace {
    to_board: VecDeque<(u64, String)>,
    from_board: VecDeque<(u64, String)>,
}

impl LinkTrace {
    fn push(&mut self, to_board: bool, t: u64, what: String) {
        let q = if to_board {
            &mut self.to_board
        } else {
            &mut self.from_board
        };
        if q.len() == TRACE_LEN {
            q.pop_front();
        }
        q.push_back((t, what));
    }
}

fn hex(bytes: &[u8]) -> String {
    let mut s = String::new();
    for b in bytes.iter().take(40) {
        let _ = write!(s, "{b:02X} ");
    }
    if bytes.len() > 40 {
        let _ = write!(s, "... ({} bytes)", bytes.len());
    }
    s.trim_end().to_string()
}

fn short(s: String) -> String {
    if s.len() > 200 {
        let cut = (0..=200)
            .rev()
            .find(|&i| s.is_char_boundary(i))
            .unwrap_or(0);
        format!("{}...", &s[..cut])
    } else {
        s
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
}

impl Inner {
    fn record_plant(&mut self, link: Link, to_board: bool, bytes: &[u8]) {
        let t = self.conductor.now_us();
        let trace = if link == Link::Servo {
            &mut self.servo
        } else {
            &mut self.base
        };
        trace.push(to_board, t, hex(bytes));
    }

    fn record_host(&mut self, to_board: bool, bytes: &[u8]) {
        let t = self.conductor.now_us();
        let mut seen = Vec::new();
        if to_board {
            self.host_to_board
                .feed(bytes, |r: Result<Frame<HostMsg>, _>| {
                    seen.push(short(match r {
                        Ok(f) => format!("#{} {:?}", f.seq, f.msg),
                        Err(e) => format!("bad frame: {e:?}"),
                    }))
                });
        } else {
            self.board_to_host
                .feed(bytes, |r: Result<Frame<DeviceMsg>, _>| {
                    seen.push(short(match r {
                        Ok(f) => format!("#{} {:?}", f.seq, f.msg),
                        Err(e) => format!("bad frame: {e:?}"),
                    }))
                });
        }
        for s in seen {
            self.host.push(to_board, t, s);
        }
    }
}

/// A pseudo-terminal: our master end and, when kept, the other end held open.
struct Pty {
    master: TTYPort,
    _slave: Option<TTYPort>,
    path: String,
}

fn pty(keep_slave: bool) -> Result<Pty, ServeError> {
    let (mut master, slave) =
        TTYPort::pair().map_err(|e| ServeError::Io(std::io::Error::other(e.to_string())))?;
    let path = slave.name().unwrap_or_default();
    master
        .set_timeout(TICK)
        .map_err(|e| ServeError::Io(std::io::Error::other(e.to_string())))?;
    Ok(Pty {
        master,
        _slave: keep_slave.then_some(slave),
        path,
    })
}

/// Write all of `bytes` unless the other side stops reading for [`TICK`]; returns how many
/// were written.
fn write_some(port: &mut TTYPort, bytes: &[u8]) -> usize {
    let mut done = 0;
    while done < bytes.len() {
        match std::io::Write::write(port, &bytes[done..]) {
            Ok(0) | Err(_) => break,
            Ok(n) => done += n,
        }
    }
    done
}

/// Read what is there (the port is known readable); `None` when the other side is closed.
fn read_now(port: &TTYPort, buf: &mut [u8]) -> Option<usize> {
    match nix::unistd::read(port.as_raw_fd(), buf) {
        Ok(n) => Some(n),
        Err(nix::errno::Errno::EAGAIN) | Err(nix::errno::Errno::EINTR) => Some(0),
        Err(_) => None,
    }
}

/// Whether a host has the host end open (no hang-up on our master).
fn host_present(port: &TTYPort) -> bool {
    let mut fds = [PollFd::new(port.as_raw_fd(), PollFlags::POLLIN)];
    match poll(&mut fds, 0) {
        Ok(_) => !fds[0]
            .revents()
            .is_some_and(|r| r.contains(PollFlags::POLLHUP)),
        Err(_) => false,
    }
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
        let hw = Hardware::in_scene(&desc, opts.seed, scene).map_err(ServeError::Scene)?;
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
        }));
        let quit = Arc::new(AtomicBool::new(false));
        let ports = Ports {
            board_host,
            servo,
            base,
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

    /// What the server knows, for a person reading a failed test: clock, counters of the
    /// conductor, the plants and the lines, and the last frames on each link.
    pub fn report(&self) -> String {
        let mut i = self.lock();
        let mut s = String::new();
        let now = i.conductor.now_us();
        let st = i.conductor.stats();
        let wall = i.first_report.map(|t| t.elapsed().as_secs_f64());
        let _ = writeln!(
            s,
            "plants of {:?}: simulated time {:.3} s{}; {} steps, {} reports from the board, {} bad clock frames, {} re-anchorings of the pace{}",
            i.robot,
            now as f64 * 1e-6,
            wall.map(|w| format!(" after {w:.1} s of wall time since the board's first report ({:.2}x real time)", now as f64 * 1e-6 / w.max(1e-9))).unwrap_or_else(|| " (the board never reported on its clock link)".into()),
            st.advances,
            st.reports,
            st.bad_clock_frames,
            i.paced_behind,
            i.stopped.as_ref().map(|w| format!("; server stopped: {w}")).unwrap_or_default()
        );
        match i.conductor.report() {
            Some(r) => {
                let _ = writeln!(
                    s,
                    "board's last report: at {} us, next {} us, consumed {:?} and sent {:?} bytes (servo, base); the plants wrote {:?} and read {:?}",
                    r.now_us,
                    if r.next_us == u64::MAX { "none".to_string() } else { r.next_us.to_string() },
                    r.rx,
                    r.tx,
                    st.written,
                    st.read
                );
            }
            None => {
                let _ = writeln!(s, "board's last report: none");
            }
        }
        let hw = i.conductor.hardware();
        let c = hw.chain.stats;
        let _ = writeln!(
            s,
            "servo bus (plants' side): {} instructions, {} status packets, {} bad packets; line bytes [to servos, from servos, to base, from base] = {:?}",
            c.instructions,
            c.statuses,
            c.bad_packets,
            hw.line_bytes()
        );
        for id in 1..=32u8 {
            if let Some(sv) = hw.chain.servo(id) {
                let _ = writeln!(
                    s,
                    "  servo {id}: angle {:.4} rad, torque {}, hardware error {:#04x}{}",
                    sv.theta,
                    if sv.torque_enabled() { "on" } else { "off" },
                    sv.hardware_error(),
                    if sv.silent { ", silent" } else { "" }
                );
            }
        }
        if let Some(b) = hw.base.as_ref() {
            let _ = writeln!(
                s,
                "base: truth {:?}, wheel speed {:?}, target {:?}, {} bad packets",
                b.drive.truth,
                b.drive.speed,
                b.drive.target,
                b.bad_packets()
            );
        }
        let _ = writeln!(
            s,
            "host link: {} bytes to the board, {} from it, {} dropped while no host had the port open (host connected: {})",
            i.host_bytes[0], i.host_bytes[1], i.host_dropped, i.host_connected
        );
        for (name, trace) in [
            ("host", &i.host),
            ("servo bus", &i.servo),
            ("base", &i.base),
        ] {
            for (dir, q) in [
                ("to the board", &trace.to_board),
                ("from the board", &trace.from_board),
            ] {
                if q.is_empty() {
                    continue;
                }
                let _ = writeln!(s, "last on {name}, {dir}:");
                for (t, what) in q {
                    let _ = writeln!(s, "  {:>10.6} s  {what}", *t as f64 * 1e-6);
                }
            }
        }
        s
    }
}

impl Drop for BoardServer {
    fn drop(&mut self) {
        self.quit.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

struct Ports {
    board_host: Pty,
    servo: Pty,
    base: Option<Pty>,
    clock: Pty,
    host: Pty,
}

/// The server thread; returns why it stopped.
fn run(mut p: Ports, inner: &Mutex<Inner>, quit: &AtomicBool, opts: BoardOptions) -> String {
    let rtf = opts.real_time_factor;
    let lock = || inner.lock().unwrap_or_else(|e| e.into_inner());
    let mut buf = [0u8; 4096];
    // Pace: simulated time `origin.1` was released at wall time `origin.0`.
    let mut origin: Option<(Instant, u64)> = None;
    let mut host_connected = false;
    let mut last_host_check = Instant::now() - TICK;
    while !quit.load(Ordering::Relaxed) {
        // Step the clock as far as the pace allows.
        let mut wait = TICK;
        {
            let mut i = lock();
            let hold = i.hold_at;
            if let Some(next) = i
                .conductor
                .poll()
                .map(|t| t.min(hold))
                .filter(|t| *t > i.conductor.now_us())
            {
                let now = i.conductor.now_us();
                let (wall0, sim0) = *origin.get_or_insert((Instant::now(), now));
                let due = if rtf.is_finite() && rtf > 0.0 {
                    wall0 + Duration::from_secs_f64((next - sim0) as f64 * 1e-6 / rtf)
                } else {
                    Instant::now()
                };
                let wall = Instant::now();
                if due <= wall {
                    i.conductor.advance(next);
                    if wall > due + SLACK {
                        origin = Some((wall, next));
                        i.paced_behind += 1;
                    }
                    wait = Duration::ZERO;
                } else {
                    wait = wait.min(due - wall);
                }
            }
            let clock = i.conductor.take_clock_output();
            if !clock.is_empty() && write_some(&mut p.clock.master, &clock) < clock.len() {
                return "the board does not read its clock link".into();
            }
            for (link, port) in [
                (Link::Servo, Some(&mut p.servo)),
                (Link::Base, p.base.as_mut()),
            ] {
                let out = i.conductor.take_board_output(link);
                if out.is_empty() {
                    continue;
                }
                i.record_plant(link, true, &out);
                if let Some(port) = port {
                    write_some(&mut port.master, &out);
                }
            }
        }
        if last_host_check.elapsed() >= TICK {
            last_host_check = Instant::now();
            host_connected = host_present(&p.host.master);
            lock().host_connected = host_connected;
        }
        // Look at the ports.
        let mut watch = vec![(3usize, p.board_host.master.as_raw_fd())];
        if opts.plants {
            watch.push((0, p.clock.master.as_raw_fd()));
            watch.push((1, p.servo.master.as_raw_fd()));
            if let Some(b) = p.base.as_ref() {
                watch.push((2, b.master.as_raw_fd()));
            }
        }
        if host_connected {
            watch.push((4, p.host.master.as_raw_fd()));
        }
        let mut fds: Vec<PollFd> = watch
            .iter()
            .map(|(_, fd)| PollFd::new(*fd, PollFlags::POLLIN))
            .collect();
        let ms = wait.as_micros().div_ceil(1000).min(TICK.as_millis()) as i32;
        if let Err(e) = poll(&mut fds, ms) {
            if e != nix::errno::Errno::EINTR {
                return format!("poll failed: {e}");
            }
            continue;
        }
        for ((which, _), fd) in watch.iter().zip(&fds) {
            let ready = fd.revents().unwrap_or(PollFlags::empty());
            if !ready.intersects(PollFlags::POLLIN | PollFlags::POLLHUP | PollFlags::POLLERR) {
                continue;
            }
            let port = match which {
                0 => &p.clock.master,
                1 => &p.servo.master,
                2 => match p.base.as_ref() {
                    Some(b) => &b.master,
                    None => continue,
                },
                3 => &p.board_host.master,
                _ => &p.host.master,
            };
            let Some(n) = read_now(port, &mut buf) else {
                if *which == 4 {
                    host_connected = false;
                }
                continue;
            };
            if n == 0 {
                continue;
            }
            let bytes = &buf[..n];
            let mut i = lock();
            match which {
                0 => {
                    i.conductor.on_clock_bytes(bytes);
                    if i.first_report.is_none() && i.conductor.report().is_some() {
                        i.first_report = Some(Instant::now());
                    }
                }
                1 | 2 => {
                    let link = LINES[which - 1];
                    i.record_plant(link, false, bytes);
                    i.conductor.on_board_bytes(link, bytes);
                }
                3 => {
                    i.host_bytes[1] += n as u64;
                    i.record_host(false, bytes);
                    if host_connected {
                        let sent = write_some(&mut p.host.master, bytes);
                        i.host_dropped += (n - sent) as u64;
                    } else {
                        i.host_dropped += n as u64;
                    }
                }
                _ => {
                    i.host_bytes[0] += n as u64;
                    i.record_host(true, bytes);
                    write_some(&mut p.board_host.master, bytes);
                }
            }
        }
    }
    "stopped by its owner".into()
}
