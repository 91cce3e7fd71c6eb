//! The serial backend: the firmware behind a serial port. One I/O thread owns the port: it
//! writes queued frames, decodes incoming ones (telemetry into the latest state, replies and
//! faults into queues), sends heartbeats when the API is quiet, and when the port fails it
//! reports the link lost and reopens it, handshaking again, until it comes back.
//!
//! The link's clock is the firmware's: [`Link::now`] is the time of the newest telemetry and
//! [`Link::wait`] waits for the firmware's clock to move on. A real board's clock runs with
//! the wall clock; an emulated board's runs as fast as the machine emulating it can manage,
//! and the API's timings (motion deadlines, control periods) follow it either way. A firmware
//! that sends no telemetry for [`TELEMETRY_SILENCE`] is reported lost.

use std::collections::{HashSet, VecDeque};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use ferrobot_protocol::{
    encode_frame, DeviceInfo, DeviceMsg, Fault, Frame, FrameDecoder, HostMsg, Telemetry, MAX_WIRE,
    PROTOCOL_VERSION, SCHEMA_HASH,
};

use super::{rejection, Link};
use crate::error::{Error, Result};

/// How long a command waits for its acknowledgement.
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(1);
/// Heartbeat period when the API sends nothing.
pub const HEARTBEAT: Duration = Duration::from_millis(100);
/// Wall time without telemetry after which an accepted firmware counts as lost (the firmware
/// sends it every few tens of milliseconds of its own time).
pub const TELEMETRY_SILENCE: Duration = Duration::from_secs(2);

#[derive(Default)]
struct State {
    telemetry: Option<Telemetry>,
    /// When the newest telemetry arrived (wall time).
    telemetry_at: Option<Instant>,
    replies: VecDeque<Frame<DeviceMsg>>,
    faults: Vec<Fault>,
    lost: Option<String>,
    info: Option<DeviceInfo>,
    next_seq: u16,
    quit: bool,
}

struct Shared {
    state: Mutex<State>,
    cv: Condvar,
}

/// The serial backend.
pub struct SerialLink {
    shared: Arc<Shared>,
    tx: Sender<(u16, HostMsg)>,
    info: DeviceInfo,
    path: PathBuf,
    thread: Option<thread::JoinHandle<()>>,
}

fn open(path: &Path) -> std::io::Result<Box<dyn serialport::SerialPort>> {
    serialport::new(path.to_string_lossy(), 1_000_000)
        .timeout(Duration::from_millis(2))
        .open()
        .map_err(|e| std::io::Error::other(e.to_string()))
}

fn frame_bytes(seq: u16, msg: &HostMsg) -> Vec<u8> {
    let mut buf = [0u8; MAX_WIRE];
    encode_frame(seq, msg, &mut buf)
        .map(|n| buf[..n].to_vec())
        .unwrap_or_default()
}

