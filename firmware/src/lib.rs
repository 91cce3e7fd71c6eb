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
pub mod config;
pub mod gripper;
pub mod joint;
mod log;
pub mod shell;
pub mod time;
pub mod txbuf;

use log::{log_info, log_warn};

use ferrobot_protocol::dxl::units;
use ferrobot_protocol::ranges;
use ferrobot_protocol::{
    encode_frame, fault_flags, DeviceInfo, DeviceMsg, Diagnostics, Fault, FaultKind, FrameDecoder,
    GripperState, HostMsg, JointKind, JointMode, JointState, LoopStats, Name, RejectReason,
    Telemetry, MAX_JOINTS, MAX_WIRE, PROTOCOL_VERSION, SCHEMA_HASH,
};
use heapless::Vec;

use base::{BaseDriver, BaseEvent};
use bus::{BusEvent, Goal, ServoBus, ServoStatus};
pub use config::RobotProfile;
use gripper::{Gripper, GripperDrive};
use joint::{JointControl, JointOutput};
use time::{Duration, Instant};
use txbuf::TxBuf;

/// Firmware version, major/minor/patch.
pub const FIRMWARE_VERSION: [u8; 3] = [0, 1, 0];

/// Whether a joint output may reach the servos: finite, within the joint's speed limit, an
/// effort the servos can give (`strength`, N·m), and its position limits (or between them and
/// the `anchor` of a joint outside them, and up to the braking offset beyond it while it is
/// `braking`).
fn goal_is_safe(
    out: &JointOutput,
    lim: &ferrobot_protocol::JointLimits,
    (anchor, braking): (Option<f32>, bool),
    strength: f32,
    (state, reach): ((f32, f32), f32),
    ff: f32,
) -> bool {
    match *out {
        JointOutput::None => true,
        JointOutput::Position(g) => {
            let (lo, hi) = joint::position_goal_window(lim, anchor, braking, state, reach);
            // The gravity model's goal offset (within the servo's full-PWM reach at rest) may
            // carry the goal beyond that.
            let (lo, hi) = (lo + ff.min(0.0), hi + ff.max(0.0));
            g.is_finite() && (lo..=hi).contains(&g)
        }
        JointOutput::Velocity(v) => v.is_finite() && v.abs() <= lim.velocity,
        // Within what the servos can give (the guard may exceed the effort limit to keep the
        // joint within its position and speed limits).
        JointOutput::Effort(tau, qd) | JointOutput::PwmEffort(tau, qd) => {
            tau.is_finite() && qd.is_finite() && tau.abs() <= strength
        }
    }
}

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

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Session {
    None,
    Accepted,
    Refused,
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
    /// The sign and offset of each gravity-model joint's row at start: the rows the model was
    /// built for (a row the host configures differently measures other angles).
    gravity_rows: [Option<(i8, f32)>; config::GRAVITY_LINKS],
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
        let mut gravity_rows = [None; config::GRAVITY_LINKS];
        if let Some(m) = profile.gravity {
            for (r, &j) in gravity_rows.iter_mut().zip(&m.joints) {
                *r = profile.joints.get(j as usize).map(|c| (c.sign, c.offset));
            }
        }
        let mut fw = Self {
            envelope,
            gravity_rows,
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

    fn rebuild_joints(&mut self, now: Instant) {
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

    /// The watchdog, once armed by an accepted Hello, runs in every session state: a refused
    /// or silent host is a reason to stop, never a way around it.
    fn watchdog_deadline(&self) -> Option<Instant> {
        (!self.watchdog_period.is_zero() && !self.watchdog_tripped)
            .then(|| self.last_host_rx + self.watchdog_period)
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

    /// Engage the emergency stop: the base stops at once, every joint holds where it is, and
    /// motion is refused until `Resume`.
    fn emergency_stop(&mut self, now: Instant) {
        self.estop = true;
        self.base.stop(now);
        self.base.poll(now);
        self.hold_all(now);
        let gripper = self.gripper.as_ref().map(|(j, _)| *j);
        for (k, j) in self.joints.iter_mut().enumerate() {
            // A joint in a torque mode is held by its servo's own stiff position loop: a
            // torque that only limits its speed would let a load (gravity) carry it on. So is
            // one in velocity mode: the servo's velocity loop brakes softly, and its hold
            // point would let the joint run on past where the stop found it.
            if matches!(
                j.mode,
                JointMode::Current | JointMode::Pwm | JointMode::Velocity
            ) && gripper != Some(k)
            {
                j.set_mode(now, JointMode::Position);
            }
            j.stopped = true;
        }
        self.apply_modes();
        self.fault(now, FaultKind::EmergencyStop, None, None, 0);
    }

    fn trip_watchdog(&mut self, now: Instant) {
        self.watchdog_tripped = true;
        self.base.stop(now);
        self.base.poll(now);
        self.hold_all(now);
        self.fault(now, FaultKind::Watchdog, None, None, 0);
    }

    fn hold_all(&mut self, now: Instant) {
        for j in self.joints.iter_mut() {
            j.hold_here(now);
        }
        if let Some((_, g)) = self.gripper.as_mut() {
            g.halt();
        }
    }

    fn drain_bus_events(&mut self, now: Instant) {
        while let Some(e) = self.bus.pop_event() {
            let (i, kind, code) = match e {
                BusEvent::Lost(i) => (i, FaultKind::ServoLost, 0),
                BusEvent::Recovered(i) => (i, FaultKind::ServoRecovered, 0),
                BusEvent::HardwareError(i, bits) => (i, FaultKind::ServoHardware, bits as u16),
                BusEvent::ConfigFailed(i) => (i, FaultKind::ServoConfig, 0),
            };
            let (joint, id) = self
                .bus
                .servos
                .get(i as usize)
                .map(|s| (Some(s.joint), Some(s.id)))
                .unwrap_or((None, None));
            if let Some(j) = joint.and_then(|j| self.joints.get_mut(j as usize)) {
                j.hold_here(now);
            }
            self.fault(now, kind, joint, id, code);
        }
        self.lost_servos = self
            .bus
            .servos
            .iter()
            .enumerate()
            .filter(|(_, s)| s.status == ServoStatus::Lost)
            .fold(0u16, |m, (i, _)| m | (1u16 << (i as u32 % 16)));
    }

    fn drain_base_events(&mut self, now: Instant) {
        use ferrobot_protocol::base_flags as bf;
        while let Some(e) = self.base.pop_event() {
            match e {
                BaseEvent::Safety(bits) => {
                    let groups = [
                        (bits & bf::ANY_BUMPER, FaultKind::Bumper),
                        (bits & bf::ANY_CLIFF, FaultKind::Cliff),
                        (bits & bf::ANY_WHEEL_DROP, FaultKind::WheelDrop),
                    ];
                    for (b, kind) in groups {
                        if b != 0 {
                            self.fault(now, kind, None, None, b);
                        }
                    }
                }
                BaseEvent::Lost => self.fault(now, FaultKind::BaseLost, None, None, 0),
                BaseEvent::Recovered => self.fault(now, FaultKind::BaseRecovered, None, None, 0),
            }
        }
    }

    fn fault(
        &mut self,
        now: Instant,
        kind: FaultKind,
        joint: Option<u8>,
        servo_id: Option<u8>,
        code: u16,
    ) {
        log_warn!(
            "fault {=istr}: joint {=u8}, servo {=u8}, code {=u16}",
            log::fault_name(kind),
            joint.unwrap_or(u8::MAX),
            servo_id.unwrap_or(u8::MAX),
            code
        );
        if self.session == Session::Accepted {
            self.send(&DeviceMsg::Fault(Fault {
                kind,
                joint,
                servo_id,
                code,
                time_us: now.as_micros(),
            }));
        }
    }

    fn send(&mut self, msg: &DeviceMsg) {
        let mut buf = [0u8; MAX_WIRE];
        match encode_frame(self.tx_seq, msg, &mut buf) {
            Ok(n) => {
                if self.host_tx.push(buf.get(..n).unwrap_or(&[])) {
                    self.tx_seq = self.tx_seq.wrapping_add(1);
                } else {
                    self.host_tx_dropped = self.host_tx_dropped.saturating_add(1);
                }
            }
            Err(_) => self.host_tx_dropped = self.host_tx_dropped.saturating_add(1),
        }
    }

    /// Measure, control, write goals.
    fn finish_tick(&mut self, now: Instant) {
        let dt = self.loop_period.as_secs_f32();
        self.measure(now);
        self.report_outside(now);
        self.model_gravity();
        let mut goals: Vec<Goal, { bus::MAX_SERVOS }> = Vec::new();
        for _ in 0..self.bus.servos.len() {
            let _ = goals.push(Goal::None);
        }
        for j in 0..self.joints.len() {
            self.control_joint(now, dt, j, &mut goals);
        }
        self.apply_modes();
        self.bus.finish_tick(now, &goals);
        let took = now - self.tick_started;
        let s = &mut self.loop_stats;
        s.ticks = s.ticks.wrapping_add(1);
        s.worst_tick_us = s
            .worst_tick_us
            .max(u32::try_from(took.as_micros()).unwrap_or(u32::MAX));
        if took > self.loop_period {
            s.overruns = s.overruns.saturating_add(1);
            self.overrun_since_telemetry = true;
        }
    }

    /// Report each joint under control found more than [`ranges::OUTSIDE_FAULT`] outside its
    /// limits, once until it is back within half that.
    fn report_outside(&mut self, now: Instant) {
        let gripper = self.gripper.as_ref().map(|(j, _)| *j);
        for j in 0..self.joints.len() {
            let (Some(jc), Some(cfg)) = (self.joints.get(j), self.profile.joints.get(j)) else {
                continue;
            };
            let q = jc.state.position;
            let l = cfg.limits;
            let beyond = (l.min - q).max(q - l.max);
            let watched = jc.measured && jc.mode != JointMode::Off && gripper != Some(j);
            let report = watched && !jc.outside_reported && beyond > ranges::OUTSIDE_FAULT;
            let clear = !watched || beyond < 0.5 * ranges::OUTSIDE_FAULT;
            if let Some(jc) = self.joints.get_mut(j) {
                if report {
                    jc.outside_reported = true;
                } else if clear {
                    jc.outside_reported = false;
                }
            }
            if report {
                let mrad = (beyond * 1000.0).min(u16::MAX as f32) as u16;
                let id = cfg.servo_id;
                self.fault(now, FaultKind::OutsideLimits, Some(j as u8), Some(id), mrad);
            }
        }
    }

    /// Give every joint its modelled gravity load at the measured pose (or none: no model, a
    /// joint of the model unmeasured, or its row no longer the one the model was built for).
    fn model_gravity(&mut self) {
        for j in self.joints.iter_mut() {
            j.gravity = None;
        }
        let Some(m) = self.profile.gravity else {
            return;
        };
        let mut q = [0.0f32; config::GRAVITY_LINKS];
        for ((qk, &j), row) in q.iter_mut().zip(&m.joints).zip(&self.gravity_rows) {
            let j = j as usize;
            let (Some(jc), Some(cfg)) = (self.joints.get(j), self.profile.joints.get(j)) else {
                return;
            };
            let p = jc.state.position;
            if !jc.measured || !p.is_finite() || Some((cfg.sign, cfg.offset)) != *row {
                return;
            }
            *qk = p;
        }
        let mut tau = [0.0f32; config::GRAVITY_LINKS];
        let n = ferrobot_protocol::gravity::torques(
            &m.links,
            &q,
            ferrobot_protocol::gravity::G,
            &mut tau,
        );
        if n != config::GRAVITY_LINKS || tau.iter().any(|t| !t.is_finite()) {
            return;
        }
        for (&j, &t) in m.joints.iter().zip(&tau) {
            if let Some(jc) = self.joints.get_mut(j as usize) {
                jc.gravity = Some(t);
            }
        }
    }

    fn measure(&mut self, now: Instant) {
        let mut states: [Option<JointState>; MAX_JOINTS] = [None; MAX_JOINTS];
        for s in self.bus.servos.iter() {
            if !(s.fresh || (s.position_valid && !s.twin)) {
                continue;
            }
            let Some(cfg) = self.profile.joints.get(s.joint as usize) else {
                continue;
            };
            let Some(slot) = states.get_mut(s.joint as usize) else {
                continue;
            };
            let sign = cfg.sign as f32;
            let effort = cfg.model.spec().effort_from_register(s.present.current);
            if s.twin {
                if let Some(st) = slot.as_mut() {
                    st.effort += -sign * effort;
                }
            } else {
                let angle = units::tick_to_rad(s.present.position);
                *slot = Some(JointState {
                    position: sign * (angle - cfg.offset),
                    velocity: sign * s.present.velocity as f32 * units::RAD_S_PER_VELOCITY_UNIT,
                    effort: if s.fresh { sign * effort } else { 0.0 },
                });
                if !s.fresh {
                    // Position read during configuration only.
                    if let Some(st) = slot.as_mut() {
                        st.velocity = 0.0;
                    }
                }
            }
        }
        for (j, st) in states.iter().enumerate() {
            let (Some(st), Some(jc)) = (st, self.joints.get_mut(j)) else {
                continue;
            };
            let first = !jc.measured;
            jc.state = *st;
            jc.measured = true;
            if first {
                jc.first_measurement(now, st.position);
            }
        }
    }

    fn servo_indices(&self, joint: usize) -> (Option<usize>, Option<usize>) {
        let mut p = None;
        let mut t = None;
        for (i, s) in self.bus.servos.iter().enumerate() {
            if s.joint as usize == joint {
                if s.twin {
                    t = Some(i);
                } else {
                    p = Some(i);
                }
            }
        }
        (p, t)
    }

    fn control_joint(&mut self, now: Instant, dt: f32, j: usize, goals: &mut [Goal]) {
        let Some(cfg) = self.profile.joints.get(j).cloned() else {
            return;
        };
        let (p, t) = self.servo_indices(j);
        let healthy = |i: Option<usize>| {
            i.and_then(|i| self.bus.servos.get(i))
                .is_some_and(|s| s.status == ServoStatus::Ok && s.hw_error == 0)
        };
        if !healthy(p) {
            return;
        }
        let twin_ok = t.is_some() && healthy(t);
        // The gripper state machine drives its servo directly, in servo units.
        if let Some((gj, g)) = self.gripper.as_mut() {
            if *gj == j && g.state != GripperState::Unknown {
                let present = p
                    .and_then(|i| self.bus.servos.get(i))
                    .map(|s| s.present)
                    .unwrap_or_default();
                let drive = g.tick(now, &present);
                if let Some(goal) = p.and_then(|i| goals.get_mut(i)) {
                    *goal = match drive {
                        GripperDrive::Position(tick) => Goal::Position(tick),
                        GripperDrive::Pwm(pwm) => Goal::Pwm(pwm),
                        GripperDrive::Idle => Goal::None,
                    };
                }
                return;
            }
        }
        let Some(jc) = self.joints.get_mut(j) else {
            return;
        };
        // A joint that left its limits in velocity, current or PWM mode is stopped: position
        // mode (the servo's own stiff loop) holds it where it comes to rest.
        if jc.must_stop(&cfg.limits) {
            jc.set_mode(now, JointMode::Position);
            self.fault(now, FaultKind::LimitStop, Some(j as u8), None, 0);
            return;
        }
        let Some(jc) = self.joints.get_mut(j) else {
            return;
        };
        let mut out = jc.tick(now, dt, &cfg);
        let anchor = (jc.anchor(), jc.command().1);
        let state = if jc.measured {
            (jc.state.position, jc.state.velocity)
        } else {
            (f32::NAN, f32::NAN)
        };
        let window = (state, joint::position_reach(&cfg, state.1));
        // The model's offset is trusted only within the servos' full-PWM reach at rest.
        let ff = Some(jc.feed_forward())
            .filter(|f| f.is_finite() && f.abs() <= joint::position_reach(&cfg, 0.0))
            .unwrap_or(0.0);
        let strength =
            cfg.model.spec().stall_torque * if cfg.twin_id.is_some() { 2.0 } else { 1.0 };
        // The last gate before the bus: a goal that is not finite or outside the joint's
        // limits never reaches a servo; the joint holds where it is and the fault is reported.
        if !goal_is_safe(&out, &cfg.limits, anchor, strength, window, ff) {
            jc.hold_here(now);
            out = jc.tick(now, dt, &cfg);
            if !goal_is_safe(&out, &cfg.limits, anchor, strength, window, ff) {
                out = JointOutput::None;
            }
            let bit = 1u16 << (j as u32 % 16);
            if self.unsafe_reported & bit == 0 {
                self.unsafe_reported |= bit;
                self.fault(now, FaultKind::UnsafeGoal, Some(j as u8), None, 0);
            }
            return self.write_goals(p, t, twin_ok, out, &cfg, goals);
        }
        self.unsafe_reported &= !(1u16 << (j as u32 % 16));
        let clamped = jc.clamped;
        self.write_goals(p, t, twin_ok, out, &cfg, goals);
        let bit = 1u16 << (j as u32 % 16);
        if clamped && self.clamp_reported & bit == 0 {
            self.clamp_reported |= bit;
            self.fault(now, FaultKind::LimitClamped, Some(j as u8), None, 0);
        } else if !clamped {
            self.clamp_reported &= !bit;
        }
    }

    /// Turn a joint's output into the goals of its servo and twin.
    fn write_goals(
        &self,
        p: Option<usize>,
        t: Option<usize>,
        twin_ok: bool,
        out: JointOutput,
        cfg: &ferrobot_protocol::JointConfig,
        goals: &mut [Goal],
    ) {
        let sign = cfg.sign as f32;
        let spec = cfg.model.spec();
        let n = if twin_ok { 2.0 } else { 1.0 };
        let (gp, gt) = match out {
            JointOutput::None => (Goal::None, Goal::None),
            JointOutput::Position(q) => {
                let a = sign * q + cfg.offset;
                (
                    Goal::Position(units::rad_to_tick(a)),
                    Goal::Position(units::rad_to_tick(-a)),
                )
            }
            JointOutput::Velocity(v) => {
                let raw = sign * v / units::RAD_S_PER_VELOCITY_UNIT;
                let raw = if raw >= 0.0 { raw + 0.5 } else { raw - 0.5 } as i32;
                (Goal::Velocity(raw), Goal::Velocity(raw.saturating_neg()))
            }
            JointOutput::Effort(tau, qd) | JointOutput::PwmEffort(tau, qd) => {
                // Twins share the effort.
                let ts = sign * tau / n;
                let ws = sign * qd;
                if spec.current_control && matches!(out, JointOutput::Effort(..)) {
                    (
                        Goal::Current(spec.register_from_effort(ts)),
                        Goal::Current(spec.register_from_effort(-ts)),
                    )
                } else {
                    (
                        Goal::Pwm(spec.pwm_for_effort(ts, ws)),
                        Goal::Pwm(spec.pwm_for_effort(-ts, -ws)),
                    )
                }
            }
        };
        if let Some(g) = p.and_then(|i| goals.get_mut(i)) {
            *g = gp;
        }
        if twin_ok {
            if let Some(g) = t.and_then(|i| goals.get_mut(i)) {
                *g = gt;
            }
        }
    }

    /// Push each servo's desired operating mode and torque to the bus.
    fn apply_modes(&mut self) {
        for i in 0..self.bus.servos.len() {
            let Some(s) = self.bus.servos.get(i) else {
                continue;
            };
            let j = s.joint as usize;
            let model = s.model;
            let Some(jc) = self.joints.get(j) else {
                continue;
            };
            // A servo whose range exceeds one turn around its centre needs extended position mode.
            let multi_turn = self.profile.joints.get(j).is_some_and(|c| {
                let s = c.sign as f32;
                let (a, b) = (s * c.limits.min + c.offset, s * c.limits.max + c.offset);
                a.min(b) < -core::f32::consts::PI || a.max(b) > core::f32::consts::PI
            });
            let mut m = bus::mode_byte(jc.mode, model, multi_turn);
            let mut torque = jc.mode != JointMode::Off;
            if let Some((gj, g)) = self.gripper.as_ref() {
                if *gj == j {
                    match g.state {
                        GripperState::Closing | GripperState::Holding | GripperState::Closed => {
                            m = ferrobot_protocol::dxl::mode::PWM;
                            torque = true;
                        }
                        GripperState::Open | GripperState::Opening => {
                            m = ferrobot_protocol::dxl::mode::POSITION;
                            torque = true;
                        }
                        _ => {}
                    }
                }
            }
            self.bus.set_mode(i, m, torque);
        }
    }

    fn faults(&self) -> u16 {
        let mut f = 0;
        if self.estop {
            f |= fault_flags::ESTOP;
        }
        if self.watchdog_tripped {
            f |= fault_flags::WATCHDOG;
        }
        if self.lost_servos != 0 {
            f |= fault_flags::SERVO_LOST;
        }
        if self.bus.servos.iter().any(|s| s.hw_error != 0) {
            f |= fault_flags::SERVO_HARDWARE;
        }
        if self
            .bus
            .servos
            .iter()
            .any(|s| s.status == ServoStatus::Configuring)
        {
            f |= fault_flags::CONFIGURING;
        }
        if self.base.present() && self.base.lost {
            f |= fault_flags::BASE_LOST;
        }
        if self.base.flags != 0 {
            f |= fault_flags::BASE_SAFETY;
        }
        if self.overrun_since_telemetry {
            f |= fault_flags::OVERRUN;
        }
        f
    }

    /// The telemetry frame as of now.
    pub fn telemetry(&self, now: Instant) -> Telemetry {
        Telemetry {
            time_us: now.as_micros(),
            joints: self.joints.iter().map(|j| j.state).collect(),
            queued: self
                .joints
                .iter()
                .map(|j| j.queued())
                .sum::<usize>()
                .min(255) as u8,
            gripper: self
                .gripper
                .as_ref()
                .map(|(_, g)| g.state)
                .unwrap_or(GripperState::Absent),
            odometry: self.base.odom.pose,
            wheels: self.base.wheels,
            base_flags: self.base.flags,
            faults: self.faults(),
            loop_stats: self.loop_stats,
        }
    }

    fn send_telemetry(&mut self, now: Instant) {
        let t = self.telemetry(now);
        self.overrun_since_telemetry = false;
        self.send(&DeviceMsg::Telemetry(t));
    }

    /// Link and bus counters.
    pub fn diagnostics(&self) -> Diagnostics {
        let f = self.decoder.stats();
        Diagnostics {
            host_frames: f.ok,
            host_bad_frames: f.dropped(),
            host_tx_dropped: self.host_tx_dropped,
            servo_packets: self.bus.stats.packets,
            servo_bad_packets: self.bus.stats.bad_packets,
            servo_timeouts: self.bus.stats.timeouts,
            servo_alerts: self.bus.stats.alerts,
            servo_stale: self.bus.stats.stale,
            base_packets: self.base.stats.packets,
            base_bad_packets: self.base.stats.bad_packets,
        }
    }

    fn info(&self, accepted: bool) -> DeviceInfo {
        DeviceInfo {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH,
            firmware_version: FIRMWARE_VERSION,
            board: self.board.clone(),
            robot: self.profile.robot.clone(),
            joints: self.profile.joints.iter().map(|j| j.kind).collect(),
            base: self.profile.base.kind,
            loop_period_us: u32::try_from(self.loop_period.as_micros()).unwrap_or(u32::MAX),
            accepted,
            watchdog_tripped: self.watchdog_tripped,
        }
    }

    fn handle(&mut self, now: Instant, seq: u16, msg: HostMsg) {
        match msg {
            // The emergency stop overrides everything, in every session state (ISO 13850).
            HostMsg::EmergencyStop => {
                self.emergency_stop(now);
                self.send(&DeviceMsg::Ack { seq });
                return;
            }
            HostMsg::Hello {
                protocol_version,
                schema_hash,
            } => {
                let ok = protocol_version == PROTOCOL_VERSION && schema_hash == SCHEMA_HASH;
                log_info!(
                    "hello: protocol {=u16}, schema {=u32:x}: accepted {=bool}",
                    protocol_version,
                    schema_hash,
                    ok
                );
                self.session = if ok {
                    Session::Accepted
                } else {
                    Session::Refused
                };
                let info = self.info(ok);
                self.send(&DeviceMsg::Hello(info));
                if ok {
                    self.watchdog_period = self.profile.watchdog_period;
                    self.set_telemetry(now, self.profile.telemetry_period);
                } else {
                    // A refused session is a safe state: the base stops, the joints hold.
                    self.base.stop(now);
                    self.base.poll(now);
                    self.hold_all(now);
                }
                return;
            }
            _ if self.session != Session::Accepted => {
                self.send(&DeviceMsg::Reject {
                    seq,
                    reason: RejectReason::VersionMismatch,
                });
                return;
            }
            HostMsg::GetJoint { index } => {
                let reply = match self.profile.joints.get(index as usize) {
                    Some(c) => DeviceMsg::Joint {
                        index,
                        config: c.clone(),
                    },
                    None => DeviceMsg::Reject {
                        seq,
                        reason: RejectReason::UnknownJoint,
                    },
                };
                self.send(&reply);
                return;
            }
            HostMsg::GetDiagnostics => {
                let d = self.diagnostics();
                self.send(&DeviceMsg::Diagnostics(d));
                return;
            }
            _ => {}
        }
        let reply = match self.command(now, msg) {
            Ok(()) => DeviceMsg::Ack { seq },
            Err(reason) => {
                log_warn!(
                    "rejected command #{=u16}: {=istr}",
                    seq,
                    log::reject_name(reason)
                );
                DeviceMsg::Reject { seq, reason }
            }
        };
        self.send(&reply);
    }

    fn set_telemetry(&mut self, now: Instant, period: Duration) {
        self.telemetry_period = period;
        self.next_telemetry = if period.is_zero() {
            Instant::MAX
        } else {
            now + period
        };
    }

    /// Indices selected by a mask, checked against the joint count.
    fn selected(&self, mask: u16) -> Result<Vec<usize, MAX_JOINTS>, RejectReason> {
        let n = self.joints.len();
        if n < 16 && mask != u16::MAX && mask >> n != 0 {
            return Err(RejectReason::UnknownJoint);
        }
        Ok((0..n).filter(|j| mask & (1 << j) != 0).collect())
    }

    fn command(&mut self, now: Instant, msg: HostMsg) -> Result<(), RejectReason> {
        match msg {
            HostMsg::ConfigureJoint { index, config } => {
                if self.joints.iter().any(|j| j.mode != JointMode::Off) {
                    return Err(RejectReason::Busy);
                }
                if !config::joint_is_valid(&config) {
                    return Err(RejectReason::InvalidConfig);
                }
                let i = index as usize;
                // A servo belongs to one joint only.
                let ids = |c: &ferrobot_protocol::JointConfig| [Some(c.servo_id), c.twin_id];
                let taken = self
                    .profile
                    .joints
                    .iter()
                    .enumerate()
                    .filter(|(k, _)| *k != i)
                    .flat_map(|(_, c)| ids(c))
                    .flatten()
                    .any(|id| ids(&config).contains(&Some(id)));
                if taken {
                    return Err(RejectReason::InvalidConfig);
                }
                match i.cmp(&self.profile.joints.len()) {
                    core::cmp::Ordering::Less => {
                        if let Some(env) = self.envelope.get_mut(i) {
                            *env = config.limits;
                        }
                        if let Some(row) = self.profile.joints.get_mut(i) {
                            *row = config;
                        }
                    }
                    core::cmp::Ordering::Equal => {
                        self.envelope
                            .push(config.limits)
                            .map_err(|_| RejectReason::UnknownJoint)?;
                        self.profile
                            .joints
                            .push(config)
                            .map_err(|_| RejectReason::UnknownJoint)?;
                    }
                    core::cmp::Ordering::Greater => return Err(RejectReason::UnknownJoint),
                }
                self.rebuild_joints(now);
                for j in self.joints.iter_mut() {
                    j.set_mode(now, JointMode::Off);
                }
                self.apply_modes();
                Ok(())
            }
            HostMsg::SetPid { joint, gains } => {
                let row = self
                    .profile
                    .joints
                    .get_mut(joint as usize)
                    .ok_or(RejectReason::UnknownJoint)?;
                if ranges::gains_beyond_servo(&gains, row).is_some() {
                    return Err(RejectReason::InvalidConfig);
                }
                row.pid = gains;
                Ok(())
            }
            HostMsg::SetLimits { joint, limits } => {
                let row = self
                    .profile
                    .joints
                    .get(joint as usize)
                    .ok_or(RejectReason::UnknownJoint)?;
                let mut new = row.clone();
                new.limits = limits;
                if !config::joint_is_valid(&new) {
                    return Err(RejectReason::InvalidConfig);
                }
                // Limits narrow within the joint's configured envelope, never widen it.
                let env = self
                    .envelope
                    .get(joint as usize)
                    .ok_or(RejectReason::UnknownJoint)?;
                if limits.min < env.min
                    || limits.max > env.max
                    || limits.velocity > env.velocity
                    || limits.effort > env.effort
                    || limits.effort < ranges::EFFORT_NARROW_MIN_SHARE * env.effort
                {
                    return Err(RejectReason::OutOfLimits);
                }
                // Limits the joint is outside of now cannot hold at once: refused (the host
                // moves it inside first).
                let jc = self
                    .joints
                    .get_mut(joint as usize)
                    .ok_or(RejectReason::UnknownJoint)?;
                let q = jc.state.position;
                if jc.measured && !(limits.min..=limits.max).contains(&q) {
                    return Err(RejectReason::OutOfLimits);
                }
                jc.reset_anchor();
                if let Some(r) = self.profile.joints.get_mut(joint as usize) {
                    *r = new;
                }
                Ok(())
            }
            HostMsg::SetMode { joints, mode } => {
                let sel = self.selected(joints)?;
                if self.estop && mode != JointMode::Off {
                    return Err(RejectReason::EmergencyStop);
                }
                for j in sel {
                    if let Some(jc) = self.joints.get_mut(j) {
                        jc.set_mode(now, mode);
                    }
                    if let (Some((gj, g)), Some(cfg)) =
                        (self.gripper.as_mut(), self.profile.gripper)
                    {
                        if *gj == j {
                            *g = Gripper::new(cfg);
                        }
                    }
                }
                self.apply_modes();
                Ok(())
            }
            HostMsg::Waypoint {
                joints,
                duration_us,
                points,
            } => {
                if self.estop {
                    return Err(RejectReason::EmergencyStop);
                }
                let sel = self.selected(joints)?;
                if sel.len() != points.len() {
                    return Err(RejectReason::CountMismatch);
                }
                for (&j, p) in sel.iter().zip(points.iter()) {
                    let cfg = self
                        .profile
                        .joints
                        .get(j)
                        .ok_or(RejectReason::UnknownJoint)?;
                    if let Some(e) = ranges::point_error(p, &cfg.limits) {
                        return Err(e);
                    }
                    let jc = self.joints.get(j).ok_or(RejectReason::UnknownJoint)?;
                    if !matches!(jc.mode, JointMode::Position | JointMode::Current) {
                        return Err(RejectReason::WrongMode);
                    }
                    if jc.queued() >= joint::QUEUE_LEN {
                        return Err(RejectReason::QueueFull);
                    }
                    if self
                        .gripper
                        .as_ref()
                        .is_some_and(|(gj, g)| *gj == j && g.state != GripperState::Unknown)
                    {
                        return Err(RejectReason::WrongMode);
                    }
                }
                for (&j, p) in sel.iter().zip(points.iter()) {
                    if let Some(jc) = self.joints.get_mut(j) {
                        jc.push(now, Duration::from_micros(u64::from(duration_us)), p);
                    }
                }
                Ok(())
            }
            HostMsg::ClearQueue { joints } => {
                for j in self.selected(joints)? {
                    if let Some(jc) = self.joints.get_mut(j) {
                        jc.hold_here(now);
                    }
                }
                Ok(())
            }
            HostMsg::JointCommand { joints, values } => {
                let sel = self.selected(joints)?;
                if sel.len() != values.len() {
                    return Err(RejectReason::CountMismatch);
                }
                if values.iter().any(|v| !v.is_finite()) {
                    return Err(RejectReason::NotFinite);
                }
                if self.estop && values.iter().any(|v| *v != 0.0) {
                    return Err(RejectReason::EmergencyStop);
                }
                for (&j, v) in sel.iter().zip(values.iter()) {
                    let jc = self.joints.get(j).ok_or(RejectReason::UnknownJoint)?;
                    let bound = match jc.mode {
                        JointMode::Velocity => ranges::JOINT_SPEED_MAX,
                        JointMode::Current => ranges::JOINT_EFFORT_MAX,
                        JointMode::Pwm => 1.0,
                        _ => return Err(RejectReason::WrongMode),
                    };
                    if v.abs() > bound {
                        return Err(RejectReason::OutOfLimits);
                    }
                }
                for (&j, &v) in sel.iter().zip(values.iter()) {
                    if let Some(jc) = self.joints.get_mut(j) {
                        jc.set_direct(v);
                    }
                }
                Ok(())
            }
            HostMsg::BaseVelocity { v, w, duration_ms } => {
                if !(v.is_finite() && w.is_finite()) {
                    return Err(RejectReason::NotFinite);
                }
                if v.abs() > ranges::BASE_SPEED_MAX || w.abs() > ranges::BASE_TURN_MAX {
                    return Err(RejectReason::OutOfLimits);
                }
                if self.estop && (v != 0.0 || w != 0.0) {
                    return Err(RejectReason::EmergencyStop);
                }
                self.base
                    .set_velocity(now, v, w, Duration::from_millis(u64::from(duration_ms)))?;
                self.base.poll(now);
                Ok(())
            }
            HostMsg::SetBaseGeometry {
                left_radius,
                right_radius,
                track,
            } => self.base.set_geometry(left_radius, right_radius, track),
            HostMsg::ResetOdometry => {
                if !self.base.present() {
                    return Err(RejectReason::NoBase);
                }
                self.base.odom.reset();
                Ok(())
            }
            HostMsg::Gripper(cmd) => {
                if self.estop {
                    return Err(RejectReason::EmergencyStop);
                }
                let (gj, g) = self.gripper.as_mut().ok_or(RejectReason::NoGripper)?;
                g.command(now, cmd);
                let j = *gj;
                if let Some(jc) = self.joints.get_mut(j) {
                    if jc.mode == JointMode::Off {
                        jc.set_mode(now, JointMode::Position);
                    }
                }
                self.apply_modes();
                Ok(())
            }
            HostMsg::SetWatchdog { period_ms } => {
                if !(1..=ranges::WATCHDOG_MAX_MS).contains(&period_ms) {
                    return Err(RejectReason::InvalidConfig);
                }
                self.watchdog_period = Duration::from_millis(u64::from(period_ms));
                Ok(())
            }
            HostMsg::Heartbeat => Ok(()),
            HostMsg::EmergencyStop => {
                self.emergency_stop(now);
                Ok(())
            }
            HostMsg::Resume => {
                self.estop = false;
                for j in self.joints.iter_mut() {
                    j.stopped = false;
                }
                Ok(())
            }
            HostMsg::SetTelemetry { period_ms } => {
                self.set_telemetry(now, Duration::from_millis(u64::from(period_ms)));
                Ok(())
            }
            HostMsg::SetLoopPeriod { period_us } => {
                if !(ranges::LOOP_PERIOD_MIN_US..=ranges::LOOP_PERIOD_MAX_US).contains(&period_us) {
                    return Err(RejectReason::InvalidConfig);
                }
                self.loop_period = Duration::from_micros(u64::from(period_us));
                Ok(())
            }
            HostMsg::RebootJoint { joint } => {
                let jc = self
                    .joints
                    .get(joint as usize)
                    .ok_or(RejectReason::UnknownJoint)?;
                let (p, t) = self.servo_indices(joint as usize);
                // A rebooting servo is limp: only a joint that is off, or already limp from a
                // hardware error, may be rebooted.
                let faulty = [p, t]
                    .into_iter()
                    .flatten()
                    .any(|i| self.bus.servos.get(i).is_some_and(|s| s.hw_error != 0));
                if jc.mode != JointMode::Off && !faulty {
                    return Err(RejectReason::Busy);
                }
                for i in [p, t].into_iter().flatten() {
                    self.bus.reboot(i);
                }
                // The reboot leaves the servo limp and then configures it anew: the joint
                // starts again from where it is, as after a mode switch (no load correction,
                // stall or brake carried over from before the fault).
                if let Some(jc) = self.joints.get_mut(joint as usize) {
                    let mode = jc.mode;
                    jc.set_mode(now, mode);
                }
                Ok(())
            }
            // Answered by `handle` before any command; listed so that the match stays
            // exhaustive and a new message without a handler fails to compile.
            HostMsg::Hello { .. } | HostMsg::GetJoint { .. } | HostMsg::GetDiagnostics => {
                Err(RejectReason::Unsupported)
            }
        }
    }
}
