//! The host side of a session with the firmware, sans-IO (in the manner of smoltcp): fed with
//! the bytes that arrive and the time, it hands out the bytes to send. One implementation for
//! every link (the in-process simulator, a serial port, an emulated board), each a thin driver
//! that moves bytes and waits.
//!
//! It owns the sequence numbers, the handshake and its version check, the correlation of
//! acknowledgements and rejections with the commands they answer, typed requests and their
//! replies ([`Request`]), heartbeats, the newest telemetry and the fault queue. No allocation:
//! the queues are bounded, and a full one drops its oldest entry (counted).

use heapless::{Deque, Vec};

use crate::frame::{encode_frame, Frame, FrameDecoder, FrameError};
use crate::messages::{
    DeviceInfo, DeviceMsg, Diagnostics, Fault, HostMsg, JointConfig, RejectReason, Telemetry,
};
use crate::{PROTOCOL_VERSION, SCHEMA_HASH};

/// Commands and requests awaiting their answer, at most; a new one beyond evicts the oldest.
pub const MAX_PENDING: usize = 16;
/// Faults kept until taken, at most.
pub const FAULT_QUEUE: usize = 64;

/// What answers a command or a request.
#[derive(Debug, Clone, PartialEq)]
pub enum Answer {
    /// The command was carried out.
    Ack,
    /// The command or request was refused.
    Rejected(RejectReason),
    /// A joint's configuration ([`GetJoint`]).
    Joint(JointConfig),
    /// The firmware's counters ([`GetDiagnostics`]).
    Diagnostics(Diagnostics),
}

/// What a request waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Expect {
    /// An acknowledgement or rejection carrying the sequence number.
    Ack,
    /// The configuration of joint `index` (or a rejection).
    Joint(u8),
    /// The diagnostics (or a rejection).
    Diagnostics,
}

/// A typed request: its message and the reply it expects.
pub trait Request {
    /// The reply.
    type Reply;
    /// The message that asks.
    fn message(&self) -> HostMsg;
    /// What answers it.
    #[doc(hidden)]
    fn expect(&self) -> ExpectKind;
    /// The reply in an answer; `None` when the answer is of another kind.
    fn reply(answer: Answer) -> Option<Self::Reply>;
}

/// What answers a request (opaque outside the session).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExpectKind(Expect);

/// Ask for joint `0`'s configuration, as the firmware holds it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GetJoint(pub u8);

impl Request for GetJoint {
    type Reply = JointConfig;
    fn message(&self) -> HostMsg {
        HostMsg::GetJoint { index: self.0 }
    }
    fn expect(&self) -> ExpectKind {
        ExpectKind(Expect::Joint(self.0))
    }
    fn reply(answer: Answer) -> Option<JointConfig> {
        match answer {
            Answer::Joint(c) => Some(c),
            _ => None,
        }
    }
}

/// Ask for the firmware's link and bus counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GetDiagnostics;

impl Request for GetDiagnostics {
    type Reply = Diagnostics;
    fn message(&self) -> HostMsg {
        HostMsg::GetDiagnostics
    }
    fn expect(&self) -> ExpectKind {
        ExpectKind(Expect::Diagnostics)
    }
    fn reply(answer: Answer) -> Option<Diagnostics> {
        match answer {
            Answer::Diagnostics(d) => Some(d),
            _ => None,
        }
    }
}

/// Why a message could not be sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SessionError {
    /// The message does not fit a frame, or `out` is too small.
    Encode(FrameError),
    /// A request or the handshake sent as a command: use [`HostSession::request`] or
    /// [`HostSession::hello`].
    NotACommand,
}

/// Where the handshake stands.
#[derive(Debug, Clone, PartialEq)]
pub enum Handshake {
    /// No answer to a Hello yet.
    Waiting,
    /// The firmware accepted our version and schema.
    Accepted(DeviceInfo),
    /// The firmware refused them (its own are in the info).
    Refused(DeviceInfo),
}

#[derive(Debug, Clone, Copy)]
struct Pending {
    seq: u16,
    expect: Expect,
    /// A heartbeat: its acknowledgement is dropped.
    quiet: bool,
}

