//! The remote backend's server side: the served robot's link answers clients' calls, its
//! telemetry and faults are published, and a client that has commanded the robot and falls
//! silent for [`WATCHDOG`] has the robot stopped (the joints hold, the base stops), as the
//! firmware's own watchdog does for its host.
//!
//! Silence is counted on two clocks: the wall's and the served robot's. A client starved of
//! the processor while it alone lets a lockstep robot's time pass has not left the robot
//! unattended (its time stood still too), and is not stopped for it.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ferrobot::events::Event;
use ferrobot::subscription::Subscription;
use ferrobot::{Robot, Telemetry};
use ferrobot_protocol::HostMsg;
use parking_lot::Mutex;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::query::Query;
use zenoh::{Session, Wait};

use super::wire::{
    self, Answer, Call, Refusal, RemoteInfo, Reply, Request, HEARTBEAT, MAX_ADVANCE_US, WATCHDOG,
};
use crate::error::BridgeError;

/// A client, as the server knows it.
#[derive(Debug, Clone, Copy)]
struct Client {
    /// Its last heartbeat (or call).
    heard: Instant,
    /// The served robot's clock then, µs.
    heard_us: u64,
    /// Whether it has commanded the robot since it was last heard of.
    commanded: bool,
}

/// What the service has done.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RemoteStats {
    /// Calls answered.
    pub calls: u64,
    /// Calls that did not decode.
    pub bad_calls: u64,
    /// Times a silent client had the robot stopped.
    pub watchdog_stops: u64,
    /// Time let pass for clients of a robot served in lockstep, s.
    pub advanced: f64,
}

/// The remote backend's server side for one served robot.
pub struct RemoteService {
    robot: Robot,
    telemetry: Publisher<'static>,
    faults: Arc<Faults>,
    alive: Publisher<'static>,
    alive_at: Mutex<Option<Instant>>,
    /// The newest telemetry's time, µs: the served robot's clock as the watchdog reads it.
    robot_us: Arc<AtomicU64>,
    clients: Arc<Mutex<HashMap<u64, Client>>>,
    stats: Arc<Mutex<RemoteStats>>,
    stop: Arc<AtomicBool>,
    calls: Option<JoinHandle<()>>,
    _heartbeats: Subscriber<()>,
}

impl RemoteService {
    /// Serves `robot`'s link under `prefix` on `session`; `info` is what clients are told.
    pub fn start(
        robot: &Robot,
        session: &Session,
        prefix: &str,
        info: RemoteInfo,
    ) -> Result<RemoteService, BridgeError> {
        let z = |what: &str| {
            let what = what.to_string();
            move |e| BridgeError::zenoh(what.clone(), e)
        };
        let publisher = |key: String| {
            session
                .declare_publisher(key)
                .congestion_control(zenoh::qos::CongestionControl::Block)
                .wait()
                .map_err(z("declaring the remote backend's publishers"))
        };
        let telemetry = publisher(wire::telemetry_key(prefix))?;
        let faults = Arc::new(Faults::new(robot, publisher(wire::fault_key(prefix))?)?);
        let alive = publisher(wire::alive_key(prefix))?;
        let robot_us = Arc::new(AtomicU64::new((robot.time() * 1e6) as u64));
        let clients: Arc<Mutex<HashMap<u64, Client>>> = Arc::default();
        let (theirs, their_us) = (clients.clone(), robot_us.clone());
        let heartbeats = session
            .declare_subscriber(wire::heartbeat_key(prefix))
            .callback(move |s| {
                if let Ok(id) = wire::decode::<u64>(&s.payload().to_bytes()) {
                    heard(
                        &mut theirs.lock(),
                        id,
                        their_us.load(Ordering::SeqCst),
                        false,
                    );
                }
            })
            .wait()
            .map_err(z("subscribing to the clients' heartbeats"))?;
        let queryable = session
            .declare_queryable(wire::call_key(prefix))
            .complete(true)
            .wait()
            .map_err(z("declaring the remote backend's calls"))?;
        let stats: Arc<Mutex<RemoteStats>> = Arc::default();
        let stop = Arc::new(AtomicBool::new(false));
        let answerer = Answerer {
            robot: robot.clone(),
            faults: faults.clone(),
            info,
            clients: clients.clone(),
            robot_us: robot_us.clone(),
            stats: stats.clone(),
        };
        let their_stop = stop.clone();
        let calls = std::thread::Builder::new()
            .name("ferrobot-remote-calls".into())
            .spawn(move || {
                while !their_stop.load(Ordering::SeqCst) {
                    match queryable.recv_timeout(Duration::from_millis(100)) {
                        Ok(Some(q)) => answerer.answer(&q),
                        Ok(None) => {}
                        Err(_) => return,
                    }
                }
            })
            .map_err(|e| BridgeError::Usage(format!("starting the calls' thread: {e}")))?;
        Ok(RemoteService {
            robot: robot.clone(),
            telemetry,
            faults,
            alive,
            alive_at: Mutex::new(None),
            robot_us,
            clients,
            stats,
            stop,
            calls: Some(calls),
            _heartbeats: heartbeats,
        })
    }

