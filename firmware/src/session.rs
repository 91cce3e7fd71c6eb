//! The session with the host: the handshake (protocol version and schema hash), the session
//! gate that refuses every command before an accepted Hello, the answers (an Ack or a Reject
//! carrying the frame's sequence number, or the reply message), and the sequence numbers of
//! the frames the firmware sends. The emergency stop passes the gate in every state.

use ferrobot_protocol::{
    encode_frame, DeviceInfo, DeviceMsg, HostMsg, RejectReason, MAX_WIRE, PROTOCOL_VERSION,
    SCHEMA_HASH,
};

use crate::log::{self, log_info, log_warn};
use crate::time::Instant;
use crate::{Firmware, FIRMWARE_VERSION};

/// Where the handshake stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Session {
    /// No Hello yet.
    None,
    /// The host's version and schema match.
    Accepted,
    /// The host's version or schema differs: every command but the emergency stop is refused.
    Refused,
}

impl Firmware {
    /// The answer to a Hello, saying whether it was `accepted`.
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

    /// Answer one valid frame from the host: the emergency stop first, in every state; then
    /// the Hello; then, past the session gate, the queries and the commands.
    pub(crate) fn handle(&mut self, now: Instant, seq: u16, msg: HostMsg) {
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

    /// Queue a frame to the host with the next sequence number (counted as dropped when the
    /// link has no room).
    pub(crate) fn send(&mut self, msg: &DeviceMsg) {
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
}
