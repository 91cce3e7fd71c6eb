//! Dynamixel 2.0 servo-bus master, sans-IO.
//!
//! Each servo-loop tick is one bus cycle: at most one configuration transaction (a write or
//! read that the servo answers), then one sync read of present current/load, velocity and
//! position (addresses 126-135, 10 bytes) from every configured servo, then, after the joint
//! controllers ran, one sync write per goal register in use (normally exactly one).
//!
//! Robustness: status packets that fail CRC or framing are counted and dropped; a servo that
//! misses three sync reads in a row is declared lost (a fault is reported, its joint is held,
//! it leaves the sync read so it cannot block the servos after it) and is pinged every 100 ms
//! until it answers, then reconfigured. A status with the alert bit makes the master read the
//! Hardware Error Status and report it. Nothing here stops the loop.

use ferrobot_protocol::dxl::{self, addr, mode, status_error, PacketDecoder};
use ferrobot_protocol::{JointConfig, ServoModel};
use heapless::Vec;

use crate::config::BusConfig;
use crate::time::{Duration, Instant};
use crate::txbuf::TxBuf;
use heapless::Deque;

/// Most servos on one bus.
pub const MAX_SERVOS: usize = 16;
/// Bytes read per servo in the sync read: present current/load (2), velocity (4), position (4).
pub const SYNC_READ_LEN: u16 = 10;
/// Consecutive missed sync reads after which a servo is lost.
pub const MISSES_TO_LOSE: u8 = 3;
/// Failed transactions after which a servo being configured is lost.
pub const OP_RETRIES: u8 = 3;
/// Ping period of a lost servo.
pub const PROBE_PERIOD: Duration = Duration::from_millis(100);
/// Longest Return Delay Time a servo may still have before configuration sets it to 0
/// (254 × 2 µs; the factory default is 250 × 2 µs).
pub const UNCONFIGURED_RETURN_DELAY: Duration = Duration::from_micros(508);

/// Pending-operation bits of a servo, executed lowest first.
pub mod op {
    /// Reboot (clears hardware errors).
    pub const REBOOT: u16 = 1 << 0;
    /// Ping.
    pub const PING: u16 = 1 << 1;
    /// Torque off.
    pub const TORQUE_OFF: u16 = 1 << 2;
    /// Return delay time 0.
    pub const RETURN_DELAY: u16 = 1 << 3;
    /// Operating mode.
    pub const MODE: u16 = 1 << 4;
    /// Position D/I/P gains.
    pub const POS_GAINS: u16 = 1 << 5;
    /// Velocity I/P gains.
    pub const VEL_GAINS: u16 = 1 << 6;
    /// Profile acceleration and velocity.
    pub const PROFILE: u16 = 1 << 7;
    /// Read present position.
    pub const READ_POS: u16 = 1 << 8;
    /// Write the mode's neutral goal (present position, or zero).
    pub const GOAL_HOLD: u16 = 1 << 9;
    /// Torque on (skipped when the desired torque is off).
    pub const TORQUE_ON: u16 = 1 << 10;
    /// Read Hardware Error Status.
    pub const READ_HW: u16 = 1 << 11;
    /// Full configuration.
    pub const CONFIGURE: u16 = PING
        | TORQUE_OFF
        | RETURN_DELAY
        | MODE
        | POS_GAINS
        | VEL_GAINS
        | PROFILE
        | READ_POS
        | GOAL_HOLD
        | TORQUE_ON;
    /// Mode change.
    pub const MODE_CHANGE: u16 = TORQUE_OFF | MODE | READ_POS | GOAL_HOLD | TORQUE_ON;
    /// Operations during which no goal may be written.
    pub const BLOCKS_GOALS: u16 = CONFIGURE | REBOOT;