    /// Publishes a telemetry report.
    pub fn telemetry(&self, t: &Telemetry) {
        self.robot_us.fetch_max(t.time_us, Ordering::SeqCst);
        let _ = self.telemetry.put(wire::encode(t)).wait();
    }

    /// Says the server is there, at most every [`HEARTBEAT`] however often it is called.
    pub fn alive(&self) {
        let mut at = self.alive_at.lock();
        if at.is_some_and(|a| a.elapsed() < HEARTBEAT) {
            return;
        }
        *at = Some(Instant::now());
        let us = self.robot_us.load(Ordering::SeqCst);
        let _ = self.alive.put(wire::encode(&us)).wait();
    }

    /// Publishes the faults the robot has reported since the last call.
    pub fn publish_faults(&self) {
        self.faults.publish();
    }

    /// Stops the robot if a client that commanded it has been silent for [`WATCHDOG`], on the
    /// wall clock and on the robot's; it is forgotten (it commands again when it is back).
    pub fn watchdog(&self) {
        let now_us = self.robot_us.load(Ordering::SeqCst);
        let period_us = WATCHDOG.as_micros() as u64;
        let silent: Vec<u64> = self
            .clients
            .lock()
            .iter()
            .filter(|(_, c)| {
                c.heard.elapsed() > WATCHDOG && now_us.saturating_sub(c.heard_us) > period_us
            })
            .map(|(id, c)| (*id, c.commanded))
            .filter(|(_, commanded)| *commanded)
            .map(|(id, _)| id)
            .collect();
        if silent.is_empty() {
            return;
        }
        self.clients.lock().retain(|id, _| !silent.contains(id));
        let joints = self.robot.config().joints.len().min(16);
        let mask = ((1u32 << joints) - 1) as u16;
        let _ = self
            .robot
            .send_command(&HostMsg::ClearQueue { joints: mask });
        if self.robot.config().base.is_some() {
            let _ = self.robot.send_command(&HostMsg::BaseVelocity {
                v: 0.0,
                w: 0.0,
                duration_ms: 0,
            });
        }
        self.stats.lock().watchdog_stops += 1;
    }

    /// What it has done.
    pub fn stats(&self) -> RemoteStats {
        *self.stats.lock()
    }
}

impl Drop for RemoteService {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.calls.take() {
            let _ = t.join();
        }
    }
}

/// Events the fault feed holds before its oldest give way: far more than a robot reports
/// between two turns of the serving loop.
const FAULT_FEED: usize = 1024;

/// The robot's faults on their way to the clients: its events, of which the faults are
/// published, by the serving loop as they come and by the calls' thread before it answers a
/// refused command. A refusal the firmware gave because of a fault it reported first (a
/// bumper pressed, then a drive forward refused as unsafe) then reaches a client after that
/// fault, as it reached the robot: zenoh delivers one session's messages in order, so the
/// client ends its motion with the fault, its cause, rather than with the refusal.
struct Faults {
    feed: Mutex<(Subscription<Event>, Publisher<'static>)>,
}

impl Faults {
    fn new(robot: &Robot, publisher: Publisher<'static>) -> Result<Self, BridgeError> {
        let events = robot
            .subscribe_events(FAULT_FEED)
            .map_err(|e| BridgeError::Usage(format!("the robot's events: {e}")))?;
        Ok(Faults {
            feed: Mutex::new((events, publisher)),
        })
    }

