//! One bus cycle per servo-loop tick: a configuration transaction if one is pending, the sync
//! read of every servo in the loop, then the sync write of the goals; the line's time (from
//! its bit rate) sets each reply's deadline, and a servo that misses [`MISSES_TO_LOSE`] sync
//! reads in a row is lost.

use ferrobot_protocol::dxl::{self, addr, mode};
use ferrobot_protocol::JointConfig;
use heapless::Vec;

use super::{
    op, BusEvent, Goal, Phase, ServoBus, ServoStatus, MAX_SERVOS, MISSES_TO_LOSE, PROBE_PERIOD,
    STATUS_OVERHEAD, SYNC_READ_LEN, UNCONFIGURED_RETURN_DELAY,
};
use crate::time::Instant;

impl ServoBus {
    /// Hand a packet built by `build` to the line at `now`; the bytes sent (0 if it did not
    /// fit). The line stays busy for their time after whatever was still on it.
    pub(super) fn send(
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
    pub(super) fn reply_deadline(&self, reply_bytes: usize) -> Instant {
        self.line_free_at + self.cfg.bytes_time(reply_bytes) + self.cfg.reply_margin
    }

    /// Deadline of operation `o`'s status: the servo may still answer after its factory
    /// return delay.
    pub(super) fn op_deadline(&self, o: u16) -> Instant {
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

    pub(super) fn start_sync_read(&mut self, now: Instant) {
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
            self.chain_mode_ops(now, None);
        }
    }

    /// The transactions of this bus cycle are done: read the servos (within a tick), or rest
    /// (between ticks).
    pub(super) fn after_ops(&mut self, now: Instant) {
        if self.ops_then_read {
            self.start_sync_read(now);
        } else {
            self.phase = Phase::Idle;
        }
    }
}