    /// Parameters in the status that answers operation `o` (a ping's model and firmware
    /// version, a position read's 4 bytes, a hardware-error read's 1; writes and reboots
    /// answer with none).
    pub const fn reply_params(o: u16) -> usize {
        match o {
            PING => 3,
            READ_POS => 4,
            READ_HW => 1,
            _ => 0,
        }
    }
}

/// Bytes of a status packet besides its parameters.
const STATUS_OVERHEAD: usize = dxl::PACKET_OVERHEAD + 2;

/// Where a servo stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServoStatus {
    /// Being configured.
    Configuring,
    /// In the loop.
    Ok,
    /// Not answering; probed periodically.
    Lost,
}

/// Raw present values of a servo.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Present {
    /// Present current (XM, 2.69 mA) or load (XL, 0.1 %).
    pub current: i16,
    /// Present velocity, 0.229 rpm.
    pub velocity: i32,
    /// Present position, ticks.
    pub position: i32,
}

/// One servo on the bus.
#[derive(Debug, Clone)]
pub struct Servo {
    /// Dynamixel ID.
    pub id: u8,
    /// Index of its joint.
    pub joint: u8,
    /// Whether it is the mirrored twin of its joint.
    pub twin: bool,
    /// Model.
    pub model: ServoModel,
    /// Status.
    pub status: ServoStatus,
    /// Pending [`op`] bits.
    pub ops: u16,
    /// Desired operating mode (address 11 value).
    pub mode: u8,
    /// Desired torque.
    pub torque: bool,
    /// Last present values.
    pub present: Present,
    /// Whether `present` was updated by the last sync read.
    pub fresh: bool,
    /// Whether `present.position` has ever been read.
    pub position_valid: bool,
    /// Last Hardware Error Status read, 0 when none.
    pub hw_error: u8,
    retries: u8,
    misses: u8,
    next_probe: Instant,
    /// Bumped whenever the desired mode or torque changes: a mode-change transaction that
    /// was under way when the request changed does not count as done.
    gen: u8,
}

/// A goal for one servo, in servo units.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Goal {
    /// No goal this tick.
    None,
    /// Goal position, ticks.
    Position(i32),
    /// Goal velocity, 0.229 rpm.
    Velocity(i32),
    /// Goal current, 2.69 mA.
    Current(i16),
    /// Goal PWM, 1/885.
    Pwm(i16),
}

/// Things the firmware must hear about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusEvent {
    /// Servo (index) lost.
    Lost(u8),
    /// Servo (index) answers again.
    Recovered(u8),
    /// Servo (index) reports hardware-error bits.
    HardwareError(u8, u8),
    /// Servo (index) could not be configured.
    ConfigFailed(u8),
}

/// Bus counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Status packets received.
    pub packets: u32,
    /// Packets dropped by the decoder (CRC, length).
    pub bad_packets: u32,
    /// Expected status packets that did not come.
    pub timeouts: u32,
    /// Statuses with the alert bit.
    pub alerts: u32,
    /// Statuses that answered nothing awaited (a late reply to an earlier transaction, or one
    /// out of a sync read's order), dropped.
    pub stale: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Idle,
    AwaitOp {
        servo: usize,
        op: u16,
        deadline: Instant,
        gen: u8,
    },
    AwaitSync {
        deadline: Instant,
    },
    ReadDone,
}

/// The bus master.
pub struct ServoBus {
    /// Servos, in joint-table order (primary, then twin).
    pub servos: Vec<Servo, MAX_SERVOS>,
    cfg: BusConfig,
    decoder: PacketDecoder<96>,
    phase: Phase,
    read_list: Vec<u8, MAX_SERVOS>,
    received: u32,
    /// When the last byte handed to the line has left it (estimated from the bit rate):
    /// a reply cannot start before.
    line_free_at: Instant,
    tx: TxBuf<512>,
    events: Deque<BusEvent, 16>,
    /// Whether the transactions under way belong to a tick (the sync read follows them).
    ops_then_read: bool,
    /// Counters.
    pub stats: BusStats,
}