fn io_thread(path: PathBuf, shared: Arc<Shared>, rx: Receiver<(u16, HostMsg)>) {
    let mut port: Option<Box<dyn serialport::SerialPort>> = None;
    let mut decoder = FrameDecoder::new();
    let mut last_tx = Instant::now();
    let mut heartbeats: HashSet<u16> = HashSet::new();
    let mut buf = [0u8; 512];
    let mut next_retry = Instant::now();
    loop {
        if shared.state.lock().map(|s| s.quit).unwrap_or(true) {
            return;
        }
        // (Re)open.
        if port.is_none() {
            if Instant::now() < next_retry {
                thread::sleep(Duration::from_millis(10));
                continue;
            }
            next_retry = Instant::now() + Duration::from_millis(250);
            match open(&path) {
                Ok(p) => {
                    port = Some(p);
                    decoder = FrameDecoder::new();
                    let seq = next_seq(&shared);
                    let hello = HostMsg::Hello {
                        protocol_version: PROTOCOL_VERSION,
                        schema_hash: SCHEMA_HASH,
                    };
                    if let Some(p) = port.as_mut() {
                        let _ = p.write_all(&frame_bytes(seq, &hello));
                    }
                    last_tx = Instant::now();
                }
                Err(_) => continue,
            }
        }
        let Some(p) = port.as_mut() else { continue };
        // Outgoing.
        let mut failed = None;
        while let Ok((seq, msg)) = rx.try_recv() {
            if let Err(e) = p.write_all(&frame_bytes(seq, &msg)) {
                failed = Some(e.to_string());
                break;
            }
            last_tx = Instant::now();
        }
        if failed.is_none() && last_tx.elapsed() >= HEARTBEAT {
            let seq = next_seq(&shared);
            heartbeats.insert(seq);
            if let Err(e) = p.write_all(&frame_bytes(seq, &HostMsg::Heartbeat)) {
                failed = Some(e.to_string());
            }
            last_tx = Instant::now();
        }
        // Incoming.
        if failed.is_none() {
            match p.read(&mut buf) {
                Ok(0) => {}
                Ok(n) => {
                    let mut frames = Vec::new();
                    decoder.feed(&buf[..n], |r: Result<Frame<DeviceMsg>, _>| {
                        if let Ok(f) = r {
                            frames.push(f)
                        }
                    });
                    if !frames.is_empty() {
                        if let Ok(mut s) = shared.state.lock() {
                            for f in frames {
                                match f.msg {
                                    DeviceMsg::Telemetry(t) => {
                                        s.telemetry = Some(t);
                                        s.telemetry_at = Some(Instant::now());
                                    }
                                    DeviceMsg::Fault(x) => s.faults.push(x),
                                    DeviceMsg::Ack { seq } if heartbeats.remove(&seq) => {}
                                    DeviceMsg::Hello(info) => {
                                        if info.accepted {
                                            s.lost = None;
                                        }
                                        // Faults sent before this answer belong to an earlier
                                        // session (left in the port's buffer while nobody read).
                                        s.faults.clear();
                                        s.info = Some(info.clone());
                                        s.replies.push_back(Frame {
                                            seq: f.seq,
                                            msg: DeviceMsg::Hello(info),
                                        });
                                    }
                                    other => s.replies.push_back(Frame {
                                        seq: f.seq,
                                        msg: other,
                                    }),
                                }
                            }
                            while s.replies.len() > 256 {
                                s.replies.pop_front();
                            }
                        }
                        shared.cv.notify_all();
                    }
                }
                Err(e)
                    if e.kind() == std::io::ErrorKind::TimedOut
                        || e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => failed = Some(e.to_string()),
            }
        }
        if failed.is_none() {
            let silent = shared.state.lock().is_ok_and(|s| {
                s.info.as_ref().is_some_and(|i| i.accepted)
                    && s.telemetry_at
                        .is_some_and(|t| t.elapsed() > TELEMETRY_SILENCE)
            });
            if silent {
                failed = Some(format!(
                    "no telemetry from the firmware for {TELEMETRY_SILENCE:?}: its control loop \
                     has stopped (for an emulated board: its plants and clock are no longer served)"
                ));
            }
        }
        if let Some(why) = failed {
            port = None;
            heartbeats.clear();
            if let Ok(mut s) = shared.state.lock() {
                s.lost = Some(why);
                s.telemetry_at = None;
                s.info = None;
            }
            shared.cv.notify_all();
        }
    }
}

fn next_seq(shared: &Shared) -> u16 {
    shared
        .state
        .lock()
        .map(|mut s| {
            let q = s.next_seq;
            s.next_seq = s.next_seq.wrapping_add(1);
            q
        })
        .unwrap_or(0)
}