/// Counters of what the session saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SessionStats {
    /// Frames decoded.
    pub frames: u32,
    /// Frames dropped by the decoder (corrupt, oversized, undecodable).
    pub bad_frames: u32,
    /// Answers that matched nothing pending (late, duplicated, or of an evicted request).
    pub stray: u32,
    /// Pending requests evicted by newer ones.
    pub evicted: u32,
    /// Faults dropped from a full queue.
    pub faults_dropped: u32,
}

/// Telemetry reports kept for [`HostSession::take_report`] (the oldest give way): 80 ms at
/// the 10 ms period, more than any reader lets pass between two takes.
pub const REPORTS: usize = 8;

/// The host side of a session (see the module doc).
pub struct HostSession {
    next_seq: u16,
    decoder: FrameDecoder,
    handshake: Handshake,
    telemetry: Option<Telemetry>,
    reports: Deque<Telemetry, REPORTS>,
    faults: Deque<Fault, FAULT_QUEUE>,
    pending: Vec<Pending, MAX_PENDING>,
    answers: Deque<(u16, Answer), MAX_PENDING>,
    last_tx_us: Option<u64>,
    stats: SessionStats,
}

impl core::fmt::Debug for HostSession {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("HostSession")
            .field("next_seq", &self.next_seq)
            .field("handshake", &self.handshake)
            .field("pending", &self.pending.len())
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

impl Default for HostSession {
    fn default() -> Self {
        Self::new()
    }
}

impl HostSession {
    /// A session before its handshake.
    pub fn new() -> Self {
        HostSession {
            next_seq: 0,
            decoder: FrameDecoder::new(),
            handshake: Handshake::Waiting,
            telemetry: None,
            reports: Deque::new(),
            faults: Deque::new(),
            pending: Vec::new(),
            answers: Deque::new(),
            last_tx_us: None,
            stats: SessionStats::default(),
        }
    }

    fn encode(
        &mut self,
        msg: &HostMsg,
        now_us: u64,
        out: &mut [u8],
    ) -> Result<(u16, usize), SessionError> {
        let seq = self.next_seq;
        let n = encode_frame(seq, msg, out).map_err(SessionError::Encode)?;
        self.next_seq = self.next_seq.wrapping_add(1);
        self.last_tx_us = Some(now_us);
        Ok((seq, n))
    }

    fn expect(&mut self, seq: u16, expect: Expect, quiet: bool) {
        if self.pending.is_full() {
            self.pending.remove(0);
            self.stats.evicted = self.stats.evicted.saturating_add(1);
        }
        // Room was made above.
        let _ = self.pending.push(Pending { seq, expect, quiet });
    }

    /// A new connection (a reopened port starts mid-stream): the decoder is reset, the
    /// handshake waits anew, what was pending will not be answered, and the telemetry is
    /// forgotten (what the last connection said is stale: the firmware may have rebooted, or
    /// stopped, meanwhile).
    pub fn restart(&mut self) {
        self.decoder = FrameDecoder::new();
        self.handshake = Handshake::Waiting;
        self.pending.clear();
        self.telemetry = None;
        self.reports.clear();
    }

    /// A Hello with our version and schema into `out`; the handshake waits for its answer.
    pub fn hello(&mut self, now_us: u64, out: &mut [u8]) -> Result<usize, SessionError> {
        self.handshake = Handshake::Waiting;
        let msg = HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH,
        };
        self.encode(&msg, now_us, out).map(|(_, n)| n)
    }

    /// A command into `out`; its answer ([`Answer::Ack`] or [`Answer::Rejected`]) is taken
    /// with [`HostSession::take_answer`] by the returned sequence number.
    pub fn command(
        &mut self,
        msg: &HostMsg,
        now_us: u64,
        out: &mut [u8],
    ) -> Result<(u16, usize), SessionError> {
        self.command_expecting(msg, now_us, out, false)
    }

    /// A command into `out`, its acknowledgement expected, and dropped when it comes if
    /// `quiet`.
    fn command_expecting(
        &mut self,
        msg: &HostMsg,
        now_us: u64,
        out: &mut [u8],
        quiet: bool,
    ) -> Result<(u16, usize), SessionError> {
        if matches!(
            msg,
            HostMsg::Hello { .. } | HostMsg::GetJoint { .. } | HostMsg::GetDiagnostics
        ) {
            return Err(SessionError::NotACommand);
        }
        let (seq, n) = self.encode(msg, now_us, out)?;
        self.expect(seq, Expect::Ack, quiet);
        Ok((seq, n))
    }

