//! The firmware core with its simulated plants behind a serial port, paced to the wall clock:
//! `ferrobot sim-firmware` and the firmware process of the HIL measurements. Its host link is
//! a PTY reached through a stable symlink (as udev's `/dev/serial/by-id` links are), which a
//! test can unplug, plug, mute and stall ([`LinkControl`]).
//!
//! Pacing is best effort and never outruns its input: the simulated world advances at most
//! [`MAX_STEP`] between two reads of the host link. A server the machine does not run for a
//! while (a busy machine) finds its world where it left it, behind the wall clock by that
//! while, rather than jumping ahead: the firmware never lives through a silence of the host
//! that the host did not make (its watchdog would stop the robot for it).

use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::thread;
use std::time::{Duration, Instant};

use serialport::TTYPort;

use crate::camera_server::CameraOptions;
use crate::serve::{micros, pty, ServeError};

/// The most simulated time the server lets pass between two reads of the host link, µs.
pub const MAX_STEP: u64 = 20_000;

/// Commands to a running firmware server.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkControl {
    /// Close the host PTY, as pulling the USB cable would; firmware output is lost meanwhile.
    Unplug,
    /// Unplug, and plug again once this much of the firmware's own time has passed (a cable
    /// out for an exact while, whatever the machine's load).
    UnplugFor(Duration),
    /// Make a new host PTY behind the same link path, as plugging the cable back in would.
    Plug,
    /// Drop the firmware's telemetry frames from now on and pass the rest (handshakes,
    /// acknowledgements, replies), as a firmware whose control loop stopped while its link
    /// still answers would (fault injection).
    Mute,
    /// Pass the telemetry again.
    Unmute,
    /// Stop the simulated world's clock: the firmware still reads the host link and answers
    /// it, at the instant the clock stopped, but no time passes for it (so its watchdog
    /// cannot trip) until [`LinkControl::Thaw`].
    Freeze,
    /// Start the clock again where it stopped.
    Thaw,
    /// The server's thread stops for this long (wall time), as a process that a busy machine
    /// does not run: a test of the pacing.
    Stall(Duration),
}

impl LinkControl {
    /// A control line of `ferrobot sim-firmware`'s standard input: `unplug`, `unplug MS`,
    /// `plug`, `mute`, `unmute`, `freeze`, `thaw`, `stall MS`; `None` for anything else.
    pub fn parse(line: &str) -> Option<LinkControl> {
        let mut words = line.split_whitespace();
        let verb = words.next()?;
        let ms = words
            .next()
            .map(|w| w.parse::<u64>().map(Duration::from_millis));
        if words.next().is_some() {
            return None;
        }
        match (verb, ms) {
            ("unplug", None) => Some(LinkControl::Unplug),
            ("unplug", Some(Ok(d))) => Some(LinkControl::UnplugFor(d)),
            ("plug", None) => Some(LinkControl::Plug),
            ("mute", None) => Some(LinkControl::Mute),
            ("unmute", None) => Some(LinkControl::Unmute),
            ("freeze", None) => Some(LinkControl::Freeze),
            ("thaw", None) => Some(LinkControl::Thaw),
            ("stall", Some(Ok(d))) => Some(LinkControl::Stall(d)),
            _ => None,
        }
    }
}

/// `out` (frames of the firmware's host link, each ended by a `0x00`) without its telemetry
/// frames; a partial frame at the end is kept in `partial` for the next call.
fn without_telemetry(partial: &mut Vec<u8>, out: &[u8]) -> Vec<u8> {
    use ferrobot_protocol::{DeviceMsg, FrameDecoder};
    partial.extend_from_slice(out);
    let mut kept = Vec::new();
    let mut start = 0;
    for (i, &b) in partial.iter().enumerate() {
        if b != 0 {
            continue;
        }
        let frame = &partial[start..=i];
        let mut decoder = FrameDecoder::new();
        // The frame ends at its one 0x00, the last byte: that is where a frame decodes.
        let telemetry = frame.iter().any(|&b| {
            matches!(
                decoder.push::<DeviceMsg>(b),
                Some(Ok(f)) if matches!(f.msg, DeviceMsg::Telemetry(_))
            )
        });
        if !telemetry {
            kept.extend_from_slice(frame);
        }
        start = i + 1;
    }
    partial.drain(..start);
    kept
}

