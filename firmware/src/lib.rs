//! # ferrobot-firmware
//!
//! The board-independent firmware core of Ferrobot, sans-IO in the manner of smoltcp: a
//! [`Firmware`] is a pure state machine. A shell (a board's async tasks, a Linux process, or
//! the lockstep simulator) feeds it bytes from its three links and the time, calls
//! [`Firmware::poll`] no later than [`Firmware::next_deadline`], and sends what
//! [`Firmware::pending`] holds; [`shell`] is that shell for a board whose host link comes and
//! goes (USB). Nothing here blocks, allocates or panics: the crate denies
//! `unwrap`, `expect`, `panic` and unchecked indexing outside tests.
//!
//! What it runs:
//! * the servo-bus master ([`bus`]): configuration, one sync read and one sync write per tick,
//!   lost servos and hardware errors reported and never stalling the loop;
//! * joint control at the servo-loop rate ([`joint`]): cubic Hermite interpolation of queued
//!   setpoints, the joint PID of current mode, limits enforced whatever the host sends;
//! * the gripper state machine ([`gripper`]);
//! * the base drivers and odometry ([`base`]);
//! * safety: host watchdog, emergency stop, base safety sensors; every fault is reported.
//!
//! The one state, [`Firmware`], keeps its constructor and entry points here; its `impl` is
//! split over private modules by concern, as smoltcp splits its interface: the session with
//! the host (handshake, session gate, sequence numbers), the commands (one handler per
//! message kind), the servo loop, the safety layer (emergency stop, watchdog, and the last
//! gate between the controllers and the buses) and telemetry (faults, telemetry, counters).
//!
//! Time is a [`time::Instant`] on the shell's clock (µs from any epoch, never going
//! backwards); spans of it are [`time::Duration`]s. The wire's integer µs and ms are converted
//! where a message is handled or built.
#![no_std]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects
    )
)]
#![warn(missing_docs)]

pub mod base;
pub mod bus;
mod commands;
pub mod config;
pub mod dynamics;
pub mod gripper;
pub mod joint;
mod log;
mod safety;
mod servo;
mod session;
pub mod shell;
mod telemetry;
pub mod time;
pub mod txbuf;

use ferrobot_protocol::{FrameDecoder, HostMsg, JointKind, JointMode, LoopStats, Name, MAX_JOINTS};
use heapless::Vec;

use base::BaseDriver;
use bus::ServoBus;
pub use config::RobotProfile;
use gripper::Gripper;
use joint::JointControl;
use session::Session;
use time::{Duration, Instant};
use txbuf::TxBuf;

/// Firmware version, major/minor/patch.
pub const FIRMWARE_VERSION: [u8; 3] = [0, 1, 0];

/// The three links of the firmware.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Link {
    /// The host (USB CDC, UART, PTY, or in-process).
    Host,
    /// The Dynamixel servo bus.
    Servo,
    /// The mobile base.
    Base,
}

/// Size of the host transmit buffer, bytes.
pub const HOST_TX_LEN: usize = 4096;

/// The shortest servo-loop period the firmware runs, whatever its profile asks.
pub const MIN_LOOP_PERIOD: Duration = Duration::from_micros(250);

/// The firmware core.
pub struct Firmware {
    profile: RobotProfile,
    /// Per joint, the limits its row was configured with (at start or by `ConfigureJoint`):
    /// `SetLimits` may narrow a joint's limits within them, never widen them.
    envelope: Vec<ferrobot_protocol::JointLimits, MAX_JOINTS>,
    /// The arm's gravity model, as the host sent it, and whether the arm confirmed it.
    dynamics: dynamics::Dynamics,
    board: Name,
    joints: Vec<JointControl, MAX_JOINTS>,
    bus: ServoBus,
    base: BaseDriver,
    gripper: Option<(usize, Gripper)>,
    decoder: FrameDecoder,
    host_tx: TxBuf<HOST_TX_LEN>,
    tx_seq: u16,
    session: Session,
    watchdog_period: Duration,
    last_host_rx: Instant,
    watchdog_tripped: bool,
    estop: bool,
    telemetry_period: Duration,
    next_telemetry: Instant,
    loop_period: Duration,
    next_tick: Instant,
    tick_started: Instant,
    loop_stats: LoopStats,
    overrun_since_telemetry: bool,
    host_tx_dropped: u32,
    clamp_reported: u16,
    unsafe_reported: u16,
    lost_servos: u16,
}

impl Firmware {
    /// A firmware for `profile` on board `board`, starting at time `now`.
    pub fn new(profile: RobotProfile, board: &str, now: Instant) -> Self {
        let mut b = Name::new();
        for c in board.chars() {
            if b.push(c).is_err() {
                break;
            }
        }
        let bus = ServoBus::new(&profile.joints, profile.bus);
        let base = BaseDriver::new(profile.base);
        let envelope = profile.joints.iter().map(|c| c.limits).collect();
        let mut fw = Self {
            envelope,
            dynamics: dynamics::Dynamics::default(),
            board: b,
            joints: Vec::new(),
            bus,
            base,
            gripper: None,
            decoder: FrameDecoder::new(),
            host_tx: TxBuf::new(),
            tx_seq: 0,
            session: Session::None,
            watchdog_period: Duration::ZERO,
            last_host_rx: now,
            watchdog_tripped: false,
            estop: false,
            telemetry_period: Duration::ZERO,
            next_telemetry: Instant::MAX,
            loop_period: profile.loop_period.max(MIN_LOOP_PERIOD),
            next_tick: now,
            tick_started: now,
            loop_stats: LoopStats::default(),
            overrun_since_telemetry: false,
            host_tx_dropped: 0,
            clamp_reported: 0,
            unsafe_reported: 0,
            lost_servos: 0,
            profile,
        };
        fw.rebuild_joints(now);
        fw
    }

