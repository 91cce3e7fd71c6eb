//! A camera served on a Unix socket ([`ferrobot_sim::camera_server`]'s protocol): the
//! simulated world's camera beside a firmware served on a serial port, or a real RealSense
//! served by `host/peers/realsense/serve_realsense.py`, as a [`CameraDevice`]. Behind the
//! serial and emulated backends, the world that moves the plants renders the frames, so a
//! program sees the same scene whichever backend it uses.
//!
//! A frame whose header has `time_us` (the simulator's) is on the robot's clock already; one
//! without it (a real camera's server, which does not know the robot's clock) is stamped with
//! the link's clock when its header arrives, less the `age_us` the server measured, and keeps
//! the camera's own stamp ([`RawFrame::device_time`]).

use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::Duration;

use ferrobot_perception::{DepthImage, Intrinsics, RgbImage};
use serde::Deserialize;

use super::device::{CameraDevice, DeviceTime, RawFrame, TimeDomain};
use super::Link;
use crate::error::{Error, Result};

/// The socket path of the camera served beside the serial link `link`: `LINK.camera` (as
/// `ferrobot sim-firmware` serves it).
pub fn socket_beside(link: &Path) -> PathBuf {
    let mut s = link.as_os_str().to_owned();
    s.push(".camera");
    PathBuf::from(s)
}

/// How long a frame may take to arrive (wall time).
pub const FRAME_TIMEOUT: Duration = Duration::from_secs(10);
/// Longest header line accepted, bytes.
const MAX_HEADER: u64 = 4096;

#[derive(Deserialize)]
struct Info {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    rate: f64,
    #[serde(default)]
    distortion: Option<Distortion>,
    #[serde(default)]
    device: Option<String>,
}

/// A real camera's lens distortion, as its server reports it (librealsense's model and
/// coefficients). Ferrobot projects with a pinhole ([`Intrinsics`]): a D435's colour stream
/// reports zero coefficients.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct Distortion {
    /// librealsense's name of the model (`none`, `brown_conrady`, `inverse_brown_conrady`,
    /// ...).
    pub model: String,
    /// The model's coefficients (k1, k2, p1, p2, k3 for Brown-Conrady).
    pub coeffs: Vec<f64>,
}

#[derive(Deserialize)]
struct Header {
    /// The robot's clock, µs (the simulator's server only).
    time_us: Option<u64>,
    width: u32,
    height: u32,
    frame_number: Option<u64>,
    device_time_ms: Option<f64>,
    time_domain: Option<TimeDomain>,
    /// How long before the header was sent the frame was taken, µs.
    age_us: Option<u64>,
}

impl Header {
    /// The camera's own stamp, when the header has all of it.
    fn device_time(&self) -> Option<DeviceTime> {
        Some(DeviceTime {
            frame_number: self.frame_number?,
            time_ms: self.device_time_ms.filter(|t| t.is_finite())?,
            domain: self.time_domain?,
        })
    }
}

/// A camera on a Unix socket.
pub struct SocketCamera {
    path: PathBuf,
    reader: BufReader<UnixStream>,
    writer: UnixStream,
    intrinsics: Intrinsics,
    rate: f64,
    distortion: Option<Distortion>,
    device: Option<String>,
}

impl SocketCamera {
    /// Connect to the camera served at `path` and read its intrinsics.
    pub fn connect(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let stream = UnixStream::connect(&path).map_err(|e| {
            Error::Link(format!(
                "cannot reach the camera at {}: {e}",
                path.display()
            ))
        })?;
        stream.set_read_timeout(Some(FRAME_TIMEOUT))?;
        let writer = stream.try_clone()?;
        let mut cam = SocketCamera {
            reader: BufReader::new(stream),
            writer,
            intrinsics: Intrinsics {
                width: 1,
                height: 1,
                fx: 1.0,
                fy: 1.0,
                cx: 0.0,
                cy: 0.0,
            },
            rate: 1.0,
            distortion: None,
            device: None,
            path,
        };
        let info: Info = cam.ask("info")?;
        cam.intrinsics =
            Intrinsics::new(info.width, info.height, info.fx, info.fy, info.cx, info.cy)?;
        if !(info.rate.is_finite() && info.rate > 0.0 && info.rate <= 1000.0) {
            return Err(cam.bad(format!("a frame rate of {} Hz", info.rate)));
        }
        cam.rate = info.rate;
        cam.distortion = info.distortion;
        cam.device = info.device;
        Ok(cam)
    }

