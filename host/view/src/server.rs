//! The view served: a listener thread takes viewers' connections (each on a thread of its own,
//! its frames through a bounded queue), and a feed thread maps the robot's streams to messages
//! ([`ferrobot_ros2::robot`]) and hands them to the [`Hub`].

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use ferrobot::{Bell, Robot};
use ferrobot_ros2::robot::{Feeds, Messages, RobotInfo};
use ferrobot_ros2::topics;
use ferrobot_ros2::view::WorldFeed;
use parking_lot::Mutex;
use tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tungstenite::{Message, WebSocket};

use crate::hub::{Hub, HubStats, Out};
use crate::protocol::SUBPROTOCOL;

/// Why a view could not be served.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ViewError {
    /// The address could not be listened on.
    #[error("listening on {addr}: {source}")]
    Listen {
        /// The address.
        addr: String,
        /// Why.
        source: std::io::Error,
    },
    /// The robot refused.
    #[error(transparent)]
    Robot(#[from] ferrobot::Error),
}

/// How a view is served.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ViewOptions {
    /// The camera's frames too.
    pub camera: bool,
    /// Frames a viewer may fall behind before its oldest are dropped.
    pub queue: usize,
}

impl Default for ViewOptions {
    fn default() -> Self {
        ViewOptions {
            camera: true,
            queue: 512,
        }
    }
}

/// A live view of a robot for Foxglove and Lichtblick (their "Foxglove WebSocket" connection);
/// dropping it ends it.
pub struct ViewServer {
    addr: SocketAddr,
    hub: Arc<Mutex<Hub>>,
    stop: Arc<AtomicBool>,
    bell: Arc<Bell>,
    threads: Vec<JoinHandle<()>>,
}