impl SerialLink {
    /// Open `path`, start the I/O thread and handshake (within `timeout`).
    pub fn open(path: impl Into<PathBuf>, timeout: Duration) -> Result<Self> {
        let path = path.into();
        // Fail early and clearly when the port cannot be opened at all.
        drop(open(&path).map_err(|e| Error::Link(format!("cannot open {}: {e}", path.display())))?);
        let shared = Arc::new(Shared {
            state: Mutex::new(State::default()),
            cv: Condvar::new(),
        });
        let (tx, rx) = channel();
        let thread = {
            let shared = shared.clone();
            let path = path.clone();
            thread::spawn(move || io_thread(path, shared, rx))
        };
        let mut link = SerialLink {
            shared,
            tx,
            info: placeholder_info(),
            path,
            thread: Some(thread),
        };
        // Wait for the firmware's answer to the thread's Hello; say Hello again now and then
        // (a firmware in QEMU drops what it sends before the port is open).
        let deadline = Instant::now() + timeout;
        let mut next_hello = Instant::now() + Duration::from_millis(300);
        loop {
            let info = link.shared.state.lock().ok().and_then(|s| s.info.clone());
            if let Some(info) = info {
                if !info.accepted {
                    return Err(Error::VersionMismatch {
                        host: PROTOCOL_VERSION,
                        host_schema: SCHEMA_HASH,
                        firmware: info.protocol_version,
                        firmware_schema: info.schema_hash,
                    });
                }
                link.info = info;
                break;
            }
            if Instant::now() >= deadline {
                return Err(Error::Link(format!(
                    "nothing answered the handshake on {} within {timeout:?}: is the firmware \
                     running behind that port?",
                    link.path.display()
                )));
            }
            if Instant::now() >= next_hello {
                next_hello += Duration::from_millis(300);
                link.send(HostMsg::Hello {
                    protocol_version: PROTOCOL_VERSION,
                    schema_hash: SCHEMA_HASH,
                });
            }
            thread::sleep(Duration::from_millis(5));
        }
        // Hand the robot over once the firmware has configured its servos: within `timeout`
        // of the firmware's own time, which runs as long as telemetry comes.
        let first = link
            .wait_for(timeout, "telemetry", |s| {
                if let Some(why) = &s.lost {
                    return Some(Err(Error::Link(format!("{why} (reconnecting)"))));
                }
                s.telemetry.clone().map(Ok)
            })
            .map_err(|e| match e {
                Error::Timeout { after, .. } => Error::Link(format!(
                    "the firmware on {} answered the handshake but sent no telemetry within \
                     {after:?}: its control loop is not running (for an emulated board: are \
                     its plants and clock served?)",
                    link.path.display()
                )),
                e => e,
            })?;
        let deadline = Duration::from_micros(first.time_us) + timeout;
        loop {
            let t = link.telemetry()?;
            if t.faults & ferrobot_protocol::fault_flags::CONFIGURING == 0 {
                break;
            }
            if Duration::from_micros(t.time_us) >= deadline {
                return Err(Error::Timeout {
                    what: "servo configuration".into(),
                    after: timeout,
                });
            }
            link.wait(Duration::from_millis(10));
        }
        Ok(link)
    }

    fn send(&mut self, msg: HostMsg) -> u16 {
        let seq = next_seq(&self.shared);
        let _ = self.tx.send((seq, msg));
        seq
    }

    fn lost(&self) -> Option<String> {
        self.shared.state.lock().ok().and_then(|s| s.lost.clone())
    }

    /// Wait on the I/O thread's state until `ready` has an answer, or time out after
    /// `timeout` naming `what`.
    fn wait_for<T>(
        &self,
        timeout: Duration,
        what: &str,
        mut ready: impl FnMut(&mut State) -> Option<Result<T>>,
    ) -> Result<T> {
        // A timeout too long to represent waits for as long as it takes.
        let deadline = Instant::now().checked_add(timeout);
        let mut s = self
            .shared
            .state
            .lock()
            .map_err(|_| Error::Link("I/O thread panicked".into()))?;
        loop {
            if let Some(r) = ready(&mut s) {
                return r;
            }
            let left = match deadline {
                Some(d) => d.saturating_duration_since(Instant::now()),
                None => Duration::from_secs(3600),
            };
            if left.is_zero() {
                return Err(Error::Timeout {
                    what: what.to_string(),
                    after: timeout,
                });
            }
            s = self
                .shared
                .cv
                .wait_timeout(s, left)
                .map_err(|_| Error::Link("I/O thread panicked".into()))?
                .0;
        }
    }

