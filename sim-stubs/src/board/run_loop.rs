//! The server thread's loop: step the conductor's clock at the pace allowed, pass what the
//! board wrote to the plants' ports, watch the ports and hand what arrives to the conductor,
//! the plants or the other end of the host link.

use std::collections::VecDeque;
use std::os::fd::{AsRawFd, RawFd};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use ferrobot_firmware::Link;
use nix::poll::{poll, PollFd, PollFlags};

use super::ports::{host_present, line_baud, pty, read_now, write_some, Ports};
use super::wiring::{damage, garble};
use super::{BoardOptions, Inner, SLACK, TICK};
use crate::conductor::LINES;

/// Bytes the host link holds for an end that does not read them yet (a host or a board the
/// machine is slow to run); beyond it they are dropped and counted. A relay that dropped what
/// did not fit in a pseudo-terminal's few kilobytes at once lost an acknowledgement whenever
/// the host's thread waited for a busy core.
const PENDING_MAX: usize = 1 << 20;

/// Index of `link` among the plant lines.
fn idx(link: Link) -> usize {
    usize::from(link != Link::Servo)
}

/// The server thread; returns why it stopped.
pub(super) fn run(p: Ports, inner: &Mutex<Inner>, quit: &AtomicBool, opts: BoardOptions) -> String {
    let mut r = Runner {
        p,
        inner,
        opts,
        buf: [0u8; 4096],
        origin: None,
        host_connected: false,
        last_host_check: Instant::now() - TICK,
        rng: 0x9E37_79B9_7F4A_7C15,
        pending: [VecDeque::new(), VecDeque::new()],
    };
    while !quit.load(Ordering::Relaxed) {
        r.rewire();
        // Step the clock as far as the pace allows.
        let wait = match r.step_clock() {
            Ok(wait) => wait,
            Err(why) => return why,
        };
        if r.last_host_check.elapsed() >= TICK {
            r.last_host_check = Instant::now();
            r.host_connected = host_present(&r.p.host.master);
            r.lock().host_connected = r.host_connected;
            if !r.host_connected {
                // What a host that left did not read is not the next one's.
                r.pending[0].clear();
            }
        }
        r.flush();
        // Look at the ports.
        let watch = r.watched();
        let mut fds: Vec<PollFd> = watch
            .iter()
            .map(|(_, fd)| PollFd::new(*fd, PollFlags::POLLIN))
            .collect();
        let most = if r.pending.iter().any(|q| !q.is_empty()) {
            1
        } else {
            TICK.as_millis()
        };
        let ms = wait.as_micros().div_ceil(1000).min(most) as i32;
        if let Err(e) = poll(&mut fds, ms) {
            if e != nix::errno::Errno::EINTR {
                return format!("poll failed: {e}");
            }
            continue;
        }
        for ((which, _), fd) in watch.iter().zip(&fds) {
            let ready = fd.revents().unwrap_or(PollFlags::empty());
            if !ready.intersects(PollFlags::POLLIN | PollFlags::POLLHUP | PollFlags::POLLERR) {
                continue;
            }
            r.read_port(*which);
        }
    }
    "stopped by its owner".into()
}

/// The loop's state: the ports, the shared state and the pace.
struct Runner<'a> {
    p: Ports,
    inner: &'a Mutex<Inner>,
    opts: BoardOptions,
    buf: [u8; 4096],
    /// Pace: simulated time `origin.1` was released at wall time `origin.0`.
    origin: Option<(Instant, u64)>,
    host_connected: bool,
    last_host_check: Instant,
    /// The damaged lines' generator.
    rng: u64,
    /// Host-link bytes not yet written: to the host, to the board.
    pending: [VecDeque<u8>; 2],
}

impl<'a> Runner<'a> {
    fn lock(&self) -> MutexGuard<'a, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Advance the clock to its next event if the pace allows, then pass the board's clock
    /// and plant output on; how long to wait for the ports, or why the loop must stop.
    fn step_clock(&mut self) -> Result<Duration, String> {
        let rtf = self.opts.real_time_factor;
        let mut wait = TICK;
        let mut i = self.lock();
        let hold = i.hold_at;
        if let Some(next) = i
            .conductor
            .poll()
            .map(|t| t.min(hold))
            .filter(|t| *t > i.conductor.now_us())
        {
            let now = i.conductor.now_us();
            let (wall0, sim0) = *self.origin.get_or_insert((Instant::now(), now));
            let due = if rtf.is_finite() && rtf > 0.0 {
                wall0 + Duration::from_secs_f64((next - sim0) as f64 * 1e-6 / rtf)
            } else {
                Instant::now()
            };
            let wall = Instant::now();
            if due <= wall {
                i.conductor.advance(next);
                if wall > due + SLACK {
                    self.origin = Some((wall, next));
                    i.paced_behind += 1;
                }
                wait = Duration::ZERO;
            } else {
                wait = wait.min(due - wall);
            }
        }
        let clock = i.conductor.take_clock_output();
        if !clock.is_empty() && write_some(&mut self.p.clock.master, &clock) < clock.len() {
            return Err("the board does not read its clock link".into());
        }
        for link in LINES {
            let mut out = i.conductor.take_board_output(link);
            if out.is_empty() {
                continue;
            }
            i.record_plant(link, true, &out);
            let baud = i.wiring.baud[idx(link)];
            damage(&mut out, i.wiring.corruption[idx(link)], &mut self.rng);
            if let Some(port) = self.p.lines[idx(link)].as_mut() {
                if baud.is_some_and(|want| line_baud(&port.master).is_some_and(|b| b != want)) {
                    garble(&mut out);
                }
                write_some(&mut port.master, &out);
            }
        }
        Ok(wait)
    }

