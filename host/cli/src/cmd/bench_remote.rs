//! `ferrobot bench remote`: what driving a robot over zenoh costs. Simulated LoCoBots (paced at
//! real time) are served on loopback, and in one run, for --seconds each:
//!
//! - in-process: --clients threads call the served robot's own API;
//! - remote, one robot: --clients programs (each its own zenoh session, as on another machine)
//!   drive it through the remote backend;
//! - remote, two robots in two worlds: the same clients, half on each robot, each robot
//!   simulated alone;
//! - remote, two robots in one world: the same, both robots in one shared world on one clock
//!   ([`ferrobot::SharedWorld`]).
//!
//! Commands: the round trip of an acknowledged command (a heartbeat: sent, checked by the
//! firmware, acknowledged) through the API, p50 and p99, and how many all clients get through
//! per second. Joint states: each report's latency, from the instant the step of the robot's
//! clock that produced it returned (its clock passes in 1 ms steps) to a reader having it (a
//! subscription in-process; the remote backend's telemetry, on a zenoh session of the
//! reader's own), p50 and p99, and the reports each reader gets per second (the firmware
//! sends 100).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ferrobot::events::HostMsg;
use ferrobot::{Backend, Robot, Telemetry};
use ferrobot_bridge::remote::wire;
use ferrobot_bridge::zenoh::{self, Wait};
use ferrobot_bridge::{access, remote, Access, ServeOptions, Server};
use parking_lot::Mutex;
use serde::Serialize;

use super::common::print_json;

/// `ferrobot bench remote`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Seconds of each setup.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Programs (threads in-process) driving the robots at once.
    #[arg(long, default_value_t = 4)]
    pub clients: usize,
    /// One JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// One setup's figures.
#[derive(Serialize, Default, Clone)]
struct Row {
    setup: String,
    robots: usize,
    clients: usize,
    command_p50_ms: f64,
    command_p99_ms: f64,
    commands_per_s: f64,
    joint_state_latency_p50_ms: f64,
    joint_state_latency_p99_ms: f64,
    joint_states_per_s_per_reader: f64,
}

/// A served robot: the robot, its server and session, the thread that lets its time pass.
struct Served {
    robot: Robot,
    namespace: String,
    endpoint: String,
    steps: Steps,
    stop: Arc<AtomicBool>,
    clock: Option<std::thread::JoinHandle<()>>,
    _server: Server,
    _session: zenoh::Session,
}

impl Drop for Served {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(c) = self.clock.take() {
            let _ = c.join();
        }
    }
}

/// When each step of the robot's clock began: (its time then, µs; the wall instant), the
/// newest [`STEPS`].
type Steps = Arc<Mutex<std::collections::VecDeque<(u64, Instant)>>>;
const STEPS: usize = 100_000;

/// Lets `robot`'s time pass in 1 ms steps until `stop`, noting when each step began.
fn clock(robot: Robot, steps: Steps, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        while !stop.load(Ordering::SeqCst) {
            let t = (robot.time() * 1e6).round() as u64;
            {
                let mut s = steps.lock();
                if s.len() >= STEPS {
                    s.pop_front();
                }
                s.push_back((t, Instant::now()));
            }
            if robot.wait(0.001).is_err() {
                return;
            }
        }
    })
}

/// A report of time `time_us`, read now: ms since the step of the robot's clock that produced
/// it began (the last that began before its time), or `None` before any such step was noted.
fn latency_ms(steps: &Steps, time_us: u64) -> Option<f64> {
    let now = Instant::now();
    let s = steps.lock();
    let i = s.partition_point(|(t, _)| *t < time_us);
    let (_, at) = s.get(i.checked_sub(1)?)?;
    Some(now.saturating_duration_since(*at).as_secs_f64() * 1e3)
}

/// A LoCoBot paced at real time, without its camera, alone or in `world` at `pose`.
fn locobot(
    world: Option<(&ferrobot::SharedWorld, [f64; 3])>,
    seed: u64,
) -> ferrobot::Result<Robot> {
    let mut b = Robot::builder("locobot")
        .backend(Backend::Sim {
            seed,
            realtime: true,
        })
        .use_camera(false);
    if let Some((w, pose)) = world {
        b = b.shared_world(w).start_pose(pose);
    }
    b.build()
}

/// A LoCoBot alone in its world, served under `namespace`, its clock passed by a thread.
fn serve(namespace: &str) -> ferrobot::Result<Served> {
    serve_robot(locobot(None, 1)?, namespace, None)
}

