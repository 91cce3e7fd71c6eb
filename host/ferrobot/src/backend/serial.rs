//! The serial backend: the firmware behind a serial port. One I/O thread owns the port: it
//! writes queued frames, decodes incoming ones (telemetry into the latest state, replies and
//! faults into queues), sends heartbeats when the API is quiet, and when the port fails it
//! reports the link lost and reopens it, handshaking again, until it comes back.
//!
//! The link's clock is the firmware's: [`Link::now`] is the time of the newest telemetry and
//! [`Link::wait`] waits for the firmware's clock to move on. A real board's clock runs with
//! the wall clock; an emulated board's runs as fast as the machine emulating it can manage,
//! and the API's timings (motion deadlines, control periods) follow it either way. A firmware
//! that sends no telemetry for [`TELEMETRY_SILENCE`] is reported lost. The link's timeouts
//! count the wall clock, or an emulated board's clock when its emulator is at hand
//! ([`Timebase`], [`SerialLink::open_on`]), so that a busy machine slows it without losing it.

use std::collections::VecDeque;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use ferrobot_protocol::session::{
    Answer, GetDiagnostics, GetJoint, Handshake, HostSession, Request, SessionError,
};
use ferrobot_protocol::{
    DeviceInfo, Diagnostics, Fault, HostMsg, JointConfig, Telemetry, MAX_WIRE, PROTOCOL_VERSION,
    SCHEMA_HASH,
};

use super::timebase::{Mark, Timebase};
use super::{acked, replied, Link, LinkEvent, StopLine};
use crate::error::{Error, Result};

/// How long a command waits for its acknowledgement.
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(1);
/// Heartbeat period when the API sends nothing.
pub const HEARTBEAT: Duration = Duration::from_millis(100);
/// Time without telemetry after which an accepted firmware counts as lost (the firmware sends
/// it every few tens of milliseconds of its own time), counted on the link's [`Timebase`].
pub const TELEMETRY_SILENCE: Duration = Duration::from_secs(2);

/// How often a lost port is opened again.
pub const REOPEN_RETRY: Duration = Duration::from_millis(250);
/// How often a Hello is said again until the firmware answers it (a firmware in QEMU drops
/// what it sends before the port is open; a Hello can be lost on a line that just came back).
pub const HELLO_RETRY: Duration = Duration::from_millis(300);
/// Link events kept for [`Link::take_events`]; older ones are dropped first.
pub const EVENT_QUEUE: usize = 64;

struct State {
    /// The protocol's host session: sequence numbers, handshake, answers, telemetry, faults.
    session: HostSession,
    /// When the newest telemetry arrived.
    telemetry_at: Option<Mark>,
    /// Why the link is down, while it is.
    lost: Option<String>,
    /// When it went down.
    lost_at: Option<Instant>,
    /// The firmware of the first handshake: a reconnection must find the same one.
    first: Option<DeviceInfo>,
    /// Lost and back, for [`Link::take_events`].
    events: VecDeque<LinkEvent>,
    quit: bool,
}

impl State {
    fn push_event(&mut self, e: LinkEvent) {
        if self.events.len() >= EVENT_QUEUE {
            self.events.pop_front();
        }
        self.events.push_back(e);
    }

    /// The link went down (`why`): a new session will have to be made.
    fn lose(&mut self, why: String) {
        if self.lost.is_none() {
            self.push_event(LinkEvent::Lost { why: why.clone() });
            self.lost_at = Some(Instant::now());
        }
        self.lost = Some(why);
        self.telemetry_at = None;
        self.session.restart();
    }

    /// Bytes from the firmware.
    fn on_bytes(&mut self, bytes: &[u8], time: &Timebase) {
        let before = self.session.telemetry().map(|t| t.time_us);
        self.session.on_bytes(bytes);
        if self.session.telemetry().map(|t| t.time_us) != before {
            self.telemetry_at = Some(time.mark());
        }
        if self.lost.is_some() {
            self.reconnected(time);
        }
    }

