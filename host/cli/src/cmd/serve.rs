//! `ferrobot serve`: a robot on zenoh, as a ROS 2 node sees one and for the remote backend
//! ([`ferrobot_bridge`]).

use std::io::Read;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use ferrobot_bridge::{access, Access, BridgeError, Credentials, ServeOptions, Server};
use serde::Serialize;

use super::common::BackendArgs;

/// `ferrobot serve`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Endpoints to listen on (`tcp/<host>:<port>`). Beyond loopback, --credentials is needed.
    #[arg(long, default_value = "tcp/127.0.0.1:7447")]
    pub listen: Vec<String>,
    /// Endpoints to connect to, e.g. an rmw_zenoh router's `tcp/localhost:7447`.
    #[arg(long)]
    pub connect: Vec<String>,
    /// A file whose first line is `user:password`: every session must present it.
    #[arg(long)]
    pub credentials: Option<std::path::PathBuf>,
    /// The robot's ROS 2 namespace (`/` for none).
    #[arg(long, default_value = "/")]
    pub namespace: String,
    /// The ROS domain (`ROS_DOMAIN_ID`).
    #[arg(long, default_value_t = 0)]
    pub domain: u32,
    /// The world, on the simulator: a bundled scene or a scene file.
    #[arg(long, default_value = "empty")]
    pub scene: String,
    /// Leave the camera's topics out.
    #[arg(long)]
    pub no_camera: bool,
    /// Also serve a live view for Foxglove and Lichtblick (their Foxglove WebSocket
    /// connection) on this address, e.g. 127.0.0.1:8765.
    #[arg(long)]
    pub view: Option<String>,
    /// On the simulator: its time passes only while a remote client waits (virtual time, as
    /// in-process: what a client does is the same beside a busy core), not paced to the wall
    /// clock. ROS 2 peers see time pass only while a client drives the robot.
    #[arg(long)]
    pub lockstep: bool,
    /// On the simulator: where the robot starts, X Y THETA (m, m, rad) in the world
    /// (default: the scene's start pose).
    #[arg(long, num_args = 3, allow_negative_numbers = true, value_names = ["X", "Y", "THETA"])]
    pub start_pose: Option<Vec<f64>>,
    /// On the simulator: serve another robot in the same world, on one clock, under its own
    /// namespace: NAMESPACE=ROBOT@X,Y,THETA (m, m, rad), e.g. `/b=locobot@1.5,0,3.14`. Repeat
    /// for more; each needs a namespace of its own.
    #[arg(
        long,
        value_name = "NAMESPACE=ROBOT@X,Y,THETA",
        allow_hyphen_values = true
    )]
    pub also: Vec<String>,
    /// Where it runs (the in-process simulator by default, paced at real time).
    #[command(flatten)]
    pub backend: BackendArgs,
}

/// Another robot to serve in the same world (`--also`).
#[derive(Debug, Clone, PartialEq)]
struct Also {
    namespace: String,
    robot: String,
    pose: [f64; 3],
}

/// `NAMESPACE=ROBOT@X,Y,THETA`.
fn parse_also(s: &str) -> ferrobot::Result<Also> {
    let bad = |why: &str| {
        ferrobot::Error::Usage(format!(
            "--also {s:?}: {why} (NAMESPACE=ROBOT@X,Y,THETA, e.g. /b=locobot@1.5,0,3.14)"
        ))
    };
    let (namespace, rest) = s.split_once('=').ok_or_else(|| bad("no '='"))?;
    let (robot, pose) = rest.rsplit_once('@').ok_or_else(|| bad("no '@'"))?;
    let v: Vec<f64> = pose
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad("the pose is not three numbers"))?;
    let pose: [f64; 3] = v
        .try_into()
        .map_err(|_| bad("the pose is not three numbers"))?;
    if robot.is_empty() {
        return Err(bad("no robot"));
    }
    Ok(Also {
        namespace: namespace.to_string(),
        robot: robot.to_string(),
        pose,
    })
}

/// The robots to serve: the first (`ROBOT`, `--namespace`, `--start-pose`) and the others
/// (`--also`), each under a namespace of its own; in one shared world when there are others.
fn robots(
    a: &Args,
    backend: &ferrobot::Backend,
) -> ferrobot::Result<Vec<(String, ferrobot::Robot)>> {
    let others = a
        .also
        .iter()
        .map(|s| parse_also(s))
        .collect::<ferrobot::Result<Vec<_>>>()?;
    let mut seen = std::collections::BTreeSet::from([a.namespace.clone()]);
    for o in &others {
        if !seen.insert(o.namespace.clone()) {
            return Err(ferrobot::Error::Usage(format!(
                "namespace {:?} is served twice: each robot needs its own",
                o.namespace
            )));
        }
    }
    if !others.is_empty() && !matches!(backend, ferrobot::Backend::Sim { .. }) {
        return Err(ferrobot::Error::Usage(
            "--also serves robots in one simulated world: it takes the simulator backend".into(),
        ));
    }
    let start = a.start_pose.as_ref().map(|p| [p[0], p[1], p[2]]);
    let mut b = super::common::robot_builder(&a.robot).backend(backend.clone());
    if let Some(p) = start {
        b = b.start_pose(p);
    }
    if others.is_empty() {
        return Ok(vec![(a.namespace.clone(), b.scene(&a.scene).build()?)]);
    }
    let world = ferrobot::SharedWorld::new(&a.scene)?;
    let mut out = vec![(a.namespace.clone(), b.shared_world(&world).build()?)];
    for (k, o) in others.into_iter().enumerate() {
        let mut backend = backend.clone();
        if let ferrobot::Backend::Sim { seed, .. } = &mut backend {
            // Each robot's plants their own noise.
            *seed = seed.wrapping_add(k as u64 + 1);
        }
        let bot = super::common::robot_builder(&o.robot)
            .backend(backend)
            .shared_world(&world)
            .start_pose(o.pose)
            .build()?;
        out.push((o.namespace, bot));
    }
    Ok(out)
}

