//! The remote backend's client side: [`RemoteLink`], a [`Link`] to a robot another process or
//! machine serves, through which a [`ferrobot::Robot`] runs exactly as on its own link (its
//! motions, goals and typed errors are the API's, computed here).
//!
//! The link's clock is the served firmware's (the newest telemetry's time). A served robot that
//! falls silent for [`TELEMETRY_SILENCE`] is reported lost ([`LinkEvent::Lost`]): calls fail
//! with [`ferrobot::Error::Link`], motions under way end with it, and when its telemetry
//! returns the link is back ([`LinkEvent::Reconnected`]). Meanwhile the server, not hearing this
//! client's heartbeat for [`WATCHDOG`], has stopped the robot if this client had commanded it.
//!
//! A robot served in lockstep ([`RemoteInfo::lockstep`]) has its time passed by the link's
//! waits ([`Call::Advance`]), the link's clock the served robot's; its server's `alive` beats,
//! not its telemetry, say that it is there.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ferrobot::backend::{Link, LinkEvent, StopLine};
use ferrobot::{Diagnostics, Fault, Telemetry};
use ferrobot_protocol::session::REPORTS;
use ferrobot_protocol::{DeviceInfo, FaultKind, HostMsg, JointConfig};
use parking_lot::{Condvar, Mutex};
use zenoh::pubsub::Subscriber;
use zenoh::{Session, Wait};

use super::wire::{self, Answer, Call, RemoteInfo, Request, CALL_TIMEOUT, HEARTBEAT, WATCHDOG};
use crate::error::BridgeError;

/// Time without telemetry after which the served robot counts as lost (it sends it every
/// 10 ms).
pub const TELEMETRY_SILENCE: Duration = Duration::from_secs(1);
/// Faults and link events kept until taken; older ones give way.
pub const QUEUE: usize = 64;

#[derive(Default)]
struct State {
    newest: Option<Telemetry>,
    reports: VecDeque<Telemetry>,
    faults: VecDeque<Fault>,
    events: VecDeque<LinkEvent>,
    heard: Option<Instant>,
    lost_at: Option<Instant>,
    /// The served robot's clock after the last [`Call::Advance`], µs (lockstep only).
    advanced_us: u64,
    commanded: bool,
    /// The served robot's clock when this client's last resume was acknowledged, µs: an
    /// emergency stop's fault from before it, arriving late (faults and replies travel apart),
    /// is not news.
    resumed_us: u64,
}

impl State {
    fn fault(&mut self, f: Fault) {
        let stale = f.kind == FaultKind::EmergencyStop && f.time_us <= self.resumed_us;
        if !stale {
            push(&mut self.faults, QUEUE, f);
        }
    }

    fn resumed(&mut self, time_us: u64) {
        self.resumed_us = self.resumed_us.max(time_us);
        let r = self.resumed_us;
        self.faults
            .retain(|f| !(f.kind == FaultKind::EmergencyStop && f.time_us <= r));
    }
}

fn push<T>(q: &mut VecDeque<T>, cap: usize, v: T) {
    if q.len() >= cap {
        q.pop_front();
    }
    q.push_back(v);
}

struct Shared {
    state: Mutex<State>,
    cv: Condvar,
    stop: AtomicBool,
    lockstep: bool,
}

impl Shared {
    fn telemetry(&self, t: Telemetry) {
        let mut s = self.state.lock();
        Self::heard(&mut s);
        push(&mut s.reports, REPORTS, t.clone());
        s.newest = Some(t);
        self.cv.notify_all();
    }

    /// The server's `alive` beat: what says a lockstep robot is there.
    fn alive(&self) {
        if self.lockstep {
            Self::heard(&mut self.state.lock());
            self.cv.notify_all();
        }
    }

    /// The served robot was heard from: back, if it had been lost.
    fn heard(s: &mut State) {
        if let Some(at) = s.lost_at.take() {
            let down_for = at.elapsed();
            let watchdog_stopped = s.commanded && down_for > WATCHDOG;
            push(
                &mut s.events,
                QUEUE,
                LinkEvent::Reconnected {
                    down_for,
                    watchdog_stopped,
                },
            );
        }
        s.heard = Some(Instant::now());
    }