    /// A command into `out` whose answer is dropped when it comes (an emergency stop sent
    /// from beside the thread that waits on answers, which sends it again for its answer).
    pub fn command_quiet(
        &mut self,
        msg: &HostMsg,
        now_us: u64,
        out: &mut [u8],
    ) -> Result<usize, SessionError> {
        self.command_expecting(msg, now_us, out, true)
            .map(|(_, n)| n)
    }

    /// A typed request into `out`; its reply is taken with [`HostSession::take_reply`].
    pub fn request<R: Request>(
        &mut self,
        r: &R,
        now_us: u64,
        out: &mut [u8],
    ) -> Result<(u16, usize), SessionError> {
        let (seq, n) = self.encode(&r.message(), now_us, out)?;
        self.expect(seq, r.expect().0, false);
        Ok((seq, n))
    }

    /// A heartbeat into `out` when nothing was sent for `period_us` (or ever); its
    /// acknowledgement is dropped. `None` when none is due.
    pub fn heartbeat_due(&mut self, now_us: u64, period_us: u64, out: &mut [u8]) -> Option<usize> {
        if self
            .last_tx_us
            .is_some_and(|t| now_us.saturating_sub(t) < period_us)
        {
            return None;
        }
        self.command_quiet(&HostMsg::Heartbeat, now_us, out).ok()
    }

    /// A message sent without waiting for its answer (a test's or a hostile host's raw
    /// stream): any message, a sequence number from the session; its answer arrives as
    /// unrouted ([`HostSession::on_bytes_with`]).
    pub fn send_unrouted(
        &mut self,
        msg: &HostMsg,
        now_us: u64,
        out: &mut [u8],
    ) -> Result<(u16, usize), SessionError> {
        self.encode(msg, now_us, out)
    }

    /// Feed bytes received from the firmware.
    pub fn on_bytes(&mut self, bytes: &[u8]) {
        self.on_bytes_with(bytes, |_| {});
    }

    /// Feed bytes received from the firmware; `unrouted` sees every message that answers
    /// nothing pending and is not telemetry (hellos, faults, logs, answers to unrouted
    /// messages), after the session has taken note of it.
    pub fn on_bytes_with(&mut self, bytes: &[u8], mut unrouted: impl FnMut(&DeviceMsg)) {
        let mut decoder = core::mem::take(&mut self.decoder);
        decoder.feed(bytes, |r: Result<Frame<DeviceMsg>, _>| match r {
            Ok(f) => {
                self.stats.frames = self.stats.frames.saturating_add(1);
                if !self.on_message(&f.msg) {
                    unrouted(&f.msg);
                }
            }
            Err(_) => self.stats.bad_frames = self.stats.bad_frames.saturating_add(1),
        });
        self.decoder = decoder;
    }

    /// Route an answer to the request pending at `at`; false when nothing was pending.
    fn answered(&mut self, at: Option<usize>, answer: Answer) -> bool {
        let Some(i) = at else {
            self.stats.stray = self.stats.stray.saturating_add(1);
            return false;
        };
        let p = self.pending.remove(i);
        if p.quiet {
            return true;
        }
        if self.answers.is_full() {
            self.answers.pop_front();
        }
        let _ = self.answers.push_back((p.seq, answer));
        true
    }

    /// Take note of a message; true when it was routed (telemetry, or an answer to something
    /// pending).
    fn on_message(&mut self, msg: &DeviceMsg) -> bool {
        match msg {
            DeviceMsg::Telemetry(t) => {
                self.telemetry = Some(t.clone());
                if self.reports.is_full() {
                    self.reports.pop_front();
                }
                // Room was made above.
                let _ = self.reports.push_back(t.clone());
                true
            }
            DeviceMsg::Fault(f) => {
                if self.faults.is_full() {
                    self.faults.pop_front();
                    self.stats.faults_dropped = self.stats.faults_dropped.saturating_add(1);
                }
                let _ = self.faults.push_back(*f);
                false
            }
            DeviceMsg::Hello(info) => {
                // Faults sent before this answer belong to an earlier session (left in a
                // port's buffer while nobody read).
                self.faults.clear();
                self.handshake = if info.accepted {
                    Handshake::Accepted(info.clone())
                } else {
                    Handshake::Refused(info.clone())
                };
                false
            }
            DeviceMsg::Ack { seq } => {
                let at = self.pending.iter().position(|p| p.seq == *seq);
                self.answered(at, Answer::Ack)
            }
            DeviceMsg::Reject { seq, reason } => {
                let at = self.pending.iter().position(|p| p.seq == *seq);
                self.answered(at, Answer::Rejected(*reason))
            }
            DeviceMsg::Joint { index, config } => {
                let at = self
                    .pending
                    .iter()
                    .position(|p| p.expect == Expect::Joint(*index));
                self.answered(at, Answer::Joint(config.clone()))
            }
            DeviceMsg::Diagnostics(d) => {
                let at = self
                    .pending
                    .iter()
                    .position(|p| p.expect == Expect::Diagnostics);
                self.answered(at, Answer::Diagnostics(*d))
            }
            DeviceMsg::Log(_) => false,
        }
    }

