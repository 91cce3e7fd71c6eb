//! Decoding what the servos answer: status packets that fail CRC or framing are counted and
//! dropped; a status is taken only as the answer to the transaction under way (right servo,
//! right shape) or as the next one of the sync read, and anything else is counted as stale.

use ferrobot_protocol::dxl::{self, status_error};

use super::{op, BusEvent, Phase, Present, ServoBus, ServoStatus, SYNC_READ_LEN};
use crate::time::Instant;

impl ServoBus {
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

    pub(super) fn on_status(&mut self, now: Instant, id: u8, err: u8, data: &[u8; 10], len: usize) {
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
                    // Whether it kept its torque decides how it is taken back (READ_TORQUE).
                    if let Some(s) = self.servos.get_mut(servo) {
                        s.status = ServoStatus::Configuring;
                        s.ops |= op::READ_TORQUE;
                        s.hw_error = 0;
                        s.reread_pending = true;
                    }
                    self.event(BusEvent::Recovered(servo as u8));
                } else {
                    if let Some(s) = self.servos.get_mut(servo) {
                        match o {
                            op::READ_POS if len >= 4 => {
                                s.present.position = dxl::le_u32(data, 0) as i32;
                                s.position_valid = true;
                                s.reread |= core::mem::take(&mut s.reread_pending);
                            }
                            op::READ_HW if len >= 1 => {
                                s.hw_error = data[0];
                            }
                            op::READ_TORQUE if len >= 1 => {
                                s.ops |= if data[0] == 1 {
                                    op::RESUME
                                } else {
                                    op::CONFIGURE
                                };
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
                if !self.chain_mode_ops(now, Some(servo)) {
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
}