    /// Build the joint controls (every joint in position mode, holding) and the gripper from
    /// the joint table, and configure the servos anew.
    pub(crate) fn rebuild_joints(&mut self, now: Instant) {
        self.joints.clear();
        self.gripper = None;
        for (j, c) in self.profile.joints.iter().enumerate() {
            let mut jc = JointControl::new();
            // Every joint starts in position mode holding where it is found; the gripper
            // too, until it is told to open or close.
            jc.set_mode(now, JointMode::Position);
            let _ = self.joints.push(jc);
            if let (JointKind::Gripper, None, Some(g)) =
                (c.kind, &self.gripper, self.profile.gripper)
            {
                self.gripper = Some((j, Gripper::new(g)));
            }
        }
        self.bus.rebuild(&self.profile.joints);
        self.apply_modes();
    }

    /// The profile in use (joint table as currently configured).
    pub fn profile(&self) -> &RobotProfile {
        &self.profile
    }

    /// The servo bus (for inspection).
    pub fn bus(&self) -> &ServoBus {
        &self.bus
    }

    /// The base driver (for inspection).
    pub fn base(&self) -> &BaseDriver {
        &self.base
    }

    /// Joint control states (for inspection).
    pub fn joints(&self) -> &[JointControl] {
        &self.joints
    }

    /// Whether the emergency stop is engaged.
    pub fn estopped(&self) -> bool {
        self.estop
    }

    /// Bytes waiting to go out on `link`.
    pub fn pending(&self, link: Link) -> &[u8] {
        match link {
            Link::Host => self.host_tx.pending(),
            Link::Servo => self.bus.pending_tx(),
            Link::Base => self.base.pending_tx(),
        }
    }

    /// The shell sent the first `n` pending bytes of `link`.
    pub fn consume(&mut self, link: Link, n: usize) {
        match link {
            Link::Host => self.host_tx.consume(n),
            Link::Servo => self.bus.consume_tx(n),
            Link::Base => self.base.consume_tx(n),
        }
    }

    /// The latest time by which [`Firmware::poll`] must run.
    pub fn next_deadline(&self) -> Instant {
        let mut d = if self.bus.read_done() {
            Instant::ZERO
        } else if self.bus.is_idle() {
            self.next_tick
        } else {
            self.bus.deadline().unwrap_or(self.next_tick)
        };
        d = d.min(self.base.deadline()).min(self.next_telemetry);
        if let Some(w) = self.watchdog_deadline() {
            d = d.min(w);
        }
        d
    }

    /// Bytes from the host.
    pub fn on_host_bytes(&mut self, now: Instant, bytes: &[u8]) {
        for &b in bytes {
            if let Some(Ok(frame)) = self.decoder.push::<HostMsg>(b) {
                self.last_host_rx = now;
                // A Hello's answer says whether the watchdog had tripped; the frame ends it.
                self.handle(now, frame.seq, frame.msg);
                self.watchdog_tripped = false;
            }
        }
        // A mode change starts at once when the bus is free.
        self.bus.kick(now);
    }

    /// Bytes from the servo bus.
    pub fn on_servo_bytes(&mut self, now: Instant, bytes: &[u8]) {
        self.bus.on_bytes(now, bytes);
        self.drain_bus_events(now);
        if self.bus.read_done() {
            self.finish_tick(now);
        }
    }

    /// Bytes from the base.
    pub fn on_base_bytes(&mut self, now: Instant, bytes: &[u8]) {
        self.base.on_bytes(now, bytes);
        self.drain_base_events(now);
    }

    /// Advance timers to `now`: servo-loop ticks, bus timeouts, base, watchdog, telemetry.
    pub fn poll(&mut self, now: Instant) {
        if let Some(w) = self.watchdog_deadline() {
            if now >= w {
                self.trip_watchdog(now);
            }
        }
        self.base.poll(now);
        self.drain_base_events(now);
        self.bus.poll(now);
        self.drain_bus_events(now);
        if self.bus.read_done() {
            self.finish_tick(now);
        }
        if self.bus.is_idle() && now >= self.next_tick {
            let period = self.loop_period;
            let late = now - self.next_tick;
            // The period is at least 1 µs (`SetLoopPeriod` refuses less); 0 would tick now.
            let periods_late = late.checked_div_duration(period).unwrap_or(0);
            if late >= period {
                let skipped = periods_late as u32;
                self.loop_stats.overruns = self.loop_stats.overruns.saturating_add(skipped);
                self.overrun_since_telemetry = true;
            }
            self.next_tick += period.saturating_mul(periods_late.saturating_add(1));
            self.bus.set_next_tick(self.next_tick);
            self.tick_started = now;
            self.bus.begin_tick(now, &self.profile.joints);
            self.drain_bus_events(now);
            if self.bus.read_done() {
                self.finish_tick(now);
            }
        }
        if now >= self.next_telemetry {
            self.send_telemetry(now);
            let p = self.telemetry_period;
            self.next_telemetry = if p.is_zero() {
                Instant::MAX
            } else {
                self.next_telemetry.max(now - p) + p
            };
            if self.next_telemetry <= now {
                self.next_telemetry = now + p;
            }
        }
    }
}