    /// Declares the robot lost when it has been silent too long.
    fn check_silence(&self) {
        let mut s = self.state.lock();
        let silent = s.heard.is_some_and(|h| h.elapsed() > TELEMETRY_SILENCE);
        if silent && s.lost_at.is_none() {
            s.lost_at = Some(Instant::now());
            let why = format!("no telemetry from the served robot for {TELEMETRY_SILENCE:?}");
            push(&mut s.events, QUEUE, LinkEvent::Lost { why });
            self.cv.notify_all();
        }
    }

    fn lost(&self) -> Option<ferrobot::Error> {
        self.state
            .lock()
            .lost_at
            .map(|_| ferrobot::Error::Link("the served robot is silent (reconnecting)".into()))
    }
}

/// Calls the served robot: the session, the call's key and this client's id.
#[derive(Clone)]
struct Caller {
    session: Session,
    key: String,
    client: u64,
}

impl Caller {
    fn call(&self, call: Call, what: &str) -> ferrobot::Result<Answer> {
        let request = wire::encode(&Request {
            client: self.client,
            call,
        });
        let replies = self
            .session
            .get(&self.key)
            .payload(request)
            .timeout(CALL_TIMEOUT)
            .wait()
            .map_err(|e| ferrobot::Error::Link(format!("{what}: {e}")))?;
        let reply = replies.recv().map_err(|_| {
            ferrobot::Error::Link(format!("{what}: no answer from the served robot"))
        })?;
        let sample = reply
            .result()
            .map_err(|e| ferrobot::Error::Link(format!("{what}: {e:?}")))?;
        let bytes = sample.payload().to_bytes();
        let answer: wire::Reply = wire::decode(&bytes).map_err(|e| {
            ferrobot::Error::Link(format!("{what}: an answer that does not decode: {e}"))
        })?;
        answer.map_err(|r| r.to_error(what))
    }
}

/// A link to a served robot.
pub struct RemoteLink {
    caller: Caller,
    info: RemoteInfo,
    shared: Arc<Shared>,
    heartbeat: Option<JoinHandle<()>>,
    _subscribers: [Subscriber<()>; 3],
}

impl RemoteLink {
    /// Connects to the robot served under `prefix` on `session`: asks what it is (waiting up
    /// to `timeout` for it to answer), listens to its telemetry and faults, and starts the
    /// heartbeat.
    pub fn connect(
        session: &Session,
        prefix: &str,
        timeout: Duration,
    ) -> Result<RemoteLink, BridgeError> {
        let caller = Caller {
            session: session.clone(),
            key: wire::call_key(prefix),
            client: client_id(session),
        };
        let start = Instant::now();
        let info = loop {
            match caller.call(Call::Info, "connecting") {
                Ok(Answer::Info(info)) => break info,
                Ok(other) => {
                    return Err(BridgeError::Usage(format!(
                        "the served robot answered {other:?} to a connection"
                    )))
                }
                Err(e) if start.elapsed() > timeout => {
                    return Err(BridgeError::Usage(format!(
                        "no robot served under {prefix} answered within {timeout:?}: {e}"
                    )))
                }
                Err(_) => std::thread::sleep(Duration::from_millis(100)),
            }
        };
        let shared = Arc::new(Shared {
            state: Mutex::new(State::default()),
            cv: Condvar::new(),
            stop: AtomicBool::new(false),
            lockstep: info.lockstep,
        });
        let subscribers = subscribe(session, prefix, &shared)?;
        let heartbeat = heartbeat(session, prefix, caller.client, shared.clone())?;
        let mut link = RemoteLink {
            caller,
            info,
            shared,
            heartbeat: Some(heartbeat),
            _subscribers: subscribers,
        };
        // The clock starts with the first report (a lockstep robot's comes with its time).
        if link.info.lockstep {
            // Where its clock stands, then two of its 10 ms reports on.
            if let Ok(Answer::Advanced { time_us, .. }) = link
                .caller
                .call(Call::Advance { until_us: 0 }, "connecting")
            {
                link.shared.state.lock().advanced_us = time_us;
            }
            link.advance(Duration::from_millis(20));
        }
        let first = link.wait_until(timeout, |s| s.newest.is_some());
        if !first {
            return Err(BridgeError::Usage(format!(
                "the robot served under {prefix} sent no telemetry within {timeout:?}"
            )));
        }
        Ok(link)
    }

