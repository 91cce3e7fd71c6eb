//! The remote backend's server side: the served robot's link answers clients' calls, its
//! telemetry and faults are published, and a client that has commanded the robot and falls
//! silent for [`WATCHDOG`] has the robot stopped (the joints hold, the base stops), as the
//! firmware's own watchdog does for its host.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ferrobot::{Fault, Robot, Telemetry};
use ferrobot_protocol::HostMsg;
use parking_lot::Mutex;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::query::Query;
use zenoh::{Session, Wait};

use super::wire::{self, Answer, Call, Refusal, RemoteInfo, Reply, Request, WATCHDOG};
use crate::error::BridgeError;

/// A client, as the server knows it.
#[derive(Debug, Clone, Copy)]
struct Client {
    /// Its last heartbeat (or call).
    heard: Instant,
    /// Whether it has commanded the robot since it was last heard of.
    commanded: bool,
}

/// What the service has done.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RemoteStats {
    /// Calls answered.
    pub calls: u64,
    /// Calls that did not decode.
    pub bad_calls: u64,
    /// Times a silent client had the robot stopped.
    pub watchdog_stops: u64,
}

/// The remote backend's server side for one served robot.
pub struct RemoteService {
    robot: Robot,
    telemetry: Publisher<'static>,
    faults: Publisher<'static>,
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
        let faults = publisher(wire::fault_key(prefix))?;
        let clients: Arc<Mutex<HashMap<u64, Client>>> = Arc::default();
        let theirs = clients.clone();
        let heartbeats = session
            .declare_subscriber(wire::heartbeat_key(prefix))
            .callback(move |s| {
                if let Ok(id) = wire::decode::<u64>(&s.payload().to_bytes()) {
                    let mut c = theirs.lock();
                    let e = c.entry(id).or_insert(Client {
                        heard: Instant::now(),
                        commanded: false,
                    });
                    e.heard = Instant::now();
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
            info,
            clients: clients.clone(),
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
            clients,
            stats,
            stop,
            calls: Some(calls),
            _heartbeats: heartbeats,
        })
    }

    /// Publishes a telemetry report.
    pub fn telemetry(&self, t: &Telemetry) {
        let _ = self.telemetry.put(wire::encode(t)).wait();
    }

    /// Publishes a fault.
    pub fn fault(&self, f: &Fault) {
        let _ = self.faults.put(wire::encode(f)).wait();
    }

    /// Stops the robot if a client that commanded it has been silent for [`WATCHDOG`]; it is
    /// forgotten (it commands again when it is back).
    pub fn watchdog(&self) {
        let silent: Vec<u64> = self
            .clients
            .lock()
            .iter()
            .filter(|(_, c)| c.heard.elapsed() > WATCHDOG)
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

/// Answers calls, on the calls' thread.
struct Answerer {
    robot: Robot,
    info: RemoteInfo,
    clients: Arc<Mutex<HashMap<u64, Client>>>,
    stats: Arc<Mutex<RemoteStats>>,
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
        {
            let mut c = self.clients.lock();
            let e = c.entry(r.client).or_insert(Client {
                heard: Instant::now(),
                commanded: false,
            });
            e.heard = Instant::now();
            e.commanded |= commands;
        }
        match r.call {
            Call::Info => Ok(Answer::Info(self.info.clone())),
            Call::Command(msg) => self
                .robot
                .send_command(&msg)
                .map(|_| Answer::Done {
                    time_us: (self.robot.time() * 1e6) as u64,
                })
                .map_err(|e| Refusal::of(&e)),
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
        }
    }
}