    /// While the link is down: once the firmware has answered the new handshake, the link is
    /// back if it is the same firmware (robot, joints, base, board) and accepts us.
    fn reconnected(&mut self, time: &Timebase) {
        let info = match self.session.handshake() {
            Handshake::Accepted(info) => info.clone(),
            Handshake::Refused(info) => {
                self.lost = Some(format!(
                    "the firmware now behind the port refuses this host's protocol (version \
                     {}, schema {:#010x}; ours {PROTOCOL_VERSION}, {SCHEMA_HASH:#010x})",
                    info.protocol_version, info.schema_hash
                ));
                return;
            }
            Handshake::Waiting => return,
        };
        if let Some(first) = &self.first {
            let same = |a: &DeviceInfo, b: &DeviceInfo| {
                (&a.robot, &a.board, &a.joints, a.base) == (&b.robot, &b.board, &b.joints, b.base)
            };
            if !same(first, &info) {
                self.lost = Some(format!(
                    "another firmware answers behind the port: robot {} on board {} (was {} on \
                     {})",
                    info.robot.as_str(),
                    info.board.as_str(),
                    first.robot.as_str(),
                    first.board.as_str()
                ));
                return;
            }
        }
        self.lost = None;
        // The silence is counted from the handshake, so that a firmware that answers it but
        // sends no telemetry is lost again rather than trusted.
        self.telemetry_at = Some(time.mark());
        let down_for = self.lost_at.take().map(|t| t.elapsed()).unwrap_or_default();
        self.push_event(LinkEvent::Reconnected {
            down_for,
            watchdog_stopped: info.watchdog_tripped,
        });
    }
}

struct Shared {
    state: Mutex<State>,
    cv: Condvar,
    /// The link's wall clock, the session's time base.
    start: Instant,
    /// What the link's timeouts count.
    time: Timebase,
}

impl Shared {
    fn now_us(&self) -> u64 {
        self.start.elapsed().as_micros() as u64
    }

    fn lock(&self) -> Result<std::sync::MutexGuard<'_, State>> {
        self.state
            .lock()
            .map_err(|_| Error::Link("I/O thread panicked".into()))
    }

    /// The state, locked, while the link is up; the reason it is lost otherwise.
    fn connected(&self) -> Result<std::sync::MutexGuard<'_, State>> {
        let s = self.lock()?;
        match &s.lost {
            Some(why) => Err(Error::Link(format!("{why} (reconnecting)"))),
            None => Ok(s),
        }
    }
}

/// Read what the port holds into the session: until a read comes back short (the buffer was
/// empty then) or times out. At most 64 reads (32 KiB), so that a firmware that never stops
/// sending cannot hold the turn.
fn read_pending(
    p: &mut dyn serialport::SerialPort,
    shared: &Shared,
) -> std::result::Result<(), String> {
    let mut buf = [0u8; 512];
    for _ in 0..64 {
        match p.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => {
                if let Ok(mut s) = shared.state.lock() {
                    s.on_bytes(&buf[..n], &shared.time);
                }
                shared.cv.notify_all();
                if n < buf.len() {
                    return Ok(());
                }
            }
            Err(e)
                if e.kind() == std::io::ErrorKind::TimedOut
                    || e.kind() == std::io::ErrorKind::WouldBlock =>
            {
                return Ok(())
            }
            Err(e) => return Err(e.to_string()),
        }
    }
    Ok(())
}