    /// What the server said the robot is.
    pub fn remote_info(&self) -> &RemoteInfo {
        &self.info
    }

    /// Lets a lockstep robot's time pass `dt` on: [`Call::Advance`] until its clock is there,
    /// each answer followed by the telemetry it names. A refused or lost call ends the wait
    /// (the silence shows as a lost link).
    fn advance(&mut self, dt: Duration) {
        if self.info.shared {
            // Other robots' clients pass this robot's time too: `dt` on from where the clock
            // stands now, not from the newest report here.
            if let Ok(Answer::Advanced { time_us, .. }) = self
                .caller
                .call(Call::Advance { until_us: 0 }, "reading the clock")
            {
                let mut s = self.shared.state.lock();
                s.advanced_us = s.advanced_us.max(time_us);
            }
        }
        let target = (self.now() + dt).as_micros() as u64;
        loop {
            if self.shared.lost().is_some() {
                return;
            }
            let call = Call::Advance { until_us: target };
            let Ok(Answer::Advanced {
                time_us,
                telemetry_us,
            }) = self.caller.call(call, "letting time pass")
            else {
                return;
            };
            {
                let mut s = self.shared.state.lock();
                s.advanced_us = s.advanced_us.max(time_us);
            }
            self.wait_until(CALL_TIMEOUT, |s| {
                s.lost_at.is_some() || s.newest.as_ref().is_some_and(|t| t.time_us >= telemetry_us)
            });
            if time_us >= target {
                return;
            }
        }
    }

    /// Waits up to `timeout` for `ready`; whether it became true.
    fn wait_until(&self, timeout: Duration, mut ready: impl FnMut(&State) -> bool) -> bool {
        let deadline = Instant::now() + timeout;
        let mut s = self.shared.state.lock();
        loop {
            if ready(&s) {
                return true;
            }
            if self.shared.cv.wait_until(&mut s, deadline).timed_out() {
                return ready(&s);
            }
        }
    }
}

/// A random id for this client.
fn client_id(session: &Session) -> u64 {
    use std::hash::BuildHasher;
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
        .as_nanos();
    std::collections::hash_map::RandomState::new().hash_one((
        session.zid().to_string(),
        nanos,
        std::process::id(),
    ))
}

fn subscribe(
    session: &Session,
    prefix: &str,
    shared: &Arc<Shared>,
) -> Result<[Subscriber<()>; 3], BridgeError> {
    let z = |e| BridgeError::zenoh("subscribing to the served robot", e);
    let mine = shared.clone();
    let telemetry = session
        .declare_subscriber(wire::telemetry_key(prefix))
        .callback(move |s| {
            if let Ok(t) = wire::decode::<Telemetry>(&s.payload().to_bytes()) {
                mine.telemetry(t);
            }
        })
        .wait()
        .map_err(z)?;
    let mine = shared.clone();
    let faults = session
        .declare_subscriber(wire::fault_key(prefix))
        .callback(move |s| {
            if let Ok(f) = wire::decode::<Fault>(&s.payload().to_bytes()) {
                mine.state.lock().fault(f);
            }
        })
        .wait()
        .map_err(z)?;
    let mine = shared.clone();
    let alive = session
        .declare_subscriber(wire::alive_key(prefix))
        .callback(move |_| mine.alive())
        .wait()
        .map_err(z)?;
    Ok([telemetry, faults, alive])
}

/// Puts this client's id every [`HEARTBEAT`] and watches the served robot's silence.
fn heartbeat(
    session: &Session,
    prefix: &str,
    client: u64,
    shared: Arc<Shared>,
) -> Result<JoinHandle<()>, BridgeError> {
    let publisher = session
        .declare_publisher(wire::heartbeat_key(prefix))
        .wait()
        .map_err(|e| BridgeError::zenoh("declaring the heartbeat", e))?;
    let id = wire::encode(&client);
    std::thread::Builder::new()
        .name("ferrobot-remote-heartbeat".into())
        .spawn(move || {
            while !shared.stop.load(Ordering::SeqCst) {
                let _ = publisher.put(id.clone()).wait();
                shared.check_silence();
                std::thread::sleep(HEARTBEAT);
            }
        })
        .map_err(|e| BridgeError::Usage(format!("starting the heartbeat: {e}")))
}

