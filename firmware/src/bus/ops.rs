//! The configuration transactions of the bus master: one at a time, each a write or read the
//! servo answers, the lowest pending [`op`] bit of a servo first; a lost servo is pinged
//! every [`PROBE_PERIOD`], and a servo that fails [`OP_RETRIES`] in a row is lost.

use ferrobot_protocol::dxl::{self, addr, mode};
use ferrobot_protocol::JointConfig;

use super::{op, BusEvent, Phase, Servo, ServoBus, ServoStatus, OP_RETRIES, PROBE_PERIOD};
use crate::time::Instant;

impl ServoBus {
    pub(super) fn start_op(&mut self, now: Instant, joints: &[JointConfig]) -> bool {
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

    /// After a mode-change transaction of servo `last` (none: between ticks, from idle), the
    /// next one of any servo changing mode: a servo whose change has begun is finished at
    /// once, never left limp, or running a goal of its old mode, for longer than its
    /// transactions take. Another servo's change starts only between ticks and before the
    /// next tick is due: a chain of changes across ticks would leave every other servo's goal
    /// stale (a joint in current mode kept accelerating with a stale effort for 3 ms, to
    /// 1.09 rad/s against its 0.63 rad/s limit: pointed seed 716). Returns whether one was
    /// started.
    pub(super) fn chain_mode_ops(&mut self, now: Instant, last: Option<usize>) -> bool {
        loop {
            let changing = |s: &Servo| {
                s.status == ServoStatus::Ok && s.ops != 0 && s.ops & !op::MODE_CHANGE == 0
            };
            let going_on = last.filter(|&i| self.servos.get(i).is_some_and(changing));
            let next = going_on.or_else(|| {
                let may_start = !self.ops_then_read && now < self.next_tick;
                may_start
                    .then(|| self.servos.iter().position(changing))
                    .flatten()
            });
            let Some(i) = next else {
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
    pub(super) fn issue_op(&mut self, now: Instant, i: usize, joints: &[JointConfig]) -> bool {
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
            op::READ_TORQUE => self.send(now, |b| dxl::read(b, id, addr::TORQUE_ENABLE, 1)),
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
    pub(super) fn op_done(&mut self, i: usize, o: u16, gen: u8) {
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

    pub(super) fn op_failed(&mut self, now: Instant, i: usize) {
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
}