    /// The answer to the command or request `seq`, once it has come.
    pub fn take_answer(&mut self, seq: u16) -> Option<Answer> {
        let i = self.answers.iter().position(|(s, _)| *s == seq)?;
        // Rotate the one found to the front and pop it (Deque has no remove).
        for _ in 0..i {
            if let Some(a) = self.answers.pop_front() {
                let _ = self.answers.push_back(a);
            }
        }
        self.answers.pop_front().map(|(_, a)| a)
    }

    /// The reply to request `seq` of type `R`, once it has come: `Err` with the firmware's
    /// reason when it refused.
    pub fn take_reply<R: Request>(&mut self, seq: u16) -> Option<Result<R::Reply, RejectReason>> {
        match self.take_answer(seq)? {
            Answer::Rejected(r) => Some(Err(r)),
            a => R::reply(a).map(Ok),
        }
    }

    /// Stop waiting for `seq` (its caller gave up); a late answer then counts as stray.
    pub fn forget(&mut self, seq: u16) {
        self.pending.retain(|p| p.seq != seq);
    }

    /// Where the handshake stands.
    pub fn handshake(&self) -> &Handshake {
        &self.handshake
    }

    /// The oldest telemetry report not yet taken (the newest [`REPORTS`] are kept): for a
    /// reader that wants every report, not only the newest.
    pub fn take_report(&mut self) -> Option<Telemetry> {
        self.reports.pop_front()
    }

    /// The newest telemetry.
    pub fn telemetry(&self) -> Option<&Telemetry> {
        self.telemetry.as_ref()
    }

    /// The oldest fault not yet taken.
    pub fn take_fault(&mut self) -> Option<Fault> {
        self.faults.pop_front()
    }

    /// Counters.
    pub fn stats(&self) -> SessionStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::{FaultKind, GripperCommand};
    use crate::MAX_WIRE;

    fn device(seq: u16, msg: &DeviceMsg) -> heapless::Vec<u8, MAX_WIRE> {
        let mut buf = [0u8; MAX_WIRE];
        let n = encode_frame(seq, msg, &mut buf).expect("fits");
        heapless::Vec::from_slice(&buf[..n]).expect("fits")
    }

    #[test]
    fn answers_go_to_the_command_they_answer() {
        let mut s = HostSession::new();
        let mut out = [0u8; MAX_WIRE];
        let (a, _) = s
            .command(&HostMsg::Gripper(GripperCommand::Open), 0, &mut out)
            .expect("sent");
        let (b, _) = s.command(&HostMsg::Resume, 0, &mut out).expect("sent");
        // Answers out of order, with garbage between them.
        s.on_bytes(&device(
            0,
            &DeviceMsg::Reject {
                seq: b,
                reason: RejectReason::Busy,
            },
        ));
        s.on_bytes(&[1, 2, 3, 0, 0xff, 0]);
        s.on_bytes(&device(0, &DeviceMsg::Ack { seq: a }));
        assert_eq!(s.take_answer(a), Some(Answer::Ack));
        assert_eq!(s.take_answer(b), Some(Answer::Rejected(RejectReason::Busy)));
        assert_eq!(s.take_answer(a), None, "an answer is taken once");
        assert!(s.stats().bad_frames >= 1);
        // An answer to nothing is stray, not an answer.
        s.on_bytes(&device(0, &DeviceMsg::Ack { seq: 999 }));
        assert_eq!(s.take_answer(999), None);
        assert_eq!(s.stats().stray, 1);
    }