/// Operating-mode byte that realises a joint mode on a servo model; `multi_turn` joints (servo
/// range beyond ±π) use extended position mode.
pub fn mode_byte(
    joint_mode: ferrobot_protocol::JointMode,
    model: ServoModel,
    multi_turn: bool,
) -> u8 {
    use ferrobot_protocol::JointMode as M;
    match joint_mode {
        M::Position | M::Off if multi_turn => mode::EXTENDED_POSITION,
        M::Position | M::Off => mode::POSITION,
        M::Velocity => mode::VELOCITY,
        M::Current if model.spec().current_control => mode::CURRENT,
        M::Current | M::Pwm => mode::PWM,
        _ => mode::POSITION,
    }
}

impl ServoBus {
    /// A bus for the joint table; every servo starts unconfigured, torque off, position mode.
    pub fn new(joints: &[JointConfig], cfg: BusConfig) -> Self {
        let mut bus = Self {
            servos: Vec::new(),
            cfg,
            decoder: PacketDecoder::new(),
            phase: Phase::Idle,
            read_list: Vec::new(),
            received: 0,
            line_free_at: Instant::ZERO,
            tx: TxBuf::new(),
            events: Deque::new(),
            ops_then_read: true,
            stats: BusStats::default(),
        };
        bus.rebuild(joints);
        bus
    }

    /// Rebuild the servo list from a (changed) joint table; all servos are reconfigured.
    pub fn rebuild(&mut self, joints: &[JointConfig]) {
        self.servos.clear();
        for (j, c) in joints.iter().enumerate() {
            let ids = [Some(c.servo_id), c.twin_id];
            for (k, id) in ids.iter().enumerate() {
                if let Some(id) = id {
                    let _ = self.servos.push(Servo {
                        id: *id,
                        joint: j as u8,
                        twin: k == 1,
                        model: c.model,
                        status: ServoStatus::Configuring,
                        ops: op::CONFIGURE,
                        mode: mode::POSITION,
                        torque: false,
                        present: Present::default(),
                        fresh: false,
                        position_valid: false,
                        hw_error: 0,
                        retries: 0,
                        misses: 0,
                        next_probe: Instant::ZERO,
                        gen: 0,
                    });
                }
            }
        }
        self.phase = Phase::Idle;
    }

    /// Bytes waiting to go out on the bus.
    pub fn pending_tx(&self) -> &[u8] {
        self.tx.pending()
    }

    /// The shell sent the first `n` pending bytes.
    pub fn consume_tx(&mut self, n: usize) {
        self.tx.consume(n);
    }

    /// Take the next event.
    pub fn pop_event(&mut self) -> Option<BusEvent> {
        self.events.pop_front()
    }

    fn event(&mut self, e: BusEvent) {
        let _ = self.events.push_back(e);
    }

    /// Whether the bus is between ticks.
    pub fn is_idle(&self) -> bool {
        self.phase == Phase::Idle
    }

    /// Whether the sync read of this tick is complete (or timed out) and goals are awaited.
    pub fn read_done(&self) -> bool {
        self.phase == Phase::ReadDone
    }

    /// When the bus next needs `poll`, if it waits for a reply.
    pub fn deadline(&self) -> Option<Instant> {
        match self.phase {
            Phase::AwaitOp { deadline, .. } | Phase::AwaitSync { deadline } => Some(deadline),
            _ => None,
        }
    }

    /// Ask servo `i` to run a mode; torque follows `torque`.
    pub fn set_mode(&mut self, i: usize, mode_byte: u8, torque: bool) {
        if let Some(s) = self.servos.get_mut(i) {
            if s.mode != mode_byte || s.torque != torque {
                s.mode = mode_byte;
                s.torque = torque;
                s.ops |= op::MODE_CHANGE;
                s.gen = s.gen.wrapping_add(1);
            }
        }
    }

