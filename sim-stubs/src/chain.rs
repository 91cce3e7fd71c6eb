//! A Dynamixel 2.0 servo chain: the servos behind one half-duplex bus, answering real
//! instruction packets (ping, read, write, registered write and action, reboot, factory reset,
//! clear, sync read and write, bulk read and write) with real status packets.
//!
//! Replies come in the order the instruction names the servos, each after its Return Delay
//! Time; in a sync or bulk read each servo waits for the status of the one before it, so a
//! silent servo also silences the ones after it, as on the real bus. Packets with a bad CRC
//! are dropped and counted.

use ferrobot_protocol::dxl::{self, addr, inst, status_error, PacketDecoder};
use ferrobot_protocol::ServoModel;

use crate::arm::{gravity_torques, ArmJoint};
use crate::rng::SimRng;
use crate::servo::{ServoSim, SUBSTEP};

/// How a servo sits in the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoMount {
    /// Dynamixel ID.
    pub id: u8,
    /// Model.
    pub model: ServoModel,
    /// Arm joint it drives (index into the arm chain), if any.
    pub arm_joint: Option<usize>,
    /// dθ_servo / dq_joint: +1, −1 (sign-inverted or mirrored twin).
    pub gain: f64,
    /// Share of the joint's load this servo carries.
    pub share: f64,
    /// Mechanical stops in servo angle, rad.
    pub stops: Option<(f64, f64)>,
    /// Servo angle at power-up, rad.
    pub initial: f64,
}

/// One reply: bytes that go on the bus `delay_us` after the instruction was received (or
/// after the previous reply finished, the bus serialising them).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    /// Delay, µs.
    pub delay_us: u64,
    /// Packet bytes.
    pub bytes: Vec<u8>,
}

/// Chain counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ChainStats {
    /// Instruction packets accepted.
    pub instructions: u32,
    /// Packets dropped for CRC or length errors.
    pub bad_packets: u32,
    /// Status packets sent.
    pub statuses: u32,
}

/// Servo processing latency before the return delay, µs.
pub const PROCESSING_US: u64 = 10;

/// The chain.
pub struct ServoChain {
    /// Servos.
    pub servos: Vec<ServoSim>,
    /// Their mounts (same order).
    pub mounts: Vec<ServoMount>,
    arm: Vec<ArmJoint>,
    decoder: PacketDecoder<1100>,
    time_us: u64,
    substep_acc: u64,
    /// Physics substeps taken since the start.
    substeps: u64,
    pending_reg: Vec<(usize, u16, Vec<u8>)>,
    corrupt_replies: u32,
    present_stale: bool,
    /// Counters.
    pub stats: ChainStats,
}

impl ServoChain {
    /// A chain of `mounts` with gravity from `arm`, seeded.
    pub fn new(mounts: &[ServoMount], arm: &[ArmJoint], seed: u64) -> Self {
        let servos = mounts
            .iter()
            .map(|m| {
                let mut s = ServoSim::new(
                    m.id,
                    m.model,
                    m.initial,
                    SimRng::new(seed, 1000 + m.id as u64),
                );
                s.stops = m.stops;
                s
            })
            .collect();
        Self {
            servos,
            mounts: mounts.to_vec(),
            arm: arm.to_vec(),
            decoder: PacketDecoder::new(),
            time_us: 0,
            substep_acc: 0,
            substeps: 0,
            pending_reg: Vec::new(),
            corrupt_replies: 0,
            present_stale: true,
            stats: ChainStats::default(),
        }
    }

    /// Simulated time, µs.
    pub fn time_us(&self) -> u64 {
        self.time_us
    }

    /// Start the chain's clock at `t_us` (µs), before it ran: nothing happened before.
    pub fn start_at(&mut self, t_us: u64) {
        self.time_us = self.time_us.max(t_us);
    }

    /// The servo with `id`.
    pub fn servo(&self, id: u8) -> Option<&ServoSim> {
        self.servos.iter().find(|s| s.id == id)
    }

    /// The servo with `id`, mutably (fault injection, objects in the gripper).
    pub fn servo_mut(&mut self, id: u8) -> Option<&mut ServoSim> {
        self.servos.iter_mut().find(|s| s.id == id)
    }

