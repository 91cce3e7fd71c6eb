//! The host-run firmware's plant lines: the servo bus and the base on their devices, and the
//! clock that says when their bytes may be taken. Shared by the firmware's loop
//! ([`super::runtime`]) and the hardware check ([`super::check`]), which runs first on the
//! same wires and hands them over (a virtual clock's byte counts carry on).

use std::collections::VecDeque;
use std::os::fd::RawFd;
use std::time::Duration;

use nix::poll::{poll, PollFd, PollFlags};

use super::clock::Clock;
use super::device::Device;

/// Index of the servo bus among the plant lines.
pub const SERVO: usize = 0;
/// Index of the base among the plant lines.
pub const BASE: usize = 1;

/// The plant lines and their clock.
pub struct Wires {
    /// The servo bus's device.
    pub servo: Device,
    /// The base's device, for a robot with a base.
    pub base: Option<Device>,
    /// The firmware's clock.
    pub clock: Clock,
    /// Bytes read from each line, not yet taken.
    rx: [VecDeque<u8>; 2],
}

impl Wires {
    /// The lines on these devices and clock.
    pub fn new(servo: Device, base: Option<Device>, clock: Clock) -> Self {
        Wires {
            servo,
            base,
            clock,
            rx: [VecDeque::new(), VecDeque::new()],
        }
    }

    /// The device of line `i`, if there is one.
    pub fn device(&mut self, i: usize) -> Option<&mut Device> {
        if i == SERVO {
            Some(&mut self.servo)
        } else {
            self.base.as_mut()
        }
    }

    /// The time now, µs.
    pub fn now_us(&self) -> u64 {
        self.clock.now_us()
    }

    /// The bytes of line `i` that may be taken now (all of them on the wall clock; those
    /// released on a virtual one).
    pub fn take(&mut self, i: usize) -> Vec<u8> {
        let mut n = self.rx[i].len();
        if let Clock::Virtual(v) = &mut self.clock {
            n = n.min(v.allowance(i));
            v.rx[i] = v.rx[i].wrapping_add(n as u32);
        }
        self.rx[i].drain(..n).collect()
    }

    /// Send `bytes` on line `i`; false if they did not go out (a lost device loses them).
    pub fn send(&mut self, i: usize, bytes: &[u8]) -> bool {
        let sent = self.device(i).is_some_and(|d| d.write(bytes));
        if let (true, Clock::Virtual(v)) = (sent, &mut self.clock) {
            v.tx[i] = v.tx[i].wrapping_add(bytes.len() as u32);
        }
        sent
    }

    /// On a virtual clock, tell the conductor the firmware has nothing to do until `next_us`.
    pub fn idle_until(&mut self, next_us: u64) {
        if let Clock::Virtual(v) = &mut self.clock {
            v.report_idle(next_us);
        }
    }

    /// Wait up to `wait` (on a virtual clock: until its time moves or bytes come) for the
    /// lines, the clock and the `extra` descriptors; take what arrived on the lines and the
    /// clock, reopen lost devices, and return the `extra` descriptors that are ready (by
    /// index). An error when the conductor of a virtual clock has gone.
    pub fn wait(&mut self, wait: Duration, extra: &[RawFd]) -> Result<Vec<usize>, String> {
        let mut fds: Vec<PollFd> = extra
            .iter()
            .map(|fd| PollFd::new(*fd, PollFlags::POLLIN))
            .collect();
        let mut lines = Vec::with_capacity(3);
        for i in [SERVO, BASE] {
            if let Some(fd) = self.device(i).and_then(|d| d.fd()) {
                lines.push(i);
                fds.push(PollFd::new(fd, PollFlags::POLLIN));
            }
        }
        if let Clock::Virtual(v) = &self.clock {
            fds.push(PollFd::new(v.fd(), PollFlags::POLLIN));
        }
        let ms = wait.as_micros().div_ceil(1000).min(i32::MAX as u128) as i32;
        match poll(&mut fds, ms) {
            Ok(_) | Err(nix::errno::Errno::EINTR) => {}
            Err(e) => return Err(format!("poll failed: {e}")),
        }
        let ready = |fd: &PollFd| !fd.revents().unwrap_or(PollFlags::empty()).is_empty();
        let extra_ready: Vec<usize> = (0..extra.len()).filter(|&k| ready(&fds[k])).collect();
        let line_ready: Vec<usize> = lines
            .iter()
            .enumerate()
            .filter(|(k, _)| ready(&fds[extra.len() + k]))
            .map(|(_, &i)| i)
            .collect();
        let clock_ready = fds.len() > extra.len() + lines.len() && ready(&fds[fds.len() - 1]);
        for i in line_ready {
            self.read_line(i);
        }
        if clock_ready {
            if let Clock::Virtual(v) = &mut self.clock {
                if !v.on_link() {
                    return Err("the virtual-time link closed".into());
                }
            }
        }
        self.retry();
        Ok(extra_ready)
    }

    /// Read line `i`'s device, known ready.
    fn read_line(&mut self, i: usize) {
        let mut buf = [0u8; 1024];
        let Some(d) = self.device(i) else { return };
        match d.read(&mut buf) {
            Ok(n) => self.rx[i].extend(&buf[..n]),
            Err(why) => {
                eprintln!("ferrobot: {} lost: {why}", d.path.display());
                self.rx[i].clear();
            }
        }
    }

    /// Open lost devices again; while one is lost, what the conductor releases on its line is
    /// lost on the wire.
    fn retry(&mut self) {
        for i in [SERVO, BASE] {
            let Some(d) = self.device(i) else { continue };
            if d.lost().is_none() {
                continue;
            }
            if d.retry() {
                eprintln!("ferrobot: {} is back", d.path.display());
            } else if let Clock::Virtual(v) = &mut self.clock {
                v.discard(i);
            }
        }
    }
}
