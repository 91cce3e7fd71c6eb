//! A serial device of the host-run firmware: a U2D2 on the servo bus, a base's cable. Opened
//! raw at its line rate, exclusively, with the FTDI latency timer at 1 ms where the kernel lets
//! us set it; when it fails (a cable pulled: reads fail with `EIO`) it is closed and opened
//! again by its path until it comes back (a udev link follows the device to its new name).

use std::fmt;
use std::os::fd::{AsRawFd, RawFd};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};

/// How often a lost device is opened again (wall time).
pub const REOPEN_PERIOD: Duration = Duration::from_millis(100);

/// Longest a write may block on a device that does not take bytes, before they count as lost.
pub const WRITE_TIMEOUT: Duration = Duration::from_millis(20);

/// The FTDI latency timer the host-run firmware asks for, ms (the driver's default is 16).
pub const LATENCY_TIMER_MS: u32 = 1;

/// Why a device cannot be opened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OpenError {
    /// Nothing at the path.
    Missing(PathBuf),
    /// The device is there, but this user may not open it.
    Permission(PathBuf),
    /// Another program has it open exclusively, or it refused for another reason.
    Other(PathBuf, String),
}

impl fmt::Display for OpenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OpenError::Missing(p) => write!(f, "no device at {}", p.display()),
            OpenError::Permission(p) => write!(
                f,
                "no permission to open {}: add yourself to its group (`sudo usermod -aG dialout \
                 $USER`, then log in again) or install scripts/udev/99-ferrobot.rules",
                p.display()
            ),
            OpenError::Other(p, why) => write!(f, "cannot open {}: {why}", p.display()),
        }
    }
}

/// What became of the FTDI latency timer when the device was opened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LatencyTimer {
    /// It was at or below [`LATENCY_TIMER_MS`] already, or is now, ms.
    Set(u32),
    /// The kernel exposes it but would not let us write it: it stays at this many ms, and
    /// every servo reply can wait that long (install the udev rule, which sets it).
    Unwritable(u32),
    /// Not an FTDI adapter on `ftdi_sio` (a pseudo-terminal, a CDC-ACM board): nothing to set.
    NotFtdi,
}

/// Open `path` as the host-run firmware's device: raw, `baud` bit/s, 8N1, no flow control,
/// exclusive, non-blocking reads; the latency timer lowered where there is one.
pub fn open(path: &Path, baud: u32) -> Result<(TTYPort, LatencyTimer), OpenError> {
    // The kernel's own answer first, for a precise reason (serialport folds errno into text).
    std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(nix::fcntl::OFlag::O_NOCTTY.bits() | nix::fcntl::OFlag::O_NONBLOCK.bits())
        .open(path)
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => OpenError::Missing(path.to_path_buf()),
            std::io::ErrorKind::PermissionDenied => OpenError::Permission(path.to_path_buf()),
            _ => OpenError::Other(path.to_path_buf(), e.to_string()),
        })?;
    let mut port = serialport::new(path.to_string_lossy(), baud)
        .timeout(WRITE_TIMEOUT)
        .open_native()
        .map_err(|e| OpenError::Other(path.to_path_buf(), e.to_string()))?;
    port.set_exclusive(true)
        .map_err(|e| OpenError::Other(path.to_path_buf(), format!("exclusive access: {e}")))?;
    let _ = port.clear(serialport::ClearBuffer::All);
    Ok((port, set_latency_timer(path)))
}

/// The sysfs file of `path`'s FTDI latency timer, if it has one.
pub fn latency_timer_file(path: &Path) -> Option<PathBuf> {
    let dev = std::fs::canonicalize(path).ok()?;
    let name = dev.file_name()?.to_str()?;
    let f = Path::new("/sys/bus/usb-serial/devices")
        .join(name)
        .join("latency_timer");
    f.exists().then_some(f)
}