/// Two LoCoBots in one world, served under `/robot1` and `/robot2`; the first one's clock
/// thread passes the world's time (and notes its steps for both).
fn serve_shared() -> ferrobot::Result<[Served; 2]> {
    let world = ferrobot::SharedWorld::new("empty")?;
    let a = locobot(Some((&world, [0.0, 0.0, 0.0])), 1)?;
    let b = locobot(Some((&world, [1.5, 0.0, std::f64::consts::PI])), 2)?;
    let a = serve_robot(a, "/robot1", None)?;
    let b = serve_robot(b, "/robot2", Some(a.steps.clone()))?;
    Ok([a, b])
}

/// `robot` served under `namespace`; its clock passed by a thread of its own noting the steps,
/// or, given `steps`, by another robot's in the same world.
fn serve_robot(robot: Robot, namespace: &str, steps: Option<Steps>) -> ferrobot::Result<Served> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())?
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let session = access::open(&Access::listen(&endpoint))?;
    let opts = ServeOptions {
        namespace: namespace.into(),
        camera: false,
        ..ServeOptions::default()
    };
    let server = Server::start(&robot, &session, opts)?;
    let stop = Arc::new(AtomicBool::new(false));
    let (steps, clock) = match steps {
        Some(s) => (s, None),
        None => {
            let s: Steps = Arc::default();
            let c = clock(robot.clone(), s.clone(), stop.clone());
            (s, Some(c))
        }
    };
    Ok(Served {
        robot,
        namespace: namespace.into(),
        endpoint,
        steps,
        stop,
        clock,
        _server: server,
        _session: session,
    })
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

/// Sends heartbeats through `api` until `stop`; their round trips, ms.
fn commands(api: &Robot, stop: &AtomicBool) -> Vec<f64> {
    let mut rtt = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let t = Instant::now();
        if api.send_command(&HostMsg::Heartbeat).is_ok() {
            rtt.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    rtt
}

type Ages = Arc<Mutex<Vec<f64>>>;

/// Reads `served`'s telemetry as the remote backend receives it (a zenoh session of its own)
/// until the session is dropped: each report's age, ms.
fn remote_reader(served: &Served, ages: Ages) -> ferrobot::Result<zenoh::Session> {
    let session = access::open(&Access::connect(&served.endpoint))?;
    let steps = served.steps.clone();
    session
        .declare_subscriber(wire::telemetry_key(&wire::prefix(&served.namespace)))
        .callback(move |s| {
            if let Ok(t) = wire::decode::<Telemetry>(&s.payload().to_bytes()) {
                if let Some(a) = latency_ms(&steps, t.time_us) {
                    ages.lock().push(a);
                }
            }
        })
        .background()
        .wait()
        .map_err(|e| ferrobot::Error::Link(e.to_string()))?;
    Ok(session)
}

/// Reads `served`'s telemetry through its own API (a subscription) until `stop`: each report's
/// latency, ms.
fn local_reader(served: &Served, stop: &AtomicBool) -> ferrobot::Result<Vec<f64>> {
    let sub = served.robot.subscribe_telemetry(1000)?;
    let bell = ferrobot::Bell::new();
    sub.ring(bell.clone());
    let mut ages = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        bell.wait(Duration::from_millis(50));
        for t in sub.drain() {
            ages.extend(latency_ms(&served.steps, t.time_us));
        }
    }
    Ok(ages)
}

/// The row of `setup`: first the readers alone for `seconds` (`readers` returns every age
/// read and how many readers read), then `clients` command loops (client `k` on
/// `apis[k % apis.len()]`) for `seconds`. Apart, because the simulator acknowledges a command
/// in its own time: commands move its clock on, and the readers would see it run ahead.
fn measure(
    setup: &str,
    robots: usize,
    apis: &[Robot],
    clients: usize,
    seconds: f64,
    readers: impl FnOnce(&AtomicBool) -> ferrobot::Result<(Vec<f64>, usize)>,
) -> ferrobot::Result<Row> {
    let stop = AtomicBool::new(false);
    let reads = std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(Duration::from_secs_f64(seconds));
            stop.store(true, Ordering::SeqCst);
        });
        readers(&stop)
    });
    let (mut ages, readers) = reads?;
    let stop = AtomicBool::new(false);
    let mut rtts: Vec<f64> = std::thread::scope(|s| {
        let loops: Vec<_> = (0..clients)
            .map(|k| {
                let (api, stop) = (&apis[k % apis.len()], &stop);
                s.spawn(move || commands(api, stop))
            })
            .collect();
        std::thread::sleep(Duration::from_secs_f64(seconds));
        stop.store(true, Ordering::SeqCst);
        loops
            .into_iter()
            .flat_map(|l| l.join().unwrap_or_default())
            .collect()
    });
    Ok(Row {
        setup: setup.into(),
        robots,
        clients,
        commands_per_s: rtts.len() as f64 / seconds,
        command_p50_ms: percentile(&mut rtts, 0.5),
        command_p99_ms: percentile(&mut rtts, 0.99),
        joint_states_per_s_per_reader: ages.len() as f64 / seconds / readers.max(1) as f64,
        joint_state_latency_p50_ms: percentile(&mut ages, 0.5),
        joint_state_latency_p99_ms: percentile(&mut ages, 0.99),
    })
}