/// A firmware core with its simulated plants, paced to the wall clock, whose host link is a
/// PTY reached through the symlink `link` (as udev's `/dev/serial/by-id` links are).
pub struct FirmwareServer {
    /// The stable path of the host link.
    pub link: PathBuf,
    control: Option<std::sync::mpsc::Sender<LinkControl>>,
    thread: Option<thread::JoinHandle<()>>,
    /// The camera served beside the link ([`crate::camera_server`]), if the robot has one.
    pub camera: Option<crate::camera_server::CameraServer>,
}

impl FirmwareServer {
    /// Act on the host link ([`LinkControl`]).
    pub fn control(&self, c: LinkControl) {
        if let Some(tx) = &self.control {
            let _ = tx.send(c);
        }
    }
}

impl Drop for FirmwareServer {
    /// Stop serving and remove the link this server made.
    fn drop(&mut self) {
        self.camera = None;
        self.control = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A new PTY behind the symlink `link`, which must not exist (creating a symlink never
/// replaces anything): nothing at that path is ever removed or replaced, except the symlink
/// this server made itself.
fn host_pty(link: &Path) -> Result<(TTYPort, TTYPort, String), ServeError> {
    let (master, slave, name) = pty()?;
    std::os::unix::fs::symlink(&name, link).map_err(|e| match e.kind() {
        io::ErrorKind::AlreadyExists => ServeError::LinkExists(link.to_path_buf()),
        _ => ServeError::Io(e),
    })?;
    Ok((master, slave, name))
}

/// The server's host link and its clock, on the server's thread.
struct HostLink {
    path: PathBuf,
    /// The PTY (master, slave, slave's name) while plugged.
    port: Option<(TTYPort, TTYPort, String)>,
    /// When to plug again after [`LinkControl::UnplugFor`] (firmware time, µs).
    replug_at: Option<u64>,
    muted: bool,
    /// While muted, the end of the output not yet passed (a frame without its delimiter
    /// yet); passed on when the telemetry is unmuted.
    held: Vec<u8>,
    frozen: bool,
    /// Wall time the world did not live (the server stalled, or the clock was frozen), µs.
    slipped: u64,
}

impl HostLink {
    /// Close the host PTY, if open, and remove the link if it is still the symlink to it this
    /// server made.
    fn unplug(&mut self) {
        if let Some((_, _, name)) = self.port.take() {
            if std::fs::read_link(&self.path).is_ok_and(|t| t.as_os_str() == name.as_str()) {
                let _ = std::fs::remove_file(&self.path);
            }
        }
    }

    fn plug(&mut self) {
        self.replug_at = None;
        if self.port.is_none() {
            self.port = host_pty(&self.path).ok();
        }
    }

    /// Act on a control; false when the server is to end.
    fn control(&mut self, c: Result<LinkControl, TryRecvError>, now_us: u64) -> bool {
        match c {
            Ok(LinkControl::Unplug) => self.unplug(),
            Ok(LinkControl::UnplugFor(d)) => {
                self.unplug();
                self.replug_at = Some(now_us.saturating_add(d.as_micros() as u64));
            }
            Ok(LinkControl::Plug) => self.plug(),
            Ok(LinkControl::Mute) => self.muted = true,
            Ok(LinkControl::Unmute) => self.muted = false,
            Ok(LinkControl::Freeze) => self.frozen = true,
            Ok(LinkControl::Thaw) => self.frozen = false,
            Ok(LinkControl::Stall(d)) => thread::sleep(d),
            Err(TryRecvError::Disconnected) => {
                self.unplug();
                return false;
            }
            Err(TryRecvError::Empty) => {}
        }
        if self.replug_at.is_some_and(|t| now_us >= t) {
            self.plug();
        }
        true
    }

    /// The firmware time to run the world to, from the wall clock (µs since `start`, the
    /// world at `t0` then): at most [`MAX_STEP`] past the world's time `now_us`, none while
    /// frozen; the rest slips.
    fn pace(&mut self, t0: u64, start: Instant, now_us: u64) -> u64 {
        let wall = t0
            .saturating_add(micros(start))
            .saturating_sub(self.slipped);
        let limit = if self.frozen {
            now_us
        } else {
            now_us.saturating_add(MAX_STEP)
        };
        if wall > limit {
            self.slipped += wall - limit;
        }
        wall.min(limit)
    }

    /// What the host sent, if plugged (waits up to the PTY's timeout).
    fn read(&mut self, buf: &mut [u8]) -> usize {
        match self.port.as_mut() {
            Some((master, _, _)) => master.read(buf).unwrap_or(0),
            None => {
                thread::sleep(Duration::from_millis(1));
                0
            }
        }
    }

    /// Send the firmware's output to the host, if plugged (lost otherwise, as on a cable
    /// that is out); telemetry is held back while muted.
    fn write(&mut self, mut out: Vec<u8>) {
        if self.muted {
            out = without_telemetry(&mut self.held, &out);
        } else if !self.held.is_empty() {
            self.held.append(&mut out);
            out = std::mem::take(&mut self.held);
        }
        if let Some((master, _, _)) = self.port.as_mut() {
            if !out.is_empty() {
                let _ = master.write_all(&out);
            }
        }
    }
}

/// Serve `sim`'s host link on a PTY behind `link`, in real time ([`MAX_STEP`]), on a thread of
/// its own, and its world's camera (`camera`) on the Unix socket `LINK.camera`
/// ([`crate::camera_server::socket_beside`]).
pub fn serve_firmware(
    mut sim: crate::LockstepSim,
    link: PathBuf,
    camera: Option<CameraOptions>,
) -> Result<FirmwareServer, ServeError> {
    let (tx, rx) = std::sync::mpsc::channel();
    let (tap, truth_rx) = std::sync::mpsc::channel();
    let camera = match (camera, sim.body()) {
        (Some(c), Some(body)) => {
            let Some(cam) = c.camera(sim.scene(), body) else {
                return Err(ServeError::Io(io::Error::other(format!(
                    "the URDF has no camera frame {:?}",
                    c.section.frame
                ))));
            };
            Some(crate::camera_server::serve_camera(
                &crate::camera_server::socket_beside(&link),
                cam,
                c.section.rate,
                crate::camera_server::tap_truth(tap),
            )?)
        }
        _ => None,
    };
    let mut host = HostLink {
        path: link.clone(),
        port: Some(host_pty(&link)?),
        replug_at: None,
        muted: false,
        held: Vec::new(),
        frozen: false,
        slipped: 0,
    };
    let thread = thread::spawn(move || run(&mut sim, &mut host, &rx, &truth_rx));
    Ok(FirmwareServer {
        link,
        control: Some(tx),
        thread: Some(thread),
        camera,
    })
}

/// The server's loop: controls, the host's bytes, the world up to the wall clock (paced), the
/// camera's requests for ground truth, the firmware's output.
fn run(
    sim: &mut crate::LockstepSim,
    host: &mut HostLink,
    controls: &Receiver<LinkControl>,
    truth_rx: &Receiver<std::sync::mpsc::Sender<crate::lockstep::Truth>>,
) {
    let start = Instant::now();
    let t0 = sim.now_us();
    let mut buf = [0u8; 1024];
    while host.control(controls.try_recv(), sim.now_us()) {
        let n = host.read(&mut buf);
        if n > 0 {
            sim.write_host(&buf[..n]);
        }
        let to = host.pace(t0, start, sim.now_us());
        sim.run_until(to);
        crate::camera_server::answer_truth_requests(truth_rx, || sim.truth());
        host.write(sim.take_host_output());
    }
}

/// Serve `sim` behind the symlink `link` (see [`serve_firmware`]), announce it with one JSON
/// line on standard output, then obey control lines ([`LinkControl::parse`]) on standard
/// input until it closes. The body of `ferrobot sim-firmware` and of the HIL measurements.
pub fn run_firmware_server(
    sim: crate::LockstepSim,
    robot: &str,
    link: PathBuf,
    camera: Option<CameraOptions>,
) -> Result<(), ServeError> {
    use std::io::BufRead;
    let server = serve_firmware(sim, link.clone(), camera)?;
    let camera = server.camera.as_ref().map(|c| c.path.display().to_string());
    println!(
        "{}",
        serde_json::json!({"robot": robot, "host": link.display().to_string(), "camera": camera})
    );
    for line in std::io::stdin().lock().lines() {
        match line {
            Ok(line) => {
                if let Some(c) = LinkControl::parse(&line) {
                    server.control(c);
                }
            }
            Err(_) => break,
        }
    }
    Ok(())
}