    /// The lens distortion the server reports (a real camera's), if any.
    pub fn distortion(&self) -> Option<&Distortion> {
        self.distortion.as_ref()
    }

    /// The line naming the camera that the server reports (a real camera's model, serial
    /// number and firmware), if any.
    pub fn device(&self) -> Option<&str> {
        self.device.as_deref()
    }

    fn bad(&self, what: String) -> Error {
        Error::Link(format!("the camera at {} sent {what}", self.path.display()))
    }

    /// Send `request` and read one JSON line of answer.
    fn ask<T: for<'de> Deserialize<'de>>(&mut self, request: &str) -> Result<T> {
        writeln!(self.writer, "{request}").map_err(|e| self.bad(format!("nothing ({e})")))?;
        let mut line = String::new();
        (&mut self.reader)
            .take(MAX_HEADER)
            .read_line(&mut line)
            .map_err(|e| self.bad(format!("nothing ({e})")))?;
        if let Ok(v) = serde_json::from_str::<serde_json::Value>(&line) {
            if let Some(e) = v.get("error") {
                return Err(self.bad(format!("an error: {e}")));
            }
        }
        serde_json::from_str(&line).map_err(|e| self.bad(format!("{line:?} ({e})")))
    }
}

impl CameraDevice for SocketCamera {
    fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    fn rate(&self) -> f64 {
        self.rate
    }

    fn capture(&mut self, link: &mut dyn Link) -> Result<RawFrame> {
        let h: Header = self.ask("frame")?;
        let time = match h.time_us {
            Some(t) => Duration::from_micros(t),
            None => {
                let age = Duration::from_micros(h.age_us.unwrap_or(0));
                if age > FRAME_TIMEOUT {
                    return Err(self.bad(format!("a frame {} s old", age.as_secs_f64())));
                }
                link.now().saturating_sub(age)
            }
        };
        let k = self.intrinsics;
        if (h.width, h.height) != (k.width, k.height) {
            return Err(self.bad(format!(
                "a {}x{} frame from a {}x{} camera",
                h.width, h.height, k.width, k.height
            )));
        }
        let n = k.pixels();
        let mut rgb = vec![0u8; 3 * n];
        let mut raw = vec![0u8; 4 * n];
        self.reader
            .read_exact(&mut rgb)
            .and_then(|()| self.reader.read_exact(&mut raw))
            .map_err(|e| self.bad(format!("a truncated frame ({e})")))?;
        let depth = raw
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        Ok(RawFrame {
            rgb: RgbImage::new(k.width, k.height, rgb)?,
            depth: DepthImage::new(k.width, k.height, depth)?,
            time,
            device_time: h.device_time(),
        })
    }
}

// The simulator serves its camera with the `serve` feature, which `emulated` turns on.
#[cfg(all(test, feature = "emulated"))]
mod tests {
    /// The socket's name is a convention between `ferrobot sim-firmware` (the simulator's
    /// camera server) and this client, which cannot share code: they must agree.
    #[test]
    fn the_socket_beside_a_link_is_where_the_simulator_serves_it() {
        let link = std::path::Path::new("/tmp/ferrobot-link");
        assert_eq!(
            super::socket_beside(link),
            ferrobot_sim::camera_server::socket_beside(link)
        );
    }
}
