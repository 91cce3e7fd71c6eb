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
//!
//! The master's state and its servos are here; its `impl` is split by concern: the bus
//! cycle (line timing, the sync read and write, timeouts), the configuration transactions,
//! and the decoding of the statuses that answer them.

use ferrobot_protocol::dxl::{self, mode, PacketDecoder};
use ferrobot_protocol::{JointConfig, ServoModel};
use heapless::Vec;

use crate::config::BusConfig;
use crate::time::{Duration, Instant};
use crate::txbuf::TxBuf;
use heapless::Deque;

mod cycle;
mod ops;
mod status;

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
    /// Read Torque Enable of a servo that answers again after it was lost: still on, it kept
    /// its power and its settings (only its answers were lost: a noisy or stalled line), and
    /// it is taken back holding where it stands; off, it was power-cycled and is configured
    /// in full. A servo holding the arm is never switched off to be taken back.
    pub const READ_TORQUE: u16 = 1 << 12;
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
    /// Taking back a lost servo that kept its torque on: its position read and held.
    pub const RESUME: u16 = READ_POS | GOAL_HOLD;
    /// Operations during which no goal may be written.
    pub const BLOCKS_GOALS: u16 = CONFIGURE | REBOOT | READ_TORQUE;

    /// Parameters in the status that answers operation `o` (a ping's model and firmware
    /// version, a position read's 4 bytes, a hardware-error read's 1; writes and reboots
    /// answer with none).
    pub const fn reply_params(o: u16) -> usize {
        match o {
            PING => 3,
            READ_POS => 4,
            READ_HW | READ_TORQUE => 1,
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
    /// Its position was read again after it was lost or rebooted, its torque maybe off for a
    /// while: the firmware holds its joint where it now stands (not where it stood before, which
    /// a joint that sagged would be driven back to) and clears this.
    pub reread: bool,
    /// Lost or rebooted: the next position read sets [`Servo::reread`].
    reread_pending: bool,
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
    /// When the servo loop's next tick is due (set by the core): between ticks, no servo's
    /// mode change starts after it, so that the other servos' goals are not left stale.
    next_tick: Instant,
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
        M::Position | M::Teach | M::Off if multi_turn => mode::EXTENDED_POSITION,
        M::Position | M::Teach | M::Off => mode::POSITION,
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
            next_tick: Instant::ZERO,
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
                        reread: false,
                        reread_pending: false,
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

    /// When the servo loop's next tick is due: mode changes between ticks start only before it.
    pub fn set_next_tick(&mut self, t: Instant) {
        self.next_tick = t;
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
            s.reread_pending = true;
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
}