    /// Scale the mass of each arm link by `scale(link index)`: a plant whose masses differ
    /// from the description's (a model is never exact).
    pub fn scale_arm_masses(&mut self, mut scale: impl FnMut(usize) -> f64) {
        for (i, l) in self.arm.iter_mut().enumerate() {
            l.mass *= scale(i);
        }
    }

    /// A hand's torque `tau` (N·m, about the joint's axis) on arm joint `joint` (index into
    /// the arm chain), shared by its servos as gravity is, until changed; 0 lets go.
    pub fn set_hand_torque(&mut self, joint: usize, tau: f64) {
        for (s, m) in self.servos.iter_mut().zip(&self.mounts) {
            if m.arm_joint == Some(joint) {
                s.hand_torque = m.gain * m.share * tau;
            }
        }
    }

    /// Corrupt one byte of each of the next `n` status packets.
    pub fn corrupt_next_replies(&mut self, n: u32) {
        self.corrupt_replies += n;
    }

    /// Arm joint angles (rad) as the primary servos of the arm joints see them.
    pub fn arm_angles(&self) -> Vec<f64> {
        let mut q = vec![0.0; self.arm.len()];
        for (s, m) in self.servos.iter().zip(&self.mounts) {
            if let Some(j) = m.arm_joint {
                if m.share >= 0.5 && m.gain != 0.0 {
                    if let Some(v) = q.get_mut(j) {
                        // The first mount of a joint is its primary.
                        if *v == 0.0 {
                            *v = s.theta / m.gain;
                        }
                    }
                }
            }
        }
        q
    }

    /// Advance the physics to `t_us`.
    pub fn advance_to(&mut self, t_us: u64) {
        if t_us <= self.time_us {
            return;
        }
        let step_us = (SUBSTEP * 1e6) as u64;
        self.substep_acc += t_us - self.time_us;
        self.time_us = t_us;
        let mut stepped = false;
        while self.substep_acc >= step_us {
            self.substep_acc -= step_us;
            // Gravity every fourth substep of the chain's life, so the physics does not depend
            // on how often it is advanced.
            if self.substeps.is_multiple_of(4) && !self.arm.is_empty() {
                self.apply_gravity();
            }
            for s in self.servos.iter_mut() {
                s.step();
            }
            self.substeps += 1;
            stepped = true;
        }
        if stepped {
            self.present_stale = true;
        }
    }

    /// Refresh the present-value registers, once per instant at which someone reads them.
    fn refresh_present(&mut self) {
        if std::mem::take(&mut self.present_stale) {
            for s in self.servos.iter_mut() {
                s.update_present();
            }
        }
    }

    fn apply_gravity(&mut self) {
        let q = self.arm_angles();
        let mut tau = vec![0.0; self.arm.len()];
        gravity_torques(&self.arm, &q, &mut tau);
        for (s, m) in self.servos.iter_mut().zip(&self.mounts) {
            if let Some(j) = m.arm_joint {
                s.external_torque = m.gain * m.share * tau.get(j).copied().unwrap_or(0.0);
            }
        }
    }

    fn index(&self, id: u8) -> Option<usize> {
        self.servos.iter().position(|s| s.id == id)
    }

    fn status(&mut self, i: usize, err: u8, params: &[u8], delay_extra: u64) -> Option<Reply> {
        let s = self.servos.get(i)?;
        let mut buf = vec![0u8; params.len() * 2 + 16];
        let n = dxl::status(&mut buf, s.id, err | s.status_error(), params).ok()?;
        buf.truncate(n);
        if self.corrupt_replies > 0 {
            self.corrupt_replies -= 1;
            if let Some(b) = buf.get_mut(n / 2) {
                *b ^= 0x5A;
            }
        }
        self.stats.statuses += 1;
        let rdt = s.get(addr::RETURN_DELAY_TIME, 1) as u64 * 2;
        Some(Reply {
            delay_us: PROCESSING_US + rdt + delay_extra,
            bytes: buf,
        })
    }

    fn status_level(&self, i: usize) -> u32 {
        self.servos
            .get(i)
            .map(|s| s.get(addr::STATUS_RETURN_LEVEL, 1))
            .unwrap_or(2)
    }