    /// Reboot servo `i` and configure it again.
    pub fn reboot(&mut self, i: usize) {
        if let Some(s) = self.servos.get_mut(i) {
            s.ops |= op::REBOOT | op::CONFIGURE;
            s.hw_error = 0;
            s.retries = 0;
            if s.status == ServoStatus::Lost {
                s.status = ServoStatus::Configuring;
            }
        }
    }

    /// Whether goals may be written to servo `i` this tick.
    pub fn accepts_goals(&self, i: usize) -> bool {
        self.servos.get(i).is_some_and(|s| {
            s.status == ServoStatus::Ok
                && s.ops & op::BLOCKS_GOALS == 0
                && s.torque
                && s.hw_error == 0
        })
    }

    /// Hand a packet built by `build` to the line at `now`; the bytes sent (0 if it did not
    /// fit). The line stays busy for their time after whatever was still on it.
    fn send(
        &mut self,
        now: Instant,
        build: impl FnOnce(&mut [u8]) -> Result<usize, dxl::DxlError>,
    ) -> usize {
        let mut buf = [0u8; 160];
        let n = match build(&mut buf) {
            Ok(n) if self.tx.push(buf.get(..n).unwrap_or(&[])) => n,
            _ => 0,
        };
        self.line_free_at = now.max(self.line_free_at) + self.cfg.bytes_time(n);
        n
    }

    /// When `reply_bytes` of answer must have arrived: after everything sent so far has left
    /// the line (bytes still queued from earlier packets included), the answer's own time,
    /// and the margin.
    fn reply_deadline(&self, reply_bytes: usize) -> Instant {
        self.line_free_at + self.cfg.bytes_time(reply_bytes) + self.cfg.reply_margin
    }

    /// Deadline of operation `o`'s status: the servo may still answer after its factory
    /// return delay.
    fn op_deadline(&self, o: u16) -> Instant {
        self.reply_deadline(STATUS_OVERHEAD.saturating_add(op::reply_params(o)))
            + UNCONFIGURED_RETURN_DELAY
    }

    /// Start a bus cycle at `now`: one configuration transaction if any is pending, then the
    /// sync read.
    pub fn begin_tick(&mut self, now: Instant, joints: &[JointConfig]) {
        // A packet still half-received belongs to the last cycle: it is broken.
        if self.decoder.in_packet() {
            self.stats.bad_packets = self.stats.bad_packets.saturating_add(1);
        }
        self.decoder.reset();
        for s in self.servos.iter_mut() {
            s.fresh = false;
        }
        self.ops_then_read = true;
        if !self.start_op(now, joints) {
            self.start_sync_read(now);
        }
    }

    fn start_op(&mut self, now: Instant, joints: &[JointConfig]) -> bool {
        // Probe one lost servo whose time has come.
        let probe = self
            .servos
            .iter()
            .position(|s| s.status == ServoStatus::Lost && s.next_probe <= now);
        if let Some(i) = probe {
            let id = self.servos.get(i).map(|s| s.id).unwrap_or(0);
            self.send(now, |b| dxl::ping(b, id));
            self.phase = Phase::AwaitOp {
                servo: i,
                op: op::PING,
                deadline: self.op_deadline(op::PING),
                gen: self.servos.get(i).map_or(0, |s| s.gen),
            };
            return true;
        }
        loop {
            let pending = self
                .servos
                .iter()
                .position(|s| s.status != ServoStatus::Lost && s.ops != 0);
            let Some(i) = pending else {
                return false;
            };
            if self.issue_op(now, i, joints) {
                return true;
            }
        }
    }

    /// After a mode-change transaction, the next one of any servo changing mode, in the same
    /// tick: a servo is never left limp, or running a goal of its old mode, for longer than
    /// the transactions take. Returns whether one was started.
    fn chain_mode_ops(&mut self, now: Instant) -> bool {
        loop {
            let changing = self.servos.iter().position(|s| {
                s.status == ServoStatus::Ok && s.ops != 0 && s.ops & !op::MODE_CHANGE == 0
            });
            let Some(i) = changing else {
                return false;
            };
            // Mode-change transactions do not use the joint table.
            if self.issue_op(now, i, &[]) {
                return true;
            }
        }
    }

