//! The simulated camera served on a Unix socket, beside a firmware or plant server: the host
//! program talks to the firmware over a serial port and to the camera over this socket, as it
//! would to a RealSense over USB, and sees the world that moves the plants.
//!
//! The protocol: the client writes one line, the server answers.
//! * `info` → one JSON line `{"width", "height", "fx", "fy", "cx", "cy", "rate"}` (px, Hz).
//! * `frame` → one JSON line `{"time_us", "width", "height"}`, then `width · height · 3` bytes
//!   of RGB (row-major, row 0 at the top), then `width · height` little-endian `f32` depths in
//!   metres (0 = invalid). The frame is the next one at a whole multiple of the period on the
//!   simulated clock that has not been served yet; `time_us` is that clock (the firmware's).
//! * anything else → `{"error": ...}` and the connection stays open.
//!
//! A real camera's server (`host/peers/realsense/serve_realsense.py`, a RealSense on
//! librealsense) speaks the same protocol with optional keys a client may ignore:
//! * in `info`: `"distortion": {"model", "coeffs"}` (librealsense's lens model and its
//!   coefficients), `"device"` (a line naming the camera), `"depth_scale"` (m per depth unit);
//! * in `frame`'s header: no `time_us` (it does not know the robot's clock), and
//!   `"frame_number"`, `"device_time_ms"` and `"time_domain"` (the camera's own stamp, ms, and
//!   its clock: `hardware_clock`, `system_time` or `global_time`) and `"age_us"` (how long
//!   before the header was sent the frame was taken, µs, by the host's clock). The client
//!   stamps such a frame with its link's clock less `age_us`.
//!
//! The server asks for the world's ground truth through a closure: a channel to the
//! simulation thread ([`TruthTap`], [`tap_truth`]) or a short lock of the plants; the
//! simulation is never held while a frame renders.

use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::Arc;
use std::time::Duration;

use crate::camera::{BandedCamera, FrameClock};
use crate::lockstep::Truth;
use crate::render::RenderedImage;
use crate::serve::ServeError;

/// Longest request line, bytes.
pub const MAX_REQUEST: usize = 256;

/// How the camera server asks for the world's truth: it sends a reply channel, the simulation
/// thread answers with [`Truth`] at its current instant.
pub type TruthTap = mpsc::Sender<mpsc::Sender<Truth>>;

/// The simulation thread's end of a [`TruthTap`]: answer every pending request (cheap when
/// there is none).
pub fn answer_truth_requests(rx: &mpsc::Receiver<mpsc::Sender<Truth>>, truth: impl Fn() -> Truth) {
    while let Ok(reply) = rx.try_recv() {
        let _ = reply.send(truth());
    }
}

/// A source of truth for a camera server: asks the simulation thread through `tap`.
pub fn tap_truth(tap: TruthTap) -> impl FnMut() -> Option<Truth> + Send + 'static {
    move || {
        let (tx, rx) = mpsc::channel();
        tap.send(tx).ok()?;
        rx.recv_timeout(Duration::from_secs(5)).ok()
    }
}

/// A camera being served; dropping it stops the server and removes its socket.
pub struct CameraServer {
    /// The socket's path.
    pub path: PathBuf,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for CameraServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let _ = std::fs::remove_file(&self.path);
    }
}

/// The socket path of the camera served beside the serial link `link`: `LINK.camera`.
pub fn socket_beside(link: &Path) -> PathBuf {
    let mut s = link.as_os_str().to_owned();
    s.push(".camera");
    PathBuf::from(s)
}

/// Serve `camera` at `rate` Hz on a new Unix socket at `path` (which must not exist: nothing
/// is ever replaced), taking the world's truth from `truth` (`None`: the simulation has
/// stopped). One client at a time.
pub fn serve_camera(
    path: &Path,
    camera: BandedCamera,
    rate: f64,
    truth: impl FnMut() -> Option<Truth> + Send + 'static,
) -> Result<CameraServer, ServeError> {
    let (width, height) = camera.width_height();
    if path.symlink_metadata().is_ok() {
        return Err(ServeError::LinkExists(path.to_path_buf()));
    }
    let listener = UnixListener::bind(path).map_err(ServeError::Io)?;
    listener.set_nonblocking(true).map_err(ServeError::Io)?;
    let clock = FrameClock::new(rate).ok_or_else(|| {
        ServeError::Io(std::io::Error::other(format!(
            "a camera rate of {rate} Hz (need (0, 1000])"
        )))
    })?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let thread = std::thread::spawn(move || {
        let mut state = Served {
            camera,
            image: RenderedImage::new(width, height),
            clock,
            truth: Box::new(truth),
        };
        while !flag.load(Ordering::Relaxed) {
            match listener.accept() {
                Ok((stream, _)) => state.client(stream, &flag),
                Err(_) => std::thread::sleep(Duration::from_millis(5)),
            }
        }
    });
    Ok(CameraServer {
        path: path.to_path_buf(),
        stop,
        thread: Some(thread),
    })
}

