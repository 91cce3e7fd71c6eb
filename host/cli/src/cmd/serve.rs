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
    /// Where it runs (the in-process simulator by default, paced at real time).
    #[command(flatten)]
    pub backend: BackendArgs,
}

/// The line `ferrobot serve` prints once it serves.
#[derive(Serialize)]
struct Serving<'a> {
    robot: &'a str,
    listen: &'a [String],
    connect: &'a [String],
    namespace: &'a str,
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
    let robot = super::common::robot_builder(&a.robot)
        .backend(backend)
        .scene(&a.scene)
        .build()?;
    let session = access::open(&access).map_err(bridge)?;
    let opts = ServeOptions {
        domain: a.domain,
        namespace: a.namespace.clone(),
        camera: !a.no_camera,
        lockstep: a.lockstep,
        ..ServeOptions::default()
    };
    let server = Server::start(&robot, &session, opts).map_err(bridge)?;
    let view = a
        .view
        .as_deref()
        .map(|addr| view(&robot, addr, !a.no_camera))
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
        domain: a.domain,
        authenticated,
        lockstep: a.lockstep,
        view: a.view.as_deref(),
    });
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
        match a.lockstep {
            true => std::thread::sleep(std::time::Duration::from_millis(20)),
            false => robot.wait(0.02)?,
        }
    }
    let stats = server.stop();
    eprintln!("served: {stats:?}");
    if let Some(v) = view {
        eprintln!("view: {:?}", v.stats());
    }
    Ok(())
}