    /// Send servo `i`'s lowest pending operation; false when it needed no transaction (it is
    /// then done).
    fn issue_op(&mut self, now: Instant, i: usize, joints: &[JointConfig]) -> bool {
        let Some(s) = self.servos.get(i).cloned() else {
            return false;
        };
        let o = s.ops & s.ops.wrapping_neg(); // lowest pending op
        let cfg = joints.get(s.joint as usize);
        let id = s.id;
        match o {
            op::REBOOT => self.send(now, |b| dxl::reboot(b, id)),
            op::PING => self.send(now, |b| dxl::ping(b, id)),
            op::TORQUE_OFF => self.send(now, |b| dxl::write(b, id, addr::TORQUE_ENABLE, &[0])),
            op::RETURN_DELAY => {
                self.send(now, |b| dxl::write(b, id, addr::RETURN_DELAY_TIME, &[0]))
            }
            op::MODE => self.send(now, |b| dxl::write(b, id, addr::OPERATING_MODE, &[s.mode])),
            op::POS_GAINS => {
                let g = cfg.map(|c| c.servo).unwrap_or(s.model.factory_gains());
                let mut d = [0u8; 6];
                d[..2].copy_from_slice(&g.pos_d.to_le_bytes());
                d[2..4].copy_from_slice(&g.pos_i.to_le_bytes());
                d[4..].copy_from_slice(&g.pos_p.to_le_bytes());
                self.send(now, |b| dxl::write(b, id, addr::POSITION_D_GAIN, &d))
            }
            op::VEL_GAINS => {
                let g = cfg.map(|c| c.servo).unwrap_or(s.model.factory_gains());
                let mut d = [0u8; 4];
                d[..2].copy_from_slice(&g.vel_i.to_le_bytes());
                d[2..].copy_from_slice(&g.vel_p.to_le_bytes());
                self.send(now, |b| dxl::write(b, id, addr::VELOCITY_I_GAIN, &d))
            }
            op::PROFILE => {
                let g = cfg.map(|c| c.servo).unwrap_or(s.model.factory_gains());
                let mut d = [0u8; 8];
                d[..4].copy_from_slice(&g.profile_acceleration.to_le_bytes());
                d[4..].copy_from_slice(&g.profile_velocity.to_le_bytes());
                self.send(now, |b| dxl::write(b, id, addr::PROFILE_ACCELERATION, &d))
            }
            op::READ_POS => self.send(now, |b| dxl::read(b, id, addr::PRESENT_POSITION, 4)),
            op::GOAL_HOLD => {
                let (a, data, len): (u16, [u8; 4], usize) = match s.mode {
                    mode::POSITION | mode::EXTENDED_POSITION | mode::CURRENT_BASED_POSITION => {
                        (addr::GOAL_POSITION, s.present.position.to_le_bytes(), 4)
                    }
                    mode::VELOCITY => (addr::GOAL_VELOCITY, [0; 4], 4),
                    mode::CURRENT => (addr::GOAL_CURRENT, [0; 4], 2),
                    _ => (addr::GOAL_PWM, [0; 4], 2),
                };
                self.send(now, |b| {
                    dxl::write(b, id, a, data.get(..len).unwrap_or(&[]))
                })
            }
            op::TORQUE_ON => {
                if !s.torque {
                    // Nothing to send: the servo stays limp.
                    self.op_done(i, o, s.gen);
                    return false;
                }
                self.send(now, |b| dxl::write(b, id, addr::TORQUE_ENABLE, &[1]))
            }
            op::READ_HW => self.send(now, |b| dxl::read(b, id, addr::HARDWARE_ERROR_STATUS, 1)),
            _ => {
                if let Some(s) = self.servos.get_mut(i) {
                    s.ops &= !o;
                }
                return false;
            }
        };
        self.phase = Phase::AwaitOp {
            servo: i,
            op: o,
            deadline: self.op_deadline(o),
            gen: s.gen,
        };
        true
    }