struct Served {
    camera: BandedCamera,
    image: RenderedImage,
    clock: FrameClock,
    truth: Box<dyn FnMut() -> Option<Truth> + Send>,
}

impl Served {
    fn truth(&mut self) -> Option<Truth> {
        (self.truth)()
    }

    fn client(&mut self, stream: UnixStream, stop: &AtomicBool) {
        let _ = stream.set_nonblocking(false);
        let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
        let Ok(mut out) = stream.try_clone() else {
            return;
        };
        let mut reader = BufReader::new(stream);
        let mut line = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            line.clear();
            match (&mut reader)
                .take(MAX_REQUEST as u64)
                .read_until(b'\n', &mut line)
            {
                Ok(0) => return,
                Ok(_) => {}
                Err(e)
                    if e.kind() == std::io::ErrorKind::WouldBlock
                        || e.kind() == std::io::ErrorKind::TimedOut =>
                {
                    continue
                }
                Err(_) => return,
            }
            let reply = match std::str::from_utf8(&line).map(str::trim) {
                Ok("info") => self.info(&mut out),
                Ok("frame") => self.frame(&mut out),
                _ => writeln!(
                    out,
                    "{}",
                    serde_json::json!({"error": "unknown request; say `info` or `frame`"})
                ),
            };
            if reply.is_err() {
                return;
            }
        }
    }

    fn info(&self, out: &mut UnixStream) -> std::io::Result<()> {
        let k = self.camera.section();
        writeln!(
            out,
            "{}",
            serde_json::json!({"width": k.width, "height": k.height, "fx": k.fx, "fy": k.fy,
                "cx": k.cx, "cy": k.cy, "rate": self.clock.rate()})
        )
    }

    fn frame(&mut self, out: &mut UnixStream) -> std::io::Result<()> {
        let Some(now) = self.truth() else {
            return writeln!(
                out,
                "{}",
                serde_json::json!({"error": "the simulation has stopped"})
            );
        };
        // The simulation runs at the wall clock's pace: wait for the frame's instant.
        let due = self.clock.next(now.time_us);
        if due > now.time_us {
            std::thread::sleep(Duration::from_micros(due - now.time_us));
        }
        let Some(truth) = self.truth() else {
            return writeln!(
                out,
                "{}",
                serde_json::json!({"error": "the simulation has stopped"})
            );
        };
        self.camera.capture_into(&truth, &mut self.image);
        let img = &self.image;
        writeln!(
            out,
            "{}",
            serde_json::json!({"time_us": truth.time_us, "width": img.width, "height": img.height})
        )?;
        out.write_all(&img.rgb)?;
        let depth: Vec<u8> = img.depth.iter().flat_map(|d| d.to_le_bytes()).collect();
        out.write_all(&depth)?;
        out.flush()
    }
}

/// The robot's camera to serve beside a firmware server.
#[derive(Debug, Clone)]
pub struct CameraOptions {
    /// The description's camera.
    pub section: ferrobot_description::CameraSection,
    /// Seed of the depth noise.
    pub seed: u64,
    /// Simulate the depth noise.
    pub noise: bool,
    /// How far the camera sits off its URDF mount, in the camera link's frame
    /// ([`crate::camera::SimCamera::set_mount_error`]); identity for none.
    pub mount_error: nalgebra::Isometry3<f64>,
    /// Draw the description's hand-eye marker on the robot.
    pub marker: bool,
}

impl CameraOptions {
    /// The camera of `section` on `body` in `scene`, or `None` if the URDF has no such
    /// optical frame.
    pub fn camera(
        &self,
        scene: &crate::scene::Scene,
        body: &crate::body::RobotBody,
    ) -> Option<crate::camera::BandedCamera> {
        let mut cam =
            crate::camera::BandedCamera::new(scene, body, &self.section, self.seed, self.noise)?;
        cam.set_mount_error(body, &self.mount_error);
        cam.show_decals(self.marker);
        Some(cam)
    }
}