/// The line `ferrobot serve` prints once it serves.
#[derive(Serialize)]
struct Serving<'a> {
    robot: &'a str,
    listen: &'a [String],
    connect: &'a [String],
    namespace: &'a str,
    /// The other robots' namespaces (`--also`).
    also: &'a [&'a str],
    domain: u32,
    authenticated: bool,
    lockstep: bool,
    view: Option<&'a str>,
}

fn bridge(e: BridgeError) -> ferrobot::Error {
    e.into()
}

/// The live view of `robot` on `addr`.
fn view(
    robot: &ferrobot::Robot,
    addr: &str,
    camera: bool,
) -> ferrobot::Result<ferrobot_view::ViewServer> {
    let opts = ferrobot_view::ViewOptions {
        camera,
        ..Default::default()
    };
    let v = ferrobot_view::ViewServer::start(robot, addr, opts).map_err(|e| match e {
        ferrobot_view::ViewError::Robot(e) => e,
        e => ferrobot::Error::Usage(e.to_string()),
    })?;
    eprintln!(
        "live view on ws://{} (Foxglove or Lichtblick: open a Foxglove WebSocket connection)",
        v.addr()
    );
    Ok(v)
}

/// The backend to serve: the simulator paced at real time, or in lockstep with its clients.
fn backend(a: &Args) -> ferrobot::Result<ferrobot::Backend> {
    let mut backend = a.backend.backend()?;
    match &mut backend {
        ferrobot::Backend::Sim { realtime, .. } => *realtime = !a.lockstep,
        _ if a.lockstep => {
            return Err(ferrobot::Error::Usage(
                "--lockstep serves the simulator: another backend's time runs by itself".into(),
            ))
        }
        _ => {}
    }
    Ok(backend)
}

/// Serves the robot until standard input closes or the process is asked to end (SIGINT,
/// SIGTERM, SIGHUP); prints one JSON line once it serves, and says on standard error whether
/// sessions must authenticate.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let access = Access {
        listen: a.listen.clone(),
        connect: a.connect.clone(),
        credentials: match &a.credentials {
            Some(path) => Some(Credentials::from_file(path).map_err(bridge)?),
            None => None,
        },
    };
    access.check_serving().map_err(bridge)?;
    let backend = backend(a)?;
    let robots = robots(a, &backend)?;
    let session = access::open(&access).map_err(bridge)?;
    let mut servers = Vec::new();
    for (namespace, robot) in &robots {
        let opts = ServeOptions {
            domain: a.domain,
            namespace: namespace.clone(),
            camera: !a.no_camera,
            lockstep: a.lockstep,
            ..ServeOptions::default()
        };
        servers.push(Server::start(robot, &session, opts).map_err(bridge)?);
    }
    // The first robot: its waits pass the others' time too (one world, one clock).
    let robot = &robots[0].1;
    let view = a
        .view
        .as_deref()
        .map(|addr| view(robot, addr, !a.no_camera))
        .transpose()?;
    let authenticated = access.credentials.is_some();
    eprintln!(
        "serving {} on {:?}: {}",
        a.robot,
        a.listen,
        if authenticated {
            "sessions must present the credentials' user and password"
        } else {
            "no authentication (loopback only)"
        }
    );
    super::common::print_json(&Serving {
        robot: &a.robot,
        listen: &a.listen,
        connect: &a.connect,
        namespace: &a.namespace,
        also: &robots[1..]
            .iter()
            .map(|(n, _)| n.as_str())
            .collect::<Vec<_>>(),
        domain: a.domain,
        authenticated,
        lockstep: a.lockstep,
        view: a.view.as_deref(),
    });
    until_asked_to_end(robot, a.lockstep)?;
    for (server, (namespace, _)) in servers.into_iter().zip(&robots) {
        let stats = server.stop();
        eprintln!("served {namespace}: {stats:?}");
    }
    if let Some(v) = view {
        eprintln!("view: {:?}", v.stats());
    }
    Ok(())
}

/// Lets `robot`'s time pass (a simulator paced to the wall clock; in `lockstep`, its clients
/// let it pass) until standard input closes or the process is asked to end (SIGINT, SIGTERM,
/// SIGHUP).
fn until_asked_to_end(robot: &ferrobot::Robot, lockstep: bool) -> ferrobot::Result<()> {
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [
        signal_hook::consts::SIGINT,
        signal_hook::consts::SIGTERM,
        signal_hook::consts::SIGHUP,
    ] {
        signal_hook::flag::register(sig, stop.clone())?;
    }
    let eof = stop.clone();
    std::thread::spawn(move || {
        let _ = std::io::stdin().read_to_end(&mut Vec::new());
        eof.store(true, Ordering::SeqCst);
    });
    // The robot's time passes (the simulator's paced to the wall clock) and its streams flow;
    // in lockstep, its clients let it pass.
    while !stop.load(Ordering::SeqCst) {
        match lockstep {
            true => std::thread::sleep(std::time::Duration::from_millis(20)),
            false => robot.wait(0.02)?,
        }
    }
    Ok(())
}