/// The serial backend.
pub struct SerialLink {
    shared: Arc<Shared>,
    tx: Sender<Vec<u8>>,
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

/// The I/O thread: owns the port, moves bytes between it and the session, and when the port
/// fails reports the link lost and opens it again until a new session is made.
fn io_thread(path: PathBuf, shared: Arc<Shared>, rx: Receiver<Vec<u8>>) {
    let mut port: Option<Box<dyn serialport::SerialPort>> = None;
    let mut next_open = Instant::now();
    let mut next_hello = Instant::now();
    loop {
        if shared.state.lock().map(|s| s.quit).unwrap_or(true) {
            return;
        }
        let Some(p) = port.as_mut() else {
            if Instant::now() < next_open {
                thread::sleep(Duration::from_millis(10));
                continue;
            }
            next_open = Instant::now() + REOPEN_RETRY;
            if let Ok(p) = open(&path) {
                // A Hello first, on a new port.
                next_hello = Instant::now();
                port = Some(p);
            }
            continue;
        };
        if let Err(why) = turn(p.as_mut(), &shared, &rx, &mut next_hello) {
            port = None;
            if let Ok(mut s) = shared.state.lock() {
                s.lose(why);
            }
            // Frames the API encoded for the lost session are not sent to the next one: their
            // callers have their error (nothing new is encoded while the link is lost).
            while rx.try_recv().is_ok() {}
            shared.cv.notify_all();
        }
    }
}

/// One turn of the I/O thread on an open port: a Hello while the handshake waits, the API's
/// frames, a heartbeat when it has been quiet, what the firmware sent, and the firmware's
/// silence. `Err` with the reason when the link is lost.
fn turn(
    p: &mut dyn serialport::SerialPort,
    shared: &Shared,
    rx: &Receiver<Vec<u8>>,
    next_hello: &mut Instant,
) -> std::result::Result<(), String> {
    let mut frame = [0u8; MAX_WIRE + 1];
    let hello = shared.state.lock().ok().and_then(|mut s| {
        let due =
            matches!(s.session.handshake(), Handshake::Waiting) && Instant::now() >= *next_hello;
        if !due {
            return None;
        }
        *next_hello = Instant::now() + HELLO_RETRY;
        // After a leading delimiter (frame[0] stays 0), which ends whatever partial frame the
        // firmware's decoder holds from before, so that the Hello is read whole.
        s.session.hello(shared.now_us(), &mut frame[1..]).ok()
    });
    if let Some(n) = hello {
        p.write_all(&frame[..=n]).map_err(|e| e.to_string())?;
    }
    while let Ok(bytes) = rx.try_recv() {
        p.write_all(&bytes).map_err(|e| e.to_string())?;
    }
    let beat = shared.state.lock().ok().and_then(|mut s| {
        s.session
            .heartbeat_due(shared.now_us(), HEARTBEAT.as_micros() as u64, &mut frame)
    });
    if let Some(n) = beat {
        p.write_all(&frame[..n]).map_err(|e| e.to_string())?;
    }
    // The firmware's silence is judged at the clock's reading taken before the port is
    // drained: everything the firmware sent before that reading is in the port's buffer by
    // then and is read below, however long this thread was kept from running. Judged after the
    // reads instead, a thread starved between its read and the judgement would count the
    // board's time it missed as silence.
    let before = shared.time.mark();
    read_pending(p, shared)?;
    let silent = shared.state.lock().is_ok_and(|s| {
        matches!(s.session.handshake(), Handshake::Accepted(_))
            && s.telemetry_at
                .is_some_and(|t| shared.time.passed_by(&t, &before, TELEMETRY_SILENCE))
    });
    if silent {
        return Err(format!(
            "no telemetry from the firmware for {TELEMETRY_SILENCE:?}{}: its control loop has \
             stopped (for an emulated board: its plants and clock are no longer served)",
            shared.time.of()
        ));
    }
    Ok(())
}

impl SerialLink {
    /// Open `path`, start the I/O thread and handshake (within `timeout`); timeouts count the
    /// wall clock.
    pub fn open(path: impl Into<PathBuf>, timeout: Duration) -> Result<Self> {
        Self::open_on(path, timeout, Timebase::wall())
    }