    /// Operation `o` of servo `i`, sent when its request was at generation `gen`, is done.
    fn op_done(&mut self, i: usize, o: u16, gen: u8) {
        if let Some(s) = self.servos.get_mut(i) {
            // A mode change asked for while this one was on the wire: it is redone in full.
            if o & op::MODE_CHANGE != 0 && gen != s.gen {
                s.retries = 0;
                return;
            }
            s.ops &= !o;
            s.retries = 0;
            if s.status == ServoStatus::Configuring && s.ops & op::CONFIGURE == 0 {
                s.status = ServoStatus::Ok;
                s.misses = 0;
            }
        }
    }

    fn op_failed(&mut self, now: Instant, i: usize) {
        let mut lost = None;
        if let Some(s) = self.servos.get_mut(i) {
            s.retries = s.retries.saturating_add(1);
            if s.retries >= OP_RETRIES {
                s.retries = 0;
                let was_configuring = s.status == ServoStatus::Configuring;
                s.status = ServoStatus::Lost;
                s.next_probe = now + PROBE_PERIOD;
                lost = Some(was_configuring);
            }
        }
        match lost {
            Some(true) => self.event(BusEvent::ConfigFailed(i as u8)),
            Some(false) => self.event(BusEvent::Lost(i as u8)),
            None => {}
        }
    }

    fn start_sync_read(&mut self, now: Instant) {
        self.read_list.clear();
        let mut ids: Vec<u8, MAX_SERVOS> = Vec::new();
        for (i, s) in self.servos.iter().enumerate() {
            if s.status == ServoStatus::Ok {
                let _ = self.read_list.push(i as u8);
                let _ = ids.push(s.id);
            }
        }
        self.received = 0;
        if ids.is_empty() {
            self.phase = Phase::ReadDone;
            return;
        }
        self.send(now, |b| {
            dxl::sync_read(b, addr::PRESENT_CURRENT, SYNC_READ_LEN, &ids)
        });
        // Compile-time constants: evaluated (and overflow-checked) by the compiler.
        const PER_STATUS: usize = STATUS_OVERHEAD + SYNC_READ_LEN as usize;
        let per_status = PER_STATUS;
        self.phase = Phase::AwaitSync {
            deadline: self.reply_deadline(per_status.saturating_mul(ids.len())),
        };
    }

    /// Bytes from the bus.
    pub fn on_bytes(&mut self, now: Instant, bytes: &[u8]) {
        let mut rest = bytes;
        while !rest.is_empty() {
            let (used, outcome) = self.decoder.push_slice(rest);
            rest = rest.get(used..).unwrap_or(&[]);
            let pkt = match outcome {
                Some(Ok(p)) if p.is_status() => Some((p.id, p.error(), {
                    let mut d = [0u8; 10];
                    let data = p.data();
                    for (dst, src) in d.iter_mut().zip(data.iter()) {
                        *dst = *src;
                    }
                    (d, data.len())
                })),
                // An instruction echo (half-duplex) or another master: not for us.
                Some(Ok(_)) => None,
                Some(Err(_)) => {
                    self.stats.bad_packets = self.stats.bad_packets.saturating_add(1);
                    None
                }
                None => None,
            };
            if let Some((id, err, (data, len))) = pkt {
                self.stats.packets = self.stats.packets.saturating_add(1);
                self.on_status(now, id, err, &data, len);
            }
        }
    }

