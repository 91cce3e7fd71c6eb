//! The host-run firmware's loop: the firmware core ([`ferrobot_firmware::Firmware`], sans-IO)
//! between its host link and its plant lines ([`Wires`]), on one thread, as a board's shell
//! runs it (`boards/mps2-an386`'s firmware task): feed what arrived, poll the core on its
//! deadline, send what it queued, and wait on the ports until the next deadline. With a
//! virtual clock, plant bytes are taken only as far as the conductor released them, and the
//! loop reports idle once it has done everything due.

use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ferrobot_firmware::config::RobotProfile;
use ferrobot_firmware::{time, Firmware, Link};
use nix::poll::{poll, PollFd, PollFlags};
use serialport::TTYPort;

use super::clock::Clock;
use super::wires::{Wires, BASE, SERVO};

/// Longest the loop sleeps between looks at its quit flag and its lost devices.
const TICK: Duration = Duration::from_millis(10);

/// The host end of the firmware's host link.
pub struct HostEnd {
    port: TTYPort,
    /// Whether the other end may be closed (a PTY master we made): then what the firmware
    /// sends while nobody listens is dropped, as a board drops it with USB unplugged.
    master: bool,
    connected: bool,
    checked: Instant,
}

impl HostEnd {
    /// The master of a PTY whose slave a host opens.
    pub fn master(port: TTYPort) -> Self {
        HostEnd {
            port,
            master: true,
            connected: false,
            checked: Instant::now() - TICK,
        }
    }

    /// A port opened by path (the board's end of an emulated board's host link).
    pub fn opened(port: TTYPort) -> Self {
        HostEnd {
            port,
            master: false,
            connected: true,
            checked: Instant::now(),
        }
    }

    /// Whether a host has the other end open (looked at every [`TICK`]).
    fn refresh(&mut self) -> bool {
        if self.master && self.checked.elapsed() >= TICK {
            self.checked = Instant::now();
            let mut fds = [PollFd::new(self.port.as_raw_fd(), PollFlags::POLLIN)];
            self.connected = match poll(&mut fds, 0) {
                Ok(_) => !fds[0]
                    .revents()
                    .is_some_and(|r| r.contains(PollFlags::POLLHUP)),
                Err(_) => false,
            };
        }
        self.connected
    }
}

/// Wall-clock instants of servo-loop ticks, shared with whoever measures them.
pub type TickLog = std::sync::Arc<std::sync::Mutex<Vec<Instant>>>;

/// The firmware core with its ports and clock.
pub struct HostRun {
    fw: Firmware,
    host: HostEnd,
    wires: Wires,
    host_rx: Vec<u8>,
    /// Wall-clock instants at which each servo-loop tick's sync read left, for the
    /// loop-period benchmark (kept only when `Some`).
    pub ticks: Option<TickLog>,
}

impl HostRun {
    /// The firmware of `profile` ("host" its board name) on these ports.
    pub fn new(profile: RobotProfile, host: HostEnd, wires: Wires) -> Self {
        let now = time::Instant::from_micros(wires.now_us());
        HostRun {
            fw: Firmware::new(profile, "host", now),
            host,
            wires,
            host_rx: Vec::new(),
            ticks: None,
        }
    }

    /// Run until `quit` is set or the virtual clock's conductor goes away; returns why it
    /// stopped. On the way out the base is told to stop (and a Create 2's Open Interface is
    /// closed).
    pub fn run(&mut self, quit: &AtomicBool) -> String {
        let why = loop {
            if quit.load(Ordering::Relaxed) {
                break "stopped by its owner".to_string();
            }
            if let Err(why) = self.step() {
                break why;
            }
        };
        self.park_base();
        why
    }

    /// One pass: feed, poll, send, report, wait for the ports.
    pub fn step(&mut self) -> Result<(), String> {
        let now = time::Instant::from_micros(self.wires.now_us());
        self.feed(now);
        if self.fw.next_deadline() <= now {
            self.fw.poll(now);
        }
        self.flush();
        let deadline = self.fw.next_deadline();
        if deadline <= now {
            return Ok(());
        }
        self.wires.idle_until(deadline.as_micros());
        let wait = match &self.wires.clock {
            Clock::Wall(_) => Duration::from_micros(deadline.as_micros() - now.as_micros()),
            Clock::Virtual(_) => TICK,
        };
        let host = self.host.refresh().then(|| self.host.port.as_raw_fd());
        let ready = self.wires.wait(wait.min(TICK), host.as_slice())?;
        if !ready.is_empty() {
            let mut buf = [0u8; 1024];
            match nix::unistd::read(self.host.port.as_raw_fd(), &mut buf) {
                Ok(n) => self.host_rx.extend_from_slice(&buf[..n]),
                Err(nix::errno::Errno::EAGAIN) | Err(nix::errno::Errno::EINTR) => {}
                Err(_) => self.host.connected = false,
            }
        }
        Ok(())
    }

    /// Hand the firmware what it may take now.
    fn feed(&mut self, now: time::Instant) {
        if !self.host_rx.is_empty() {
            self.fw.on_host_bytes(now, &self.host_rx);
            self.host_rx.clear();
        }
        let servo = self.wires.take(SERVO);
        if !servo.is_empty() {
            self.fw.on_servo_bytes(now, &servo);
        }
        let base = self.wires.take(BASE);
        if !base.is_empty() {
            self.fw.on_base_bytes(now, &base);
        }
    }

    /// Send what the core queued on every link.
    fn flush(&mut self) {
        let out = self.fw.pending(Link::Host);
        if !out.is_empty() {
            let n = out.len();
            if self.host.refresh() {
                // A host that stops reading loses frames rather than stalling the loop.
                let _ = std::io::Write::write_all(&mut self.host.port, out);
            }
            self.fw.consume(Link::Host, n);
        }
        for (i, link) in [(SERVO, Link::Servo), (BASE, Link::Base)] {
            let out = self.fw.pending(link);
            if out.is_empty() {
                continue;
            }
            // A tick's bus cycle starts with its sync read (instruction at byte 7).
            if i == SERVO && out.get(7) == Some(&ferrobot_protocol::dxl::inst::SYNC_READ) {
                if let Some(Ok(mut t)) = self.ticks.as_ref().map(|t| t.lock()) {
                    t.push(Instant::now());
                }
            }
            let n = out.len();
            self.wires.send(i, out);
            self.fw.consume(link, n);
        }
    }

    /// The base told to stop, and a Create 2's Open Interface closed (Stop, opcode 173:
    /// streams end and the robot takes no more commands until the next Start).
    fn park_base(&mut self) {
        use ferrobot_protocol::BaseKind;
        let mut buf = [0u8; 32];
        let bytes: Vec<u8> = match self.fw.profile().base.kind {
            BaseKind::Kobuki => ferrobot_protocol::kobuki::encode_base_control(0, 0, &mut buf)
                .map(|n| buf[..n].to_vec())
                .unwrap_or_default(),
            BaseKind::Create2 => {
                use ferrobot_protocol::create2::{OP_DRIVE_DIRECT, OP_STOP};
                vec![OP_DRIVE_DIRECT, 0, 0, 0, 0, OP_STOP]
            }
            _ => return,
        };
        self.wires.send(BASE, &bytes);
    }
}
