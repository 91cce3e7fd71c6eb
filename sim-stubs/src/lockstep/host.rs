//! The host's end of a simulated serial port: the protocol's host session ([`HostSession`],
//! the one the API's links drive too) in lockstep with a simulator, its heartbeats fed as a
//! host's I/O thread feeds them, plus raw access for tests and hostile hosts.
//!
//! [`HostSide`] is what a host does through one such end (handshake, commands, requests,
//! waits), written once for both floors it runs on: a robot alone ([`SimHost`], its
//! [`LockstepSim`]) and a robot among others on one clock ([`crate::shared::Seat`]).

use ferrobot_protocol::session::{Answer, HostSession, Request, SessionError};
use ferrobot_protocol::{
    DeviceMsg, HostMsg, RejectReason, Telemetry, MAX_WIRE, PROTOCOL_VERSION, SCHEMA_HASH,
};

use super::{LockstepSim, SimError};

/// Messages a [`HostEnd`] keeps for callers to wait for, at most.
pub const INBOX_CAP: usize = 1024;

/// Heartbeat period of a [`HostEnd`] with keepalive on, µs.
pub const KEEPALIVE_US: u64 = 100_000;

/// A host's state at its end of the port: the session and what it received.
pub struct HostEnd {
    /// The host session.
    pub session: HostSession,
    /// Messages received that answered nothing pending (hellos, faults, logs, answers to
    /// [`HostSide::send`]), oldest first, at most [`INBOX_CAP`].
    pub inbox: Vec<DeviceMsg>,
    /// The newest telemetry.
    pub telemetry: Option<Telemetry>,
    /// Send a heartbeat every [`KEEPALIVE_US`] of simulated time, as a host's I/O thread does,
    /// so the firmware's watchdog stays fed (on by default).
    pub keepalive: bool,
    last_keepalive: u64,
}

impl Default for HostEnd {
    fn default() -> Self {
        HostEnd::opened_at(0)
    }
}

impl HostEnd {
    /// A new end, its port opened at `now_us` (µs): its first heartbeat [`KEEPALIVE_US`]
    /// later.
    pub fn opened_at(now_us: u64) -> Self {
        HostEnd {
            session: HostSession::new(),
            inbox: Vec::new(),
            telemetry: None,
            keepalive: true,
            last_keepalive: now_us,
        }
    }

    /// The heartbeat due at `now_us`, if keepalive is on and one is due: its bytes.
    pub fn heartbeat(&mut self, now_us: u64) -> Option<Vec<u8>> {
        if !(self.keepalive && now_us >= self.last_keepalive + KEEPALIVE_US) {
            return None;
        }
        self.last_keepalive = now_us;
        let mut buf = [0u8; MAX_WIRE];
        let n = self.session.heartbeat_due(now_us, 0, &mut buf)?;
        Some(buf[..n].to_vec())
    }

    /// Route `bytes` from the firmware through the session: answers to their requests,
    /// telemetry, and everything else to the inbox (faults too, in order).
    pub fn absorb(&mut self, bytes: &[u8]) {
        let inbox = &mut self.inbox;
        self.session.on_bytes_with(bytes, |m| {
            // Bounded: messages nobody waits for are dropped oldest first.
            if inbox.len() >= INBOX_CAP {
                inbox.remove(0);
            }
            inbox.push(m.clone());
        });
        // Faults are kept in the inbox, in order with the other messages.
        while self.session.take_fault().is_some() {}
        if let Some(t) = self.session.telemetry() {
            if self.telemetry.as_ref() != Some(t) {
                self.telemetry = Some(t.clone());
            }
        }
    }
}

/// What a host does through its [`HostEnd`] on a simulated floor. The floor provides the
/// end, the clock, the wire and the stepping; the rest is provided.
pub trait HostSide: Sized {
    /// This host's end.
    fn end(&mut self) -> &mut HostEnd;
    /// Simulated time, µs.
    fn now_us(&self) -> u64;
    /// Bytes to the firmware, delivered at the current simulated time.
    fn write_host(&mut self, bytes: &[u8]);
    /// Advance the simulation by `dt_us`, feeding every host's heartbeat on the way.
    fn step(&mut self, dt_us: u64);
    /// Route what the firmware sent to this end (and to any other end on the floor).
    fn pump(&mut self);