    /// Bytes from the master at time `t_us` (physics must be advanced to it); returns replies.
    pub fn on_bytes(&mut self, t_us: u64, bytes: &[u8]) -> Vec<Reply> {
        self.advance_to(t_us);
        let mut replies = Vec::new();
        let mut packets: Vec<(u8, u8, Vec<u8>)> = Vec::new();
        for &b in bytes {
            match self.decoder.push(b) {
                Some(Ok(p)) if !p.is_status() => {
                    packets.push((p.id, p.instruction, p.params.to_vec()))
                }
                Some(Ok(_)) => {}
                Some(Err(_)) => self.stats.bad_packets += 1,
                None => {}
            }
        }
        if packets
            .iter()
            .any(|(_, ins, _)| matches!(*ins, inst::READ | inst::SYNC_READ | inst::BULK_READ))
        {
            self.refresh_present();
        }
        for (id, ins, params) in packets {
            self.stats.instructions += 1;
            self.execute(id, ins, &params, &mut replies);
        }
        replies
    }

    /// Sync and bulk read: each `(id, address, length)` answers in turn, each servo waiting
    /// for the status of the one before it, so a silent or missing servo silences the rest.
    fn chained_reads(&mut self, reads: &[(u8, u16, u16)], replies: &mut Vec<Reply>) {
        for &(sid, a, n) in reads {
            let Some(i) = self.index(sid) else { break };
            if self.servos.get(i).is_some_and(|s| s.silent) {
                break;
            }
            let data = self
                .servos
                .get(i)
                .and_then(|s| s.read(a, n))
                .map(|d| d.to_vec());
            match data {
                Some(d) => replies.extend(self.status(i, 0, &d, 0)),
                None => replies.extend(self.status(i, status_error::ACCESS, &[], 0)),
            }
        }
    }

    /// Execute one instruction packet `ins` for `id` with parameters `p`, adding the replies.
    fn execute(&mut self, id: u8, ins: u8, p: &[u8], replies: &mut Vec<Reply>) {
        let broadcast = id == dxl::BROADCAST_ID;
        match ins {
            inst::PING => self.ping(id, broadcast, replies),
            inst::READ
            | inst::WRITE
            | inst::REG_WRITE
            | inst::REBOOT
            | inst::FACTORY_RESET
            | inst::CLEAR
                if !broadcast =>
            {
                self.unicast(id, ins, p, replies)
            }
            inst::WRITE if broadcast => {
                let a = dxl::le_u16(p, 0);
                if let Some(d) = p.get(2..) {
                    for s in self.servos.iter_mut().filter(|s| !s.silent) {
                        s.write(a, d);
                    }
                }
            }
            inst::ACTION => self.action(id, broadcast),
            inst::SYNC_READ => {
                let (a, n) = (dxl::le_u16(p, 0), dxl::le_u16(p, 2));
                let reads: Vec<(u8, u16, u16)> = p
                    .get(4..)
                    .unwrap_or(&[])
                    .iter()
                    .map(|&sid| (sid, a, n))
                    .collect();
                self.chained_reads(&reads, replies);
            }
            inst::SYNC_WRITE => self.sync_write(p),
            inst::BULK_READ => {
                let reads: Vec<(u8, u16, u16)> = p
                    .chunks_exact(5)
                    .map(|e| (e[0], dxl::le_u16(e, 1), dxl::le_u16(e, 3)))
                    .collect();
                self.chained_reads(&reads, replies);
            }
            inst::BULK_WRITE => self.bulk_write(p),
            _ => {
                if !broadcast {
                    if let Some(i) = self.index(id) {
                        if !self.servos.get(i).is_some_and(|s| s.silent) {
                            replies.extend(self.status(i, status_error::INSTRUCTION, &[], 0));
                        }
                    }
                }
            }
        }
    }

