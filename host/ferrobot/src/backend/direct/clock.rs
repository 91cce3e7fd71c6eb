//! The host-run firmware's time: the wall clock on a robot, or simulated time granted by the
//! plants' conductor over a virtual-time link when its devices are emulated
//! ([`ferrobot_protocol::clock`], as the QEMU board's UART4): then the firmware's timing is
//! the same on any machine, however busy.

use std::os::fd::{AsRawFd, RawFd};
use std::time::Instant;

use ferrobot_protocol::clock::{Advance, Idle, PLANT_LINES};
use ferrobot_protocol::{encode_frame, Frame, FrameDecoder, MAX_WIRE};
use serialport::TTYPort;

/// The firmware's clock.
pub enum Clock {
    /// Wall time since the firmware started.
    Wall(Instant),
    /// Simulated time granted by a conductor.
    Virtual(Box<VirtualClock>),
}

/// Simulated time granted over a virtual-time link, and the byte accounting the conductor
/// needs to advance it.
pub struct VirtualClock {
    port: TTYPort,
    decoder: FrameDecoder,
    now_us: u64,
    /// Bytes released on each plant line (servo bus, base), wrapping.
    release: [u32; PLANT_LINES],
    /// Bytes consumed on each plant line, wrapping.
    pub rx: [u32; PLANT_LINES],
    /// Bytes sent on each plant line, wrapping.
    pub tx: [u32; PLANT_LINES],
    last: Option<Idle>,
}

impl VirtualClock {
    /// Time granted on `port` (the board's end of the virtual-time link).
    pub fn new(port: TTYPort) -> Self {
        VirtualClock {
            port,
            decoder: FrameDecoder::new(),
            now_us: 0,
            release: [0; PLANT_LINES],
            rx: [0; PLANT_LINES],
            tx: [0; PLANT_LINES],
            last: None,
        }
    }

    /// The link's file descriptor.
    pub fn fd(&self) -> RawFd {
        self.port.as_raw_fd()
    }

    /// Bytes of plant line `i` the firmware may still consume now.
    pub fn allowance(&self, i: usize) -> usize {
        self.release[i].wrapping_sub(self.rx[i]) as usize
    }

    /// Take what arrived on the link: each `Advance` moves time forward and releases bytes.
    /// False when the link failed (the conductor is gone).
    pub fn on_link(&mut self) -> bool {
        let mut buf = [0u8; 256];
        let n = match nix::unistd::read(self.port.as_raw_fd(), &mut buf) {
            Ok(0) => return false,
            Ok(n) => n,
            Err(nix::errno::Errno::EAGAIN) | Err(nix::errno::Errno::EINTR) => return true,
            Err(_) => return false,
        };
        for &b in &buf[..n] {
            if let Some(Ok(Frame { msg, .. })) = self.decoder.push::<Advance>(b) {
                self.now_us = self.now_us.max(msg.now_us);
                self.release = msg.release;
            }
        }
        true
    }

    /// Tell the conductor the firmware is idle at its time until `next_us`, if anything
    /// changed since the last report: every released byte consumed, nothing left to send.
    pub fn report_idle(&mut self, next_us: u64) {
        if (0..PLANT_LINES).any(|i| self.allowance(i) > 0) {
            return;
        }
        let idle = Idle {
            now_us: self.now_us,
            next_us,
            rx: self.rx,
            tx: self.tx,
        };
        if self.last == Some(idle) {
            return;
        }
        let mut out = [0u8; MAX_WIRE];
        if let Ok(n) = encode_frame(idle.now_us as u16, &idle, &mut out) {
            if std::io::Write::write_all(&mut self.port, &out[..n]).is_ok() {
                self.last = Some(idle);
            }
        }
    }

    /// Count bytes of plant line `i` as consumed without the firmware: they arrived on a
    /// device the firmware had lost (a pulled cable loses what is on it).
    pub fn discard(&mut self, i: usize) {
        self.rx[i] = self.release[i];
    }
}

impl Clock {
    /// The firmware's time now, µs.
    pub fn now_us(&self) -> u64 {
        match self {
            Clock::Wall(start) => start.elapsed().as_micros() as u64,
            Clock::Virtual(v) => v.now_us,
        }
    }
}