    fn on_status(&mut self, now: Instant, id: u8, err: u8, data: &[u8; 10], len: usize) {
        if err & status_error::ALERT != 0 {
            self.stats.alerts = self.stats.alerts.saturating_add(1);
        }
        match self.phase {
            Phase::AwaitOp {
                servo, op: o, gen, ..
            } => {
                let Some(s) = self.servos.get(servo) else {
                    return;
                };
                if s.id != id {
                    self.stats.stale = self.stats.stale.saturating_add(1);
                    return;
                }
                let ok = err & 0x7F == 0;
                // Protocol 2.0 statuses carry no sequence number: a status of the right servo
                // with the wrong shape (a late sync-read status, a ping's answer to a write)
                // answers an earlier transaction. Taking it would complete this one before
                // the servo has even seen it. An error status carries no data.
                if ok && len != op::reply_params(o) {
                    self.stats.stale = self.stats.stale.saturating_add(1);
                    return;
                }
                if !ok {
                    self.op_failed(now, servo);
                } else if o == op::PING && s.status == ServoStatus::Lost {
                    if let Some(s) = self.servos.get_mut(servo) {
                        s.status = ServoStatus::Configuring;
                        s.ops |= op::CONFIGURE;
                        s.hw_error = 0;
                    }
                    self.event(BusEvent::Recovered(servo as u8));
                } else {
                    if let Some(s) = self.servos.get_mut(servo) {
                        match o {
                            op::READ_POS if len >= 4 => {
                                s.present.position = dxl::le_u32(data, 0) as i32;
                                s.position_valid = true;
                            }
                            op::READ_HW if len >= 1 => {
                                s.hw_error = data[0];
                            }
                            _ => {}
                        }
                    }
                    if o == op::READ_HW {
                        let bits = self.servos.get(servo).map(|s| s.hw_error).unwrap_or(0);
                        self.event(BusEvent::HardwareError(servo as u8, bits));
                    }
                    self.op_done(servo, o, gen);
                }
                self.decoder.reset();
                if !self.chain_mode_ops(now) {
                    self.after_ops(now);
                }
            }
            Phase::AwaitSync { .. } => {
                // Servos answer a sync read in the order of its list, each after the one
                // before it: only the next one's status belongs to this read (anything else
                // is late from an earlier one).
                let k = self.received.count_ones() as usize;
                let expected = self
                    .read_list
                    .get(k)
                    .and_then(|&i| self.servos.get(i as usize))
                    .is_some_and(|s| s.id == id);
                if !expected || len != SYNC_READ_LEN as usize {
                    self.stats.stale = self.stats.stale.saturating_add(1);
                    return;
                }
                self.received |= 1 << k;
                let i = self.read_list.get(k).copied().unwrap_or(0) as usize;
                if let Some(s) = self.servos.get_mut(i) {
                    s.present = Present {
                        current: dxl::le_u16(data, 0) as i16,
                        velocity: dxl::le_u32(data, 2) as i32,
                        position: dxl::le_u32(data, 6) as i32,
                    };
                    s.position_valid = true;
                    s.fresh = true;
                    s.misses = 0;
                    if err & status_error::ALERT != 0 && s.hw_error == 0 {
                        s.ops |= op::READ_HW;
                    }
                }
                if self.received.count_ones() as usize == self.read_list.len() {
                    self.phase = Phase::ReadDone;
                }
            }
            _ => {}
        }
    }