    /// Ping: every servo that is not silent answers with its model and firmware version.
    fn ping(&mut self, id: u8, broadcast: bool, replies: &mut Vec<Reply>) {
        let targets: Vec<usize> = if broadcast {
            (0..self.servos.len()).collect()
        } else {
            self.index(id).into_iter().collect()
        };
        for i in targets {
            if self.servos.get(i).is_some_and(|s| s.silent) {
                continue;
            }
            let (model, fw) = match self.servos.get(i) {
                Some(s) => (
                    s.get(addr::MODEL_NUMBER, 2) as u16,
                    s.get(addr::FIRMWARE_VERSION, 1) as u8,
                ),
                None => continue,
            };
            let m = model.to_le_bytes();
            replies.extend(self.status(i, 0, &[m[0], m[1], fw], 0));
        }
    }

    /// An instruction to one servo (read, write, registered write, reboot, factory reset,
    /// clear), answered as its status return level asks.
    fn unicast(&mut self, id: u8, ins: u8, p: &[u8], replies: &mut Vec<Reply>) {
        let Some(i) = self.index(id) else { return };
        if self.servos.get(i).is_some_and(|s| s.silent) {
            return;
        }
        let level = self.status_level(i);
        let (err, data) = self.apply(i, ins, p);
        let answer = level >= 2 || (level == 1 && ins == inst::READ);
        if answer {
            replies.extend(self.status(i, err, &data, 0));
        }
    }

    /// Apply a one-servo instruction to servo `i`: its error and the data read.
    fn apply(&mut self, i: usize, ins: u8, p: &[u8]) -> (u8, Vec<u8>) {
        match ins {
            inst::READ => {
                let (a, n) = (dxl::le_u16(p, 0), dxl::le_u16(p, 2));
                match self.servos.get(i).and_then(|s| s.read(a, n)) {
                    Some(d) if p.len() == 4 => (0, d.to_vec()),
                    _ => (status_error::ACCESS, Vec::new()),
                }
            }
            inst::WRITE => {
                let a = dxl::le_u16(p, 0);
                let e = match (self.servos.get_mut(i), p.get(2..)) {
                    (Some(s), Some(d)) => s.write(a, d),
                    _ => status_error::DATA_LENGTH,
                };
                (e, Vec::new())
            }
            inst::REG_WRITE => {
                let a = dxl::le_u16(p, 0);
                self.pending_reg
                    .push((i, a, p.get(2..).unwrap_or(&[]).to_vec()));
                (0, Vec::new())
            }
            inst::REBOOT => {
                if let Some(s) = self.servos.get_mut(i) {
                    s.reboot();
                }
                (0, Vec::new())
            }
            inst::FACTORY_RESET => {
                if let Some(s) = self.servos.get_mut(i) {
                    s.factory_reset();
                }
                (0, Vec::new())
            }
            _ => (0, Vec::new()),
        }
    }

    /// Action: the registered writes for `id` (all of them for broadcast) take effect.
    fn action(&mut self, id: u8, broadcast: bool) {
        let regs = std::mem::take(&mut self.pending_reg);
        for (i, a, d) in regs {
            if broadcast || self.servos.get(i).is_some_and(|s| s.id == id) {
                if let Some(s) = self.servos.get_mut(i) {
                    s.write(a, &d);
                }
            }
        }
    }

    /// Sync write: one address and length, data for each servo in turn.
    fn sync_write(&mut self, p: &[u8]) {
        let (a, n) = (dxl::le_u16(p, 0), dxl::le_u16(p, 2) as usize);
        let mut rest = p.get(4..).unwrap_or(&[]);
        while let (Some(&sid), Some(d)) = (rest.first(), rest.get(1..1 + n)) {
            if let Some(i) = self.index(sid) {
                if let Some(s) = self.servos.get_mut(i).filter(|s| !s.silent) {
                    s.write(a, d);
                }
            }
            rest = rest.get(1 + n..).unwrap_or(&[]);
        }
    }

    /// Bulk write: an address, a length and data for each servo in turn.
    fn bulk_write(&mut self, p: &[u8]) {
        let mut rest = p;
        while rest.len() >= 5 {
            let (sid, a, n) = (rest[0], dxl::le_u16(rest, 1), dxl::le_u16(rest, 3) as usize);
            let Some(d) = rest.get(5..5 + n) else { break };
            if let Some(i) = self.index(sid) {
                if let Some(s) = self.servos.get_mut(i).filter(|s| !s.silent) {
                    s.write(a, d);
                }
            }
            rest = rest.get(5 + n..).unwrap_or(&[]);
        }
    }
}