impl Drop for RemoteLink {
    /// Stops the heartbeat and says goodbye: a client that leaves has nothing stopped (what it
    /// set going ends as its commands do), one that vanishes has the robot stopped.
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.heartbeat.take() {
            let _ = t.join();
        }
        if self.shared.lost().is_none() {
            let _ = self.caller.call(Call::Bye, "leaving");
        }
    }
}

/// Sends the emergency stop through the served robot, beside whoever holds the link.
struct RemoteStopLine {
    caller: Caller,
}

impl StopLine for RemoteStopLine {
    fn emergency_stop(&self) -> ferrobot::Result<()> {
        self.caller
            .call(Call::Command(HostMsg::EmergencyStop), "emergency stop")
            .map(|_| ())
    }
}

impl Link for RemoteLink {
    fn info(&self) -> &DeviceInfo {
        &self.info.device
    }

    fn command(&mut self, msg: &HostMsg, what: &str) -> ferrobot::Result<()> {
        if let Some(e) = self.shared.lost() {
            return Err(e);
        }
        self.shared.state.lock().commanded = true;
        let answer = self.caller.call(Call::Command(msg.clone()), what)?;
        if let Answer::Done { time_us } = answer {
            let mut s = self.shared.state.lock();
            if let HostMsg::Resume = msg {
                s.resumed(time_us);
            }
            // In lockstep the acknowledgement's wait is time passed, as on a link of one's own.
            if self.info.lockstep {
                s.advanced_us = s.advanced_us.max(time_us);
            }
        }
        Ok(())
    }

    fn joint_config(&mut self, index: u8) -> ferrobot::Result<JointConfig> {
        match self
            .caller
            .call(Call::JointConfig(index), "joint configuration")?
        {
            Answer::Joint(j) => Ok(j),
            other => Err(ferrobot::Error::Link(format!(
                "joint {index}: answered {other:?}"
            ))),
        }
    }

    fn diagnostics(&mut self) -> ferrobot::Result<Diagnostics> {
        match self.caller.call(Call::Diagnostics, "diagnostics")? {
            Answer::Diagnostics(d) => Ok(d),
            other => Err(ferrobot::Error::Link(format!(
                "diagnostics: answered {other:?}"
            ))),
        }
    }

    fn telemetry(&mut self) -> ferrobot::Result<Telemetry> {
        if let Some(e) = self.shared.lost() {
            return Err(e);
        }
        self.shared
            .state
            .lock()
            .newest
            .clone()
            .ok_or_else(|| ferrobot::Error::Link("no telemetry yet".into()))
    }

    fn take_telemetry(&mut self) -> Vec<Telemetry> {
        self.shared.state.lock().reports.drain(..).collect()
    }

    fn wait(&mut self, dt: Duration) {
        if self.info.lockstep {
            return self.advance(dt);
        }
        // Until the served firmware's clock has moved `dt` on, or the robot is lost.
        let target = self.now() + dt;
        let cap = dt.saturating_mul(100).saturating_add(TELEMETRY_SILENCE);
        self.wait_until(cap, |s| {
            s.lost_at.is_some()
                || s.newest
                    .as_ref()
                    .is_some_and(|t| Duration::from_micros(t.time_us) >= target)
        });
    }

    fn now(&self) -> Duration {
        let s = self.shared.state.lock();
        let telemetry = s.newest.as_ref().map_or(0, |t| t.time_us);
        Duration::from_micros(telemetry.max(s.advanced_us))
    }

    fn take_faults(&mut self) -> Vec<Fault> {
        self.shared.state.lock().faults.drain(..).collect()
    }

    fn take_events(&mut self) -> Vec<LinkEvent> {
        self.shared.state.lock().events.drain(..).collect()
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }

    /// A base command lasts the server's watchdog period and a margin: a client starved or
    /// delayed on the network keeps the base's motion smooth, and one that is gone has it
    /// stopped by the server within [`WATCHDOG`].
    fn command_horizon(&self) -> Duration {
        WATCHDOG + Duration::from_millis(100)
    }

    fn stop_line(&self) -> Option<Arc<dyn StopLine>> {
        Some(Arc::new(RemoteStopLine {
            caller: self.caller.clone(),
        }))
    }
}