    /// Handle timeouts at `now`.
    pub fn poll(&mut self, now: Instant) {
        match self.phase {
            Phase::AwaitOp {
                servo,
                op: o,
                deadline,
                ..
            } if now >= deadline => {
                self.stats.timeouts = self.stats.timeouts.saturating_add(1);
                let lost = self
                    .servos
                    .get(servo)
                    .is_some_and(|s| s.status == ServoStatus::Lost);
                if lost && o == op::PING {
                    if let Some(s) = self.servos.get_mut(servo) {
                        s.next_probe = now + PROBE_PERIOD;
                    }
                } else {
                    self.op_failed(now, servo);
                }
                self.decoder.reset();
                self.after_ops(now);
            }
            Phase::AwaitSync { deadline } if now >= deadline => {
                let missing =
                    (self.read_list.len() as u32).saturating_sub(self.received.count_ones());
                self.stats.timeouts = self.stats.timeouts.saturating_add(missing);
                // Only the first missing servo is to blame: the ones after it wait for its
                // status before answering.
                let first = (0..self.read_list.len()).find(|k| self.received & (1 << k) == 0);
                if let Some(k) = first {
                    let i = self.read_list.get(k).copied().unwrap_or(0) as usize;
                    let mut lost = false;
                    if let Some(s) = self.servos.get_mut(i) {
                        s.misses = s.misses.saturating_add(1);
                        if s.misses >= MISSES_TO_LOSE {
                            s.status = ServoStatus::Lost;
                            s.misses = 0;
                            s.next_probe = now + PROBE_PERIOD;
                            lost = true;
                        }
                    }
                    if lost {
                        self.event(BusEvent::Lost(i as u8));
                    }
                }
                self.phase = Phase::ReadDone;
            }
            _ => {}
        }
    }

    /// Finish the tick: write the goals (one per servo, `Goal::None` to skip).
    pub fn finish_tick(&mut self, now: Instant, goals: &[Goal]) {
        let groups: [(u16, u16); 4] = [
            (addr::GOAL_POSITION, 4),
            (addr::GOAL_VELOCITY, 4),
            (addr::GOAL_CURRENT, 2),
            (addr::GOAL_PWM, 2),
        ];
        for (g, (address, len)) in groups.iter().enumerate() {
            let mut entries: Vec<(u8, [u8; 4]), MAX_SERVOS> = Vec::new();
            for (i, goal) in goals.iter().enumerate() {
                if !self.accepts_goals(i) {
                    continue;
                }
                let Some(s) = self.servos.get(i) else {
                    continue;
                };
                // A goal only ever goes to a servo in the mode it is meant for.
                let fits = match goal {
                    Goal::Position(_) => matches!(
                        s.mode,
                        mode::POSITION | mode::EXTENDED_POSITION | mode::CURRENT_BASED_POSITION
                    ),
                    Goal::Velocity(_) => s.mode == mode::VELOCITY,
                    Goal::Current(_) => s.mode == mode::CURRENT,
                    Goal::Pwm(_) => s.mode == mode::PWM,
                    Goal::None => false,
                };
                if !fits {
                    continue;
                }
                let id = s.id;
                let bytes = match (g, goal) {
                    (0, Goal::Position(p)) => p.to_le_bytes(),
                    (1, Goal::Velocity(v)) => v.to_le_bytes(),
                    (2, Goal::Current(c)) => (*c as i32).to_le_bytes(),
                    (3, Goal::Pwm(p)) => (*p as i32).to_le_bytes(),
                    _ => continue,
                };
                let _ = entries.push((id, bytes));
            }
            if !entries.is_empty() {
                let l = *len as usize;
                self.send(now, |b| {
                    dxl::sync_write(
                        b,
                        *address,
                        *len,
                        entries
                            .iter()
                            .map(|(id, d)| (*id, d.get(..l).unwrap_or(&[]))),
                    )
                });
            }
        }
        self.phase = Phase::Idle;
        self.kick(now);
    }

    /// Between ticks: start the transactions of any servo changing mode now, rather than at
    /// the next tick, so that no servo runs a goal of its old mode for a tick longer.
    pub fn kick(&mut self, now: Instant) {
        if self.phase == Phase::Idle {
            self.ops_then_read = false;
            self.chain_mode_ops(now);
        }
    }

    /// The transactions of this bus cycle are done: read the servos (within a tick), or rest
    /// (between ticks).
    fn after_ops(&mut self, now: Instant) {
        if self.ops_then_read {
            self.start_sync_read(now);
        } else {
            self.phase = Phase::Idle;
        }
    }
}
