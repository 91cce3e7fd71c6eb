//! The conductor: simulated time for a firmware that runs somewhere else (the real board
//! firmware in QEMU), sans-IO. It owns the clock of the [`Hardware`] and grants time to the
//! board over the virtual-time link ([`ferrobot_protocol::clock`]) in steps of at most
//! [`MAX_STEP_US`]: settle (the board [`Idle`] with every byte consumed and delivered), choose
//! the next event, advance (plants, then [`Advance`] to the board); the result does not depend
//! on how fast the machine runs. Design: `docs/design/sim-stubs.md`, "conductor".

use ferrobot_firmware::Link;
use ferrobot_protocol::clock::{Advance, Idle, PLANT_LINES};
use ferrobot_protocol::{encode_frame, Frame, FrameDecoder, MAX_WIRE};

use crate::hardware::Hardware;

/// Longest single step of simulated time, µs: bounds how long the clock rests between
/// steps, so bytes from a real-time host are taken at most this late.
pub const MAX_STEP_US: u64 = 5_000;

/// The plant lines in [`Idle`] order.
pub const LINES: [Link; PLANT_LINES] = [Link::Servo, Link::Base];

fn line_index(link: Link) -> Option<usize> {
    LINES.iter().position(|l| *l == link)
}

/// Counters of a conductor.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ConductorStats {
    /// Time steps granted.
    pub advances: u64,
    /// Idle reports received.
    pub reports: u64,
    /// Frames on the clock link that failed to decode.
    pub bad_clock_frames: u64,
    /// Bytes written to the board on each plant line.
    pub written: [u64; PLANT_LINES],
    /// Bytes read from the board on each plant line.
    pub read: [u64; PLANT_LINES],
}

/// The conductor's state machine (see the module documentation).
pub struct Conductor {
    hw: Hardware,
    now: u64,
    report: Option<Idle>,
    /// Bytes written to / read from the board, per plant line, wrapping like the board's.
    written: [u32; PLANT_LINES],
    read: [u32; PLANT_LINES],
    /// Bytes the board sent at `now`, handed to the plants in one piece once it has settled
    /// (however the pseudo-terminal happened to split them).
    sent: [Vec<u8>; PLANT_LINES],
    decoder: FrameDecoder,
    seq: u16,
    clock_out: Vec<u8>,
    to_board: [Vec<u8>; PLANT_LINES],
    stats: ConductorStats,
}

impl Conductor {
    /// A conductor for `hw`, at time 0, waiting for the board's first report.
    pub fn new(hw: Hardware) -> Self {
        Self {
            hw,
            now: 0,
            report: None,
            written: [0; PLANT_LINES],
            read: [0; PLANT_LINES],
            sent: Default::default(),
            decoder: FrameDecoder::new(),
            seq: 0,
            clock_out: Vec::new(),
            to_board: Default::default(),
            stats: ConductorStats::default(),
        }
    }

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.now
    }

    /// The plants.
    pub fn hardware(&mut self) -> &mut Hardware {
        &mut self.hw
    }

    /// The board's newest report.
    pub fn report(&self) -> Option<Idle> {
        self.report
    }

    /// Counters.
    pub fn stats(&self) -> ConductorStats {
        self.stats
    }

    /// Bytes from the board on the clock link.
    pub fn on_clock_bytes(&mut self, bytes: &[u8]) {
        let mut reports = Vec::new();
        self.decoder
            .feed(bytes, |r: Result<Frame<Idle>, _>| reports.push(r.ok()));
        for r in reports {
            match r {
                Some(f) => {
                    self.stats.reports += 1;
                    self.report = Some(f.msg);
                }
                None => self.stats.bad_clock_frames += 1,
            }
        }
    }

    /// Bytes the board sent on a plant line; they left it at the current time.
    pub fn on_board_bytes(&mut self, link: Link, bytes: &[u8]) {
        let Some(i) = line_index(link) else { return };
        if let (Some(r), Some(s), Some(sent)) = (
            self.read.get_mut(i),
            self.stats.read.get_mut(i),
            self.sent.get_mut(i),
        ) {
            *r = r.wrapping_add(bytes.len() as u32);
            *s += bytes.len() as u64;
            sent.extend_from_slice(bytes);
        }
    }

    /// Advance the exchange with the board. Returns the time the clock may move to next once
    /// the board has settled at the current time, `None` while it has not.
    pub fn poll(&mut self) -> Option<u64> {
        let r = self.report?;
        if r.now_us != self.now || r.tx != self.read || r.rx != self.written {
            return None;
        }
        for (link, bytes) in LINES.iter().zip(self.sent.iter_mut()) {
            if !bytes.is_empty() {
                self.hw.from_firmware(*link, self.now, bytes);
                bytes.clear();
            }
        }
        let plants = self.hw.next_event().unwrap_or(u64::MAX);
        Some(
            r.next_us
                .min(plants)
                .min(self.now + MAX_STEP_US)
                .max(self.now + 1),
        )
    }

    /// Move the clock to `t` (µs), at most to the time [`Conductor::poll`] last returned:
    /// run the plants, tell the board. Does nothing unless the board has settled.
    pub fn advance(&mut self, t: u64) {
        let Some(next) = self.poll() else { return };
        let t = t.clamp(self.now + 1, next);
        self.now = t;
        self.hw.step(t);
        for (i, link) in LINES.iter().enumerate() {
            let bytes = self.hw.to_firmware(*link, t).unwrap_or_default();
            if let (Some(w), Some(s), Some(out)) = (
                self.written.get_mut(i),
                self.stats.written.get_mut(i),
                self.to_board.get_mut(i),
            ) {
                *w = w.wrapping_add(bytes.len() as u32);
                *s += bytes.len() as u64;
                out.extend_from_slice(&bytes);
            }
        }
        self.seq = self.seq.wrapping_add(1);
        let mut buf = [0u8; MAX_WIRE];
        let advance = Advance {
            now_us: t,
            release: self.written,
        };
        if let Ok(n) = encode_frame(self.seq, &advance, &mut buf) {
            self.clock_out
                .extend_from_slice(buf.get(..n).unwrap_or_default());
        }
        self.stats.advances += 1;
    }

    /// Bytes to send to the board on the clock link.
    pub fn take_clock_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.clock_out)
    }

    /// Bytes to send to the board on a plant line.
    pub fn take_board_output(&mut self, link: Link) -> Vec<u8> {
        line_index(link)
            .and_then(|i| self.to_board.get_mut(i))
            .map(std::mem::take)
            .unwrap_or_default()
    }
}