    /// Send the handshake and wait for the firmware's answer.
    fn handshake(&mut self) -> Result<ferrobot_protocol::DeviceInfo, SimError> {
        self.send(&HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH,
        });
        let m = self.wait_msg(200_000, |m| matches!(m, DeviceMsg::Hello(_)))?;
        match m {
            DeviceMsg::Hello(info) => Ok(info),
            _ => Err(SimError::Timeout("hello")),
        }
    }

    /// Send raw bytes to the firmware (garbage, corrupted frames).
    fn send_raw(&mut self, bytes: &[u8]) {
        self.write_host(bytes);
    }

    /// Send any message without waiting for its answer (which arrives in the inbox); returns
    /// its sequence number.
    fn send(&mut self, msg: &HostMsg) -> u16 {
        let mut buf = [0u8; MAX_WIRE];
        let now = self.now_us();
        match self.end().session.send_unrouted(msg, now, &mut buf) {
            Ok((seq, n)) => {
                self.write_host(&buf[..n]);
                seq
            }
            Err(_) => 0,
        }
    }

    /// Run the simulation for `dt_us`, collecting messages.
    fn run_for(&mut self, dt_us: u64) {
        self.step(dt_us);
        self.pump();
    }

    /// Run in 1 ms steps until `ready` has an answer (checked after each pump), or
    /// `timeout_us` of simulated time pass (a timeout naming `what`).
    fn run_until_ready<T>(
        &mut self,
        timeout_us: u64,
        what: &'static str,
        mut ready: impl FnMut(&mut HostEnd) -> Option<T>,
    ) -> Result<T, SimError> {
        let end = self.now_us() + timeout_us;
        loop {
            self.pump();
            if let Some(r) = ready(self.end()) {
                return Ok(r);
            }
            if self.now_us() >= end {
                return Err(SimError::Timeout(what));
            }
            self.step(1000);
        }
    }

    /// Run in 1 ms steps until a received message satisfies `pred` (it is removed from the
    /// inbox and returned) or `timeout_us` of simulated time pass.
    fn wait_msg(
        &mut self,
        timeout_us: u64,
        pred: impl Fn(&DeviceMsg) -> bool,
    ) -> Result<DeviceMsg, SimError> {
        self.run_until_ready(timeout_us, "a message", |e| {
            let i = e.inbox.iter().position(&pred)?;
            Some(e.inbox.remove(i))
        })
    }

    /// Encode with `encode` (a command or a request), send it and wait (1 ms steps, at most
    /// `timeout_us`) for its answer, routed by the session.
    fn exchange(
        &mut self,
        timeout_us: u64,
        encode: impl FnOnce(&mut HostSession, u64, &mut [u8]) -> Result<(u16, usize), SessionError>,
    ) -> Result<Answer, SimError> {
        let mut buf = [0u8; MAX_WIRE];
        let now = self.now_us();
        let (seq, n) = encode(&mut self.end().session, now, &mut buf)
            .map_err(|_| SimError::Rejected(RejectReason::Unsupported))?;
        self.write_host(&buf[..n]);
        let r = self.run_until_ready(timeout_us, "a message", |e| e.session.take_answer(seq));
        if r.is_err() {
            self.end().session.forget(seq);
        }
        match r? {
            Answer::Rejected(reason) => Err(SimError::Rejected(reason)),
            a => Ok(a),
        }
    }

    /// Send a command and wait for its acknowledgement (routed by the session).
    fn command(&mut self, msg: &HostMsg) -> Result<(), SimError> {
        self.exchange(100_000, |s, now, out| s.command(msg, now, out))
            .map(|_| ())
    }

    /// Send a typed request and wait for its reply (routed by the session).
    fn request<R: Request>(&mut self, r: &R) -> Result<R::Reply, SimError> {
        let a = self.exchange(200_000, |s, now, out| s.request(r, now, out))?;
        R::reply(a).ok_or(SimError::Timeout("a reply of the right kind"))
    }

    /// Run in 1 ms steps until the newest telemetry satisfies `pred`, or time out.
    fn wait_telemetry(
        &mut self,
        timeout_us: u64,
        pred: impl Fn(&Telemetry) -> bool,
    ) -> Result<Telemetry, SimError> {
        self.run_until_ready(timeout_us, "telemetry", |e| {
            e.telemetry.as_ref().filter(|t| pred(t)).cloned()
        })
    }

    /// Take every fault received so far.
    fn take_faults(&mut self) -> Vec<ferrobot_protocol::Fault> {
        self.pump();
        let mut out = Vec::new();
        self.end().inbox.retain(|m| match m {
            DeviceMsg::Fault(x) => {
                out.push(*x);
                false
            }
            _ => true,
        });
        out
    }
}

/// A host side borrowed is a host side.
impl<T: HostSide> HostSide for &mut T {
    fn end(&mut self) -> &mut HostEnd {
        (**self).end()
    }

    fn now_us(&self) -> u64 {
        (**self).now_us()
    }

    fn write_host(&mut self, bytes: &[u8]) {
        (**self).write_host(bytes);
    }

    fn step(&mut self, dt_us: u64) {
        (**self).step(dt_us);
    }

    fn pump(&mut self) {
        (**self).pump();
    }
}

/// A host talking frames to a robot alone on its [`LockstepSim`] ([`HostSide`]); its
/// [`HostEnd`]'s fields are reached through it (`host.session`, `host.inbox`).
pub struct SimHost {
    /// The simulator.
    pub sim: LockstepSim,
    end: HostEnd,
}

impl std::ops::Deref for SimHost {
    type Target = HostEnd;
    fn deref(&self) -> &HostEnd {
        &self.end
    }
}

impl std::ops::DerefMut for SimHost {
    fn deref_mut(&mut self) -> &mut HostEnd {
        &mut self.end
    }
}

impl SimHost {
    /// Start `robot` with `seed` and perform the handshake.
    pub fn start(robot: &str, seed: u64) -> Result<Self, SimError> {
        let mut s = Self::new(LockstepSim::new(robot, seed)?);
        s.handshake()?;
        Ok(s)
    }

    /// Wrap a simulator without a handshake.
    pub fn new(sim: LockstepSim) -> Self {
        Self {
            sim,
            end: HostEnd::default(),
        }
    }
}

impl HostSide for SimHost {
    fn end(&mut self) -> &mut HostEnd {
        &mut self.end
    }

    fn now_us(&self) -> u64 {
        self.sim.now_us()
    }

    fn write_host(&mut self, bytes: &[u8]) {
        self.sim.write_host(bytes);
    }

    fn step(&mut self, dt_us: u64) {
        let end = self.sim.now_us() + dt_us;
        while self.sim.now_us() < end {
            if let Some(b) = self.end.heartbeat(self.sim.now_us()) {
                self.sim.write_host(&b);
            }
            let chunk = if self.end.keepalive {
                KEEPALIVE_US.min(end - self.sim.now_us())
            } else {
                end - self.sim.now_us()
            };
            self.sim.run_for(chunk);
        }
    }

    fn pump(&mut self) {
        let bytes = self.sim.take_host_output();
        self.end.absorb(&bytes);
    }
}