impl ViewServer {
    /// Serves `robot`'s view on `addr` (`127.0.0.1:8765`; port 0 for any free one).
    pub fn start(robot: &Robot, addr: &str, opts: ViewOptions) -> Result<ViewServer, ViewError> {
        let listen = |source| ViewError::Listen {
            addr: addr.into(),
            source,
        };
        let listener = TcpListener::bind(addr).map_err(listen)?;
        listener.set_nonblocking(true).map_err(listen)?;
        let bound = listener.local_addr().map_err(listen)?;
        let session = format!("{}-{}", std::process::id(), robot.time());
        let hub = Arc::new(Mutex::new(Hub::new(
            &format!("ferrobot: {}", robot.name()),
            &session,
        )));
        let info = RobotInfo::of(robot)?;
        let camera = opts.camera && info.optical.is_some() && robot.camera().is_ok();
        // The camera's frames are read (rendered, on the simulator) only while a viewer
        // subscribes to one of their channels, advertised from the start.
        let feeds = Feeds::subscribe(robot, CAMERA_QUEUE, false)?;
        let bell = Bell::new();
        feeds.ring(&bell);
        let messages = Messages::new(info).with_points(4);
        let start = std::time::Duration::from_secs_f64(robot.time());
        {
            let mut h = hub.lock();
            for (topic, data) in messages.latched(start) {
                h.publish(&topic, start.as_nanos() as u64, data, true);
            }
            if camera {
                for t in &topics::CAMERA {
                    h.channel(t);
                }
            }
        }
        let stop = Arc::new(AtomicBool::new(false));
        let (h, s, b) = (hub.clone(), stop.clone(), bell.clone());
        let r = robot.clone();
        let feed = std::thread::Builder::new()
            .name("ferrobot-view-feed".into())
            .spawn(move || feed(&r, feeds, camera, messages, h, s, b))
            .map_err(listen)?;
        let (h, s) = (hub.clone(), stop.clone());
        let queue = opts.queue.clamp(1, 100_000);
        let accept = std::thread::Builder::new()
            .name("ferrobot-view-accept".into())
            .spawn(move || accept(listener, h, s, queue))
            .map_err(listen)?;
        Ok(ViewServer {
            addr: bound,
            hub,
            stop,
            bell,
            threads: vec![feed, accept],
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// What it has done.
    pub fn stats(&self) -> HubStats {
        self.hub.lock().stats()
    }

    /// Messages published on the topic named `topic` so far (`/camera/color/image_raw`),
    /// whether or not a viewer took them.
    pub fn published(&self, topic: &str) -> u64 {
        self.hub.lock().published(topic)
    }
}

impl Drop for ViewServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        self.bell.ring();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Frames a viewer's camera feed may fall behind before the oldest is dropped.
const CAMERA_QUEUE: usize = 256;

/// The robot's streams and world, to the viewers, until `stop`; the camera's frames (when
/// `camera`) while a viewer subscribes to them.
fn feed(
    robot: &Robot,
    mut feeds: Feeds,
    mut camera: bool,
    mut messages: Messages,
    hub: Arc<Mutex<Hub>>,
    stop: Arc<AtomicBool>,
    bell: Arc<Bell>,
) {
    let mut world = WorldFeed::default();
    while !stop.load(Ordering::SeqCst) {
        let wanted = camera && hub.lock().wanted(&topics::CAMERA);
        if feeds
            .set_camera(robot, wanted, CAMERA_QUEUE, &bell)
            .is_err()
        {
            // A camera that cannot be read is left alone: the rest flows on.
            camera = false;
        }
        for item in feeds.take() {
            let t = item.time().as_nanos() as u64;
            for (topic, data) in messages.of(&item) {
                let latched = topic.latched();
                hub.lock().publish(&topic, t, data, latched);
            }
        }
        let t = (robot.time().max(0.0) * 1e9) as u64;
        for (topic, data) in world.poll(robot) {
            hub.lock().publish(&topic, t, data, topic.latched());
        }
        bell.wait(Duration::from_millis(100));
    }
}

fn accept(listener: TcpListener, hub: Arc<Mutex<Hub>>, stop: Arc<AtomicBool>, queue: usize) {
    let mut clients: Vec<JoinHandle<()>> = Vec::new();
    while !stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((stream, _)) => {
                let (h, s) = (hub.clone(), stop.clone());
                if let Ok(t) = std::thread::Builder::new()
                    .name("ferrobot-view-client".into())
                    .spawn(move || client(stream, h, s, queue))
                {
                    clients.push(t);
                }
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
        clients.retain(|t| !t.is_finished());
    }
    for t in clients {
        let _ = t.join();
    }
}

/// Selects Foxglove's subprotocol when the client offers it. (The error type is tungstenite's
/// callback contract; it is never returned.)
#[allow(clippy::result_large_err)]
fn handshake(req: &Request, mut resp: Response) -> Result<Response, ErrorResponse> {
    let offered = req
        .headers()
        .get_all("Sec-WebSocket-Protocol")
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| v.split(',').any(|p| p.trim() == SUBPROTOCOL));
    if offered {
        if let Ok(v) = SUBPROTOCOL.parse() {
            resp.headers_mut().insert("Sec-WebSocket-Protocol", v);
        }
    }
    Ok(resp)
}

/// One viewer: its frames out, its requests in, until it goes or the view ends.
fn client(stream: TcpStream, hub: Arc<Mutex<Hub>>, stop: Arc<AtomicBool>, queue: usize) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_nodelay(true);
    let Ok(mut ws) = tungstenite::accept_hdr(stream, handshake) else {
        return;
    };
    let _ = ws
        .get_ref()
        .set_read_timeout(Some(Duration::from_millis(10)));
    let (tx, rx) = sync_channel(queue);
    let id = hub.lock().join(tx);
    serve_client(&mut ws, &rx, &hub, id, &stop);
    hub.lock().leave(id);
    let _ = ws.close(None);
}

fn serve_client(
    ws: &mut WebSocket<TcpStream>,
    rx: &Receiver<Out>,
    hub: &Mutex<Hub>,
    id: u64,
    stop: &AtomicBool,
) {
    while !stop.load(Ordering::SeqCst) {
        while let Ok(out) = rx.try_recv() {
            let m = match out {
                Out::Text(t) => Message::Text(t),
                Out::Binary(b) => Message::Binary(b),
            };
            if ws.send(m).is_err() {
                return;
            }
        }
        match ws.read() {
            Ok(Message::Text(t)) => hub.lock().client_says(id, &t),
            Ok(Message::Close(_)) => return,
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(_) => return,
        }
    }
}