fn remote_setup(served: &[Served], clients: usize, seconds: f64) -> ferrobot::Result<Row> {
    let apis: Vec<Robot> = (0..clients)
        .map(|k| {
            let s = &served[k % served.len()];
            let b = remote::connect(
                "locobot",
                &Access::connect(&s.endpoint),
                &s.namespace,
                Duration::from_secs(10),
            )?;
            b.use_camera(false).build()
        })
        .collect::<ferrobot::Result<_>>()?;
    let setup = match served.len() {
        1 => "remote, one robot",
        _ => "remote, two robots",
    };
    // Each client's session reads its robot's telemetry.
    let ages: Ages = Arc::default();
    let sessions = (0..clients)
        .map(|k| remote_reader(&served[k % served.len()], ages.clone()))
        .collect::<ferrobot::Result<Vec<_>>>()?;
    ages.lock().clear();
    let row = measure(setup, served.len(), &apis, clients, seconds, |stop| {
        while !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok((std::mem::take(&mut *ages.lock()), clients))
    });
    drop(sessions);
    row
}

/// Runs the three setups.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let seconds = ferrobot::validate::seconds("seconds", a.seconds)?.as_secs_f64();
    if !(1..=16).contains(&a.clients) {
        return Err(ferrobot::Error::Usage(format!(
            "--clients {}: between 1 and 16",
            a.clients
        )));
    }
    let one = serve("/robot1")?;
    let remote_one = remote_setup(std::slice::from_ref(&one), a.clients, seconds)?;
    let two = [one, serve("/robot2")?];
    let mut remote_two = remote_setup(&two, a.clients, seconds)?;
    remote_two.setup = "remote, two robots in two worlds".into();
    // Last: its commands, acknowledged in the simulator's own time, run its clock ahead.
    let served = &two[0];
    let local = [served.robot.clone()];
    let in_process = measure("in-process", 1, &local, a.clients, seconds, |stop| {
        let ages = std::thread::scope(|s| {
            let readers: Vec<_> = (0..a.clients)
                .map(|_| s.spawn(|| local_reader(served, stop)))
                .collect();
            readers
                .into_iter()
                .map(|r| r.join().unwrap_or_else(|_| Ok(Vec::new())))
                .collect::<ferrobot::Result<Vec<_>>>()
        })?;
        Ok((ages.concat(), a.clients))
    })?;
    drop(two);
    // Alone on the machine: the two robots of one world.
    let shared = serve_shared()?;
    let mut remote_shared = remote_setup(&shared, a.clients, seconds)?;
    remote_shared.setup = "remote, two robots in one world".into();
    drop(shared);
    let rows = [in_process, remote_one, remote_two, remote_shared];
    if a.json {
        print_json(&rows);
        return Ok(());
    }
    say!("Simulated LoCoBots paced at real time, served on zenoh over loopback; {seconds:.0} s per setup; commands are acknowledged heartbeats through the API, joint states the firmware's 100 Hz telemetry");
    say!("| setup | robots | clients | command p50 ms | command p99 ms | commands/s (all clients) | joint state latency p50 ms | p99 ms | joint states/s per reader |");
    say!("|---|---|---|---|---|---|---|---|---|");
    for r in &rows {
        say!(
            "| {} | {} | {} | {:.3} | {:.3} | {:.0} | {:.2} | {:.2} | {:.1} |",
            r.setup,
            r.robots,
            r.clients,
            r.command_p50_ms,
            r.command_p99_ms,
            r.commands_per_s,
            r.joint_state_latency_p50_ms,
            r.joint_state_latency_p99_ms,
            r.joint_states_per_s_per_reader
        );
    }
    Ok(())
}