    fn wait_reply(
        &mut self,
        pred: &dyn Fn(&Frame<DeviceMsg>) -> bool,
        timeout: Duration,
        what: &str,
    ) -> Result<DeviceMsg> {
        self.wait_for(timeout, what, |s| {
            if let Some(i) = s.replies.iter().position(pred) {
                return Some(
                    s.replies
                        .remove(i)
                        .map(|f| f.msg)
                        .ok_or_else(|| Error::Link("reply vanished".into())),
                );
            }
            s.lost
                .as_ref()
                .map(|why| Err(Error::Link(format!("{why} (reconnecting)"))))
        })
    }
}

fn placeholder_info() -> DeviceInfo {
    DeviceInfo {
        protocol_version: 0,
        schema_hash: 0,
        firmware_version: [0; 3],
        board: Default::default(),
        robot: Default::default(),
        joints: Default::default(),
        base: ferrobot_protocol::BaseKind::None,
        loop_period_us: 0,
        accepted: false,
    }
}

impl Drop for SerialLink {
    fn drop(&mut self) {
        if let Ok(mut s) = self.shared.state.lock() {
            s.quit = true;
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Link for SerialLink {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }

    fn command(&mut self, msg: &HostMsg, what: &str) -> Result<()> {
        if let Some(why) = self.lost() {
            return Err(Error::Link(format!("{why} (reconnecting)")));
        }
        let seq = self.send(msg.clone());
        let reply = self.wait_reply(
            &|f| matches!(f.msg, DeviceMsg::Ack { seq: s } | DeviceMsg::Reject { seq: s, .. } if s == seq),
            REPLY_TIMEOUT,
            what,
        )?;
        match reply {
            DeviceMsg::Reject { reason, .. } => Err(rejection(what, reason)),
            _ => Ok(()),
        }
    }

    fn request(&mut self, msg: &HostMsg, accept: &dyn Fn(&DeviceMsg) -> bool) -> Result<DeviceMsg> {
        self.send(msg.clone());
        self.wait_reply(&|f| accept(&f.msg), REPLY_TIMEOUT, "request")
    }

    fn telemetry(&mut self) -> Result<Telemetry> {
        self.wait_for(REPLY_TIMEOUT, "telemetry", |s| {
            if let Some(why) = &s.lost {
                return Some(Err(Error::Link(format!("{why} (reconnecting)"))));
            }
            s.telemetry.clone().map(Ok)
        })
    }

    fn wait(&mut self, dt: Duration) {
        // Until the firmware's clock has moved `dt` on, or the link is lost (the I/O thread
        // declares it lost after TELEMETRY_SILENCE without telemetry). The cap only guards
        // against a firmware whose clock crawls at under 1 % of the wall clock.
        let target = self.now() + dt;
        let cap = dt.saturating_mul(100).saturating_add(TELEMETRY_SILENCE);
        let _ = self.wait_for(cap, "the firmware's clock", |s| {
            let reached = s
                .telemetry
                .as_ref()
                .is_some_and(|t| Duration::from_micros(t.time_us) >= target);
            (reached || s.lost.is_some()).then_some(Ok(()))
        });
    }

    fn now(&self) -> Duration {
        self.shared
            .state
            .lock()
            .ok()
            .and_then(|s| {
                s.telemetry
                    .as_ref()
                    .map(|t| Duration::from_micros(t.time_us))
            })
            .unwrap_or_default()
    }

    fn take_faults(&mut self) -> Vec<Fault> {
        self.shared
            .state
            .lock()
            .map(|mut s| std::mem::take(&mut s.faults))
            .unwrap_or_default()
    }

    fn simulator(&mut self) -> Option<&mut ferrobot_sim::LockstepSim> {
        None
    }
}

/// A writer half for tests: raw bytes straight to a port (garbage, corrupted frames).
pub fn write_raw(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut p = open(path)?;
    p.write_all(bytes)?;
    Ok(())
}