/// Lower `path`'s FTDI latency timer to [`LATENCY_TIMER_MS`] if the kernel lets us.
pub fn set_latency_timer(path: &Path) -> LatencyTimer {
    let Some(file) = latency_timer_file(path) else {
        return LatencyTimer::NotFtdi;
    };
    let read = || {
        std::fs::read_to_string(&file)
            .ok()
            .and_then(|s| s.trim().parse::<u32>().ok())
    };
    match read() {
        Some(ms) if ms <= LATENCY_TIMER_MS => LatencyTimer::Set(ms),
        current => {
            let _ = std::fs::write(&file, LATENCY_TIMER_MS.to_string());
            match read() {
                Some(ms) if ms <= LATENCY_TIMER_MS => LatencyTimer::Set(ms),
                now => LatencyTimer::Unwritable(now.or(current).unwrap_or(16)),
            }
        }
    }
}

/// A device of the host-run firmware that comes and goes.
pub struct Device {
    /// The path it is opened by.
    pub path: PathBuf,
    /// Line rate, bit/s.
    pub baud: u32,
    port: Option<TTYPort>,
    /// Why it is lost, while it is.
    lost: Option<String>,
    next_try: Instant,
    /// The latency timer at the last opening.
    pub latency: Option<LatencyTimer>,
}

impl Device {
    /// Open `path` at `baud`; an error if it cannot be opened now.
    pub fn open(path: &Path, baud: u32) -> Result<Device, OpenError> {
        let (port, latency) = open(path, baud)?;
        Ok(Device {
            path: path.to_path_buf(),
            baud,
            port: Some(port),
            lost: None,
            next_try: Instant::now(),
            latency: Some(latency),
        })
    }

    /// The file descriptor to watch, while open.
    pub fn fd(&self) -> Option<RawFd> {
        self.port.as_ref().map(|p| p.as_raw_fd())
    }

    /// Why it is lost, while it is.
    pub fn lost(&self) -> Option<&str> {
        self.lost.as_deref()
    }

    /// Close it: it failed for `why`. It is opened again from [`Device::retry`].
    pub fn lose(&mut self, why: String) {
        if self.port.take().is_some() {
            self.lost = Some(why);
            self.next_try = Instant::now() + REOPEN_PERIOD;
        }
    }

    /// While lost, try opening it again (every [`REOPEN_PERIOD`]); true when it came back.
    pub fn retry(&mut self) -> bool {
        if self.port.is_some() || Instant::now() < self.next_try {
            return false;
        }
        self.next_try = Instant::now() + REOPEN_PERIOD;
        match open(&self.path, self.baud) {
            Ok((port, latency)) => {
                self.port = Some(port);
                self.latency = Some(latency);
                self.lost = None;
                true
            }
            Err(_) => false,
        }
    }

    /// Read what is there into `buf` (the device is known readable): `Ok(0)` if nothing, an
    /// error (and the device lost) when it failed.
    pub fn read(&mut self, buf: &mut [u8]) -> Result<usize, String> {
        let Some(fd) = self.fd() else { return Ok(0) };
        match nix::unistd::read(fd, buf) {
            Ok(0) => {
                let why = "the device hung up".to_string();
                self.lose(why.clone());
                Err(why)
            }
            Ok(n) => Ok(n),
            Err(nix::errno::Errno::EAGAIN) | Err(nix::errno::Errno::EINTR) => Ok(0),
            Err(e) => {
                let why = format!("read failed: {e}");
                self.lose(why.clone());
                Err(why)
            }
        }
    }

    /// Write all of `bytes`: true if they went out; false (and the device lost, unless it
    /// merely did not take them within [`WRITE_TIMEOUT`]) if not.
    pub fn write(&mut self, bytes: &[u8]) -> bool {
        let Some(port) = self.port.as_mut() else {
            return false;
        };
        match std::io::Write::write_all(port, bytes) {
            Ok(()) => true,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => false,
            Err(e) => {
                self.lose(format!("write failed: {e}"));
                false
            }
        }
    }

    /// Set the line rate to `baud` bit/s (the hardware check's scan); false if refused.
    pub fn set_baud(&mut self, baud: u32) -> bool {
        let ok = self
            .port
            .as_mut()
            .is_some_and(|p| p.set_baud_rate(baud).is_ok());
        // What is still buffered stays: the next exchange takes it (and drops it), so that a
        // virtual clock's byte counts hold.
        if ok {
            self.baud = baud;
        }
        ok
    }
}