    #[test]
    fn typed_requests_get_their_reply_and_heartbeats_stay_quiet() {
        let mut s = HostSession::new();
        let mut out = [0u8; MAX_WIRE];
        assert!(s.heartbeat_due(0, 100_000, &mut out).is_some());
        assert!(s.heartbeat_due(50_000, 100_000, &mut out).is_none());
        let (d, _) = s.request(&GetDiagnostics, 60_000, &mut out).expect("sent");
        s.on_bytes(&device(0, &DeviceMsg::Ack { seq: 0 }));
        let diag = Diagnostics {
            host_frames: 7,
            ..Diagnostics::default()
        };
        s.on_bytes(&device(0, &DeviceMsg::Diagnostics(diag)));
        assert_eq!(s.take_reply::<GetDiagnostics>(d), Some(Ok(diag)));
        assert_eq!(s.stats().stray, 0, "the heartbeat's ack was expected");
        assert_eq!(
            s.command(&HostMsg::GetDiagnostics, 0, &mut out),
            Err(SessionError::NotACommand)
        );
        let (j, _) = s.request(&GetJoint(3), 0, &mut out).expect("sent");
        s.on_bytes(&device(
            0,
            &DeviceMsg::Reject {
                seq: j,
                reason: RejectReason::UnknownJoint,
            },
        ));
        assert_eq!(
            s.take_reply::<GetJoint>(j),
            Some(Err(RejectReason::UnknownJoint))
        );
    }

    /// A telemetry report at `time_us` of a robot without joints.
    fn report(time_us: u64) -> Telemetry {
        Telemetry {
            time_us,
            joints: heapless::Vec::new(),
            queued: 0,
            gripper: crate::GripperState::Unknown,
            odometry: Default::default(),
            wheels: Default::default(),
            base_flags: 0,
            faults: 0,
            loop_stats: Default::default(),
        }
    }

    /// Every report is kept for a reader that wants them all, the newest [`REPORTS`] of them,
    /// oldest first; a restart forgets them.
    #[test]
    fn reports_are_kept_in_order_up_to_their_bound() {
        let mut s = HostSession::new();
        for i in 0..(REPORTS as u64 + 3) {
            s.on_bytes(&device(0, &DeviceMsg::Telemetry(report(i * 10_000))));
        }
        let got: heapless::Vec<u64, 16> = core::iter::from_fn(|| s.take_report())
            .map(|t| t.time_us)
            .collect();
        let want: heapless::Vec<u64, 16> = (3..REPORTS as u64 + 3).map(|i| i * 10_000).collect();
        assert_eq!(got, want);
        s.on_bytes(&device(0, &DeviceMsg::Telemetry(report(1))));
        s.restart();
        assert!(s.take_report().is_none());
    }

    /// A new connection forgets the old one's telemetry: the host must not take what a
    /// firmware said before a reboot, or before its loop stopped, for its state now.
    #[test]
    fn a_restart_forgets_the_telemetry() {
        let mut s = HostSession::new();
        let t = report(5_000);
        s.on_bytes(&device(0, &DeviceMsg::Telemetry(t.clone())));
        assert_eq!(s.telemetry(), Some(&t));
        s.restart();
        assert_eq!(s.telemetry(), None);
    }

    #[test]
    fn queues_are_bounded_and_a_hello_starts_afresh() {
        let mut s = HostSession::new();
        let mut out = [0u8; MAX_WIRE];
        for k in 0..(MAX_PENDING as u16 + 4) {
            s.command(&HostMsg::Resume, k as u64, &mut out)
                .expect("sent");
        }
        assert_eq!(s.stats().evicted, 4);
        let fault = Fault {
            kind: FaultKind::Watchdog,
            joint: None,
            servo_id: None,
            code: 0,
            time_us: 0,
        };
        for _ in 0..FAULT_QUEUE + 3 {
            s.on_bytes(&device(0, &DeviceMsg::Fault(fault)));
        }
        assert_eq!(s.stats().faults_dropped, 3);
        assert_eq!(s.take_fault(), Some(fault));
        s.hello(0, &mut out).expect("hello");
        assert_eq!(s.handshake(), &Handshake::Waiting);
    }
}