    /// [`SerialLink::open`] with the link's timeouts (`timeout` among them) counted on `time`:
    /// an emulated board's clock when its emulator runs in this process.
    pub fn open_on(path: impl Into<PathBuf>, timeout: Duration, time: Timebase) -> Result<Self> {
        let path = path.into();
        // Fail early and clearly when the port cannot be opened at all.
        drop(open(&path).map_err(|e| Error::Link(format!("cannot open {}: {e}", path.display())))?);
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                session: HostSession::new(),
                telemetry_at: None,
                lost: None,
                lost_at: None,
                first: None,
                events: VecDeque::new(),
                quit: false,
            }),
            cv: Condvar::new(),
            start: Instant::now(),
            time,
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
            info: super::placeholder_info(),
            path,
            thread: Some(thread),
        };
        link.info = link.handshake(timeout)?;
        link.configured(timeout)?;
        Ok(link)
    }

    /// The firmware's answer to the Hello the I/O thread says (again every HELLO_RETRY) until
    /// it answers, within `timeout`.
    fn handshake(&self, timeout: Duration) -> Result<DeviceInfo> {
        self.wait_for(timeout, "handshake", |s| match s.session.handshake() {
            Handshake::Refused(info) => Some(Err(Error::VersionMismatch {
                host: PROTOCOL_VERSION,
                host_schema: SCHEMA_HASH,
                firmware: info.protocol_version,
                firmware_schema: info.schema_hash,
            })),
            Handshake::Accepted(info) => {
                let info = info.clone();
                s.first = Some(info.clone());
                // What happened before the link was handed over is not the program's.
                s.events.clear();
                Some(Ok(info))
            }
            Handshake::Waiting => None,
        })
        .map_err(|e| match e {
            Error::Timeout { .. } => Error::Link(format!(
                "nothing answered the handshake on {} within {timeout:?}: is the firmware \
                     running behind that port?",
                self.path.display()
            )),
            e => e,
        })
    }

    /// Wait until the firmware has configured its servos, within `timeout` of its own time
    /// (which runs as long as telemetry comes): then the robot is handed over.
    fn configured(&mut self, timeout: Duration) -> Result<()> {
        let link = self;
        let first = link
            .wait_for(timeout, "telemetry", |s| {
                if let Some(why) = &s.lost {
                    return Some(Err(Error::Link(format!("{why} (reconnecting)"))));
                }
                s.session.telemetry().cloned().map(Ok)
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
        Ok(())
    }

    /// Encode with `encode` (a command or a request) under the session's lock and hand the
    /// frame to the I/O thread; wait for the answer to its sequence number.
    fn exchange(
        &mut self,
        what: &str,
        encode: impl FnOnce(
            &mut HostSession,
            u64,
            &mut [u8],
        ) -> std::result::Result<(u16, usize), SessionError>,
    ) -> Result<Answer> {
        let mut frame = [0u8; MAX_WIRE];
        let seq = {
            let mut s = self.shared.connected()?;
            let (seq, n) = encode(&mut s.session, self.shared.now_us(), &mut frame)
                .map_err(|e| Error::Link(format!("{what}: {e:?}")))?;
            // Sent under the lock, so frames leave in the order of their sequence numbers.
            let _ = self.tx.send(frame[..n].to_vec());
            seq
        };
        let r = self.wait_for(REPLY_TIMEOUT, what, |s| {
            if let Some(a) = s.session.take_answer(seq) {
                return Some(Ok(a));
            }
            s.lost
                .as_ref()
                .map(|why| Err(Error::Link(format!("{why} (reconnecting)"))))
        });
        if r.is_err() {
            if let Ok(mut s) = self.shared.state.lock() {
                s.session.forget(seq);
            }
        }
        r
    }

    /// A typed request and its reply.
    fn request<R: Request>(&mut self, r: &R, what: &str) -> Result<R::Reply> {
        let a = self.exchange(what, |s, now, out| s.request(r, now, out))?;
        replied::<R>(what, a)
    }

    /// Wait on the I/O thread's state until `ready` has an answer, or time out after
    /// `timeout` naming `what`.
    fn wait_for<T>(
        &self,
        timeout: Duration,
        what: &str,
        mut ready: impl FnMut(&mut State) -> Option<Result<T>>,
    ) -> Result<T> {
        // Counted on the link's timebase; a timeout too long to represent on the wall clock
        // waits for as long as it takes.
        let time = &self.shared.time;
        let endless = Instant::now().checked_add(timeout).is_none();
        let mark = time.mark();
        let mut s = self
            .shared
            .state
            .lock()
            .map_err(|_| Error::Link("I/O thread panicked".into()))?;
        loop {
            if let Some(r) = ready(&mut s) {
                return r;
            }
            if !endless && time.passed(&mark, timeout) {
                return Err(Error::Timeout {
                    what: what.to_string(),
                    after: timeout,
                });
            }
            let left = match endless {
                false => time.recheck(&mark, timeout).max(Duration::from_micros(100)),
                true => Duration::from_secs(3600),
            };
            s = self
                .shared
                .cv
                .wait_timeout(s, left)
                .map_err(|_| Error::Link("I/O thread panicked".into()))?
                .0;
        }
    }
}

/// The serial link's [`StopLine`]: the frame is encoded under the session's lock (so frames
/// leave in the order of their sequence numbers) and queued for the I/O thread, without the
/// robot's I/O lock.
struct SerialStopLine {
    shared: Arc<Shared>,
    tx: Sender<Vec<u8>>,
}

impl StopLine for SerialStopLine {
    fn emergency_stop(&self) -> Result<()> {
        let mut frame = [0u8; MAX_WIRE];
        let mut s = self.shared.connected()?;
        let n = s
            .session
            .command_quiet(&HostMsg::EmergencyStop, self.shared.now_us(), &mut frame)
            .map_err(|e| Error::Link(format!("emergency stop: {e:?}")))?;
        self.tx
            .send(frame[..n].to_vec())
            .map_err(|_| Error::Link("the I/O thread has ended".into()))
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
        let a = self.exchange(what, |s, now, out| s.command(msg, now, out))?;
        acked(what, a)
    }

    fn joint_config(&mut self, index: u8) -> Result<JointConfig> {
        self.request(&GetJoint(index), "joint configuration")
    }

    fn diagnostics(&mut self) -> Result<Diagnostics> {
        self.request(&GetDiagnostics, "diagnostics")
    }

    fn telemetry(&mut self) -> Result<Telemetry> {
        self.wait_for(REPLY_TIMEOUT, "telemetry", |s| {
            if let Some(why) = &s.lost {
                return Some(Err(Error::Link(format!("{why} (reconnecting)"))));
            }
            s.session.telemetry().cloned().map(Ok)
        })
    }

    fn take_telemetry(&mut self) -> Vec<Telemetry> {
        match self.shared.lock() {
            Ok(mut s) => std::iter::from_fn(|| s.session.take_report()).collect(),
            Err(_) => Vec::new(),
        }
    }

    fn stop_line(&self) -> Option<Arc<dyn StopLine>> {
        Some(Arc::new(SerialStopLine {
            shared: self.shared.clone(),
            tx: self.tx.clone(),
        }))
    }

    fn wait(&mut self, dt: Duration) {
        // Until the firmware's clock has moved `dt` on, or the link is lost (the I/O thread
        // declares it lost after TELEMETRY_SILENCE without telemetry). The cap only guards
        // against a firmware whose clock crawls at under 1 % of the wall clock.
        let target = self.now() + dt;
        let cap = dt.saturating_mul(100).saturating_add(TELEMETRY_SILENCE);
        let _ = self.wait_for(cap, "the firmware's clock", |s| {
            let reached = s
                .session
                .telemetry()
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
                s.session
                    .telemetry()
                    .map(|t| Duration::from_micros(t.time_us))
            })
            .unwrap_or_default()
    }

    fn take_faults(&mut self) -> Vec<Fault> {
        self.shared
            .state
            .lock()
            .map(|mut s| std::iter::from_fn(|| s.session.take_fault()).collect())
            .unwrap_or_default()
    }

    fn take_events(&mut self) -> Vec<LinkEvent> {
        self.shared
            .lock()
            .map(|mut s| s.events.drain(..).collect())
            .unwrap_or_default()
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

/// A writer half for tests: raw bytes straight to a port (garbage, corrupted frames).
pub fn write_raw(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut p = open(path)?;
    p.write_all(bytes)?;
    Ok(())
}