    fn publish(&self) {
        let feed = self.feed.lock();
        for e in feed.0.drain() {
            if let Event::Fault { fault, .. } = e {
                let _ = feed.1.put(wire::encode(&fault)).wait();
            }
        }
    }
}

/// Answers calls, on the calls' thread.
struct Answerer {
    robot: Robot,
    faults: Arc<Faults>,
    info: RemoteInfo,
    clients: Arc<Mutex<HashMap<u64, Client>>>,
    robot_us: Arc<AtomicU64>,
    stats: Arc<Mutex<RemoteStats>>,
}

/// Client `id` was heard from (and has commanded the robot, if `commands`) when the robot's
/// clock read `robot_us`.
fn heard(clients: &mut HashMap<u64, Client>, id: u64, robot_us: u64, commands: bool) {
    let e = clients.entry(id).or_insert(Client {
        heard: Instant::now(),
        heard_us: robot_us,
        commanded: false,
    });
    e.heard = Instant::now();
    e.heard_us = e.heard_us.max(robot_us);
    e.commanded |= commands;
}

impl Answerer {
    fn answer(&self, q: &Query) {
        let payload = q.payload().map(|p| p.to_bytes()).unwrap_or_default();
        let reply: Reply = match wire::decode::<Request>(&payload) {
            Ok(r) => {
                self.stats.lock().calls += 1;
                self.call(r)
            }
            Err(e) => {
                self.stats.lock().bad_calls += 1;
                Err(Refusal::Other(format!("a call that does not decode: {e}")))
            }
        };
        let _ = q.reply(q.key_expr().clone(), wire::encode(&reply)).wait();
    }

    fn call(&self, r: Request) -> Reply {
        let commands = matches!(r.call, Call::Command(_));
        let robot_us = self.robot_us.load(Ordering::SeqCst);
        heard(&mut self.clients.lock(), r.client, robot_us, commands);
        match r.call {
            Call::Bye => {
                self.clients.lock().remove(&r.client);
                Ok(Answer::Done { time_us: robot_us })
            }
            Call::Info => Ok(Answer::Info(self.info.clone())),
            Call::Command(msg) => self
                .robot
                .send_command(&msg)
                .map(|_| Answer::Done {
                    time_us: (self.robot.time() * 1e6) as u64,
                })
                .map_err(|e| {
                    // The faults before the refusal go out first (see `Faults`).
                    self.faults.publish();
                    Refusal::of(&e)
                }),
            Call::JointConfig(i) => self
                .robot
                .firmware_joint(i)
                .map(Answer::Joint)
                .map_err(|e| Refusal::of(&e)),
            Call::Diagnostics => self
                .robot
                .diagnostics()
                .map(Answer::Diagnostics)
                .map_err(|e| Refusal::of(&e)),
            Call::Advance { until_us } => self.advance(until_us),
        }
    }

    /// Lets the lockstep robot's time pass until `until_us` (at most [`MAX_ADVANCE_US`] on).
    fn advance(&self, until_us: u64) -> Reply {
        if !self.info.lockstep {
            return Err(Refusal::Other(
                "the served robot's time runs by itself: it is not served in lockstep".into(),
            ));
        }
        let now_us = (self.robot.time() * 1e6) as u64;
        let to_us = until_us.min(now_us.saturating_add(MAX_ADVANCE_US));
        if to_us > now_us {
            let dt = (to_us - now_us) as f64 * 1e-6;
            self.robot.wait(dt).map_err(|e| Refusal::of(&e))?;
            self.stats.lock().advanced += dt;
        }
        let telemetry = self.robot.telemetry().map_err(|e| Refusal::of(&e))?;
        Ok(Answer::Advanced {
            time_us: (self.robot.time() * 1e6) as u64,
            telemetry_us: telemetry.time_us,
        })
    }
}