    /// Pull and plug the plant lines' cables as the wiring says.
    fn rewire(&mut self) {
        // On every pass: read the wiring in place (no copy), and act only on a change.
        let i = self.lock();
        let wiring = &i.wiring;
        for k in 0..2 {
            if wiring.links[k].is_none() {
                continue;
            }
            match (wiring.plugged[k], self.p.lines[k].is_some()) {
                (false, true) => {
                    self.p.lines[k] = None;
                    wiring.pulled(k);
                }
                (true, false) => {
                    if let Ok(p) = pty(true) {
                        wiring.plugged_in(k, &p.path);
                        self.p.lines[k] = Some(p);
                    }
                }
                _ => {}
            }
        }
    }

    /// The ports to watch, each with its number: 0 clock, 1 servo bus, 2 base, 3 the board's
    /// end of the host link, 4 the host's end.
    fn watched(&self) -> Vec<(usize, RawFd)> {
        let p = &self.p;
        let mut watch = vec![(3usize, p.board_host.master.as_raw_fd())];
        if self.opts.plants {
            watch.push((0, p.clock.master.as_raw_fd()));
            for (k, line) in p.lines.iter().enumerate() {
                if let Some(l) = line {
                    watch.push((k + 1, l.master.as_raw_fd()));
                }
            }
        }
        if self.host_connected {
            watch.push((4, p.host.master.as_raw_fd()));
        }
        watch
    }

    /// Read port `which` (see [`Runner::watched`]), known ready, and deliver what came.
    fn read_port(&mut self, which: usize) {
        let p = &self.p;
        let port = match which {
            0 => &p.clock.master,
            1 | 2 => match p.lines[which - 1].as_ref() {
                Some(l) => &l.master,
                None => return,
            },
            3 => &p.board_host.master,
            _ => &p.host.master,
        };
        let Some(n) = read_now(port, &mut self.buf) else {
            if which == 4 {
                self.host_connected = false;
            }
            return;
        };
        if n == 0 {
            return;
        }
        self.deliver(which, n);
    }

    /// Hand the `n` bytes read from port `which` to their receiver.
    fn deliver(&mut self, which: usize, n: usize) {
        let mut i = self.lock();
        let bytes = &self.buf[..n];
        match which {
            0 => {
                i.conductor.on_clock_bytes(bytes);
                if i.first_report.is_none() && i.conductor.report().is_some() {
                    i.first_report = Some(Instant::now());
                }
            }
            1 | 2 => {
                let link = LINES[which - 1];
                let mut bytes = bytes.to_vec();
                let baud = i.wiring.baud[which - 1];
                let port = self.p.lines[which - 1].as_ref();
                let wrong = |p: &super::ports::Pty| {
                    baud.is_some_and(|want| line_baud(&p.master).is_some_and(|b| b != want))
                };
                if port.is_some_and(wrong) {
                    garble(&mut bytes);
                }
                damage(&mut bytes, i.wiring.corruption[which - 1], &mut self.rng);
                i.record_plant(link, false, &bytes);
                i.conductor.on_board_bytes(link, &bytes);
            }
            3 => {
                i.host_bytes[1] += n as u64;
                i.record_host(false, bytes);
                if self.host_connected {
                    i.host_dropped += queue(&mut self.pending[0], bytes);
                } else {
                    i.host_dropped += n as u64;
                }
            }
            _ => {
                i.host_bytes[0] += n as u64;
                i.record_host(true, bytes);
                i.host_dropped += queue(&mut self.pending[1], bytes);
            }
        }
        drop(i);
        self.flush();
    }

    /// Write what the host link holds for each end, as far as it reads.
    fn flush(&mut self) {
        let ends = [&mut self.p.host.master, &mut self.p.board_host.master];
        for (q, port) in self.pending.iter_mut().zip(ends) {
            while !q.is_empty() {
                let (front, _) = q.as_slices();
                let (len, sent) = (front.len(), write_some(port, front));
                q.drain(..sent);
                if sent < len {
                    break;
                }
            }
        }
    }
}

/// Append `bytes` to `q` as far as [`PENDING_MAX`] allows; how many were dropped.
fn queue(q: &mut VecDeque<u8>, bytes: &[u8]) -> u64 {
    let room = PENDING_MAX.saturating_sub(q.len()).min(bytes.len());
    q.extend(&bytes[..room]);
    (bytes.len() - room) as u64
}
