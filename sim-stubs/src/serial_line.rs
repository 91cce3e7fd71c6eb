//! A one-way serial line with a bit rate: bytes handed over at time `t` arrive when the last
//! of them has been clocked out, after whatever was already on the line.

use std::collections::VecDeque;

/// A timed one-way serial line.
#[derive(Debug, Clone)]
pub struct SerialLine {
    byte_ns: u64,
    busy_until_ns: u64,
    queue: VecDeque<(u64, Vec<u8>)>,
    /// Bytes carried.
    pub bytes: u64,
}

impl SerialLine {
    /// A line at `baud` bit/s (10 bits per byte); 0 means instantaneous.
    pub fn new(baud: u32) -> Self {
        Self {
            byte_ns: if baud == 0 {
                0
            } else {
                10_000_000_000 / baud as u64
            },
            busy_until_ns: 0,
            queue: VecDeque::new(),
            bytes: 0,
        }
    }

    /// Hand over `bytes` at `t_us`; they arrive at the returned time (µs).
    pub fn send(&mut self, t_us: u64, bytes: Vec<u8>) -> u64 {
        if bytes.is_empty() {
            return t_us;
        }
        let start = (t_us * 1000).max(self.busy_until_ns);
        let done = start + bytes.len() as u64 * self.byte_ns;
        self.busy_until_ns = done;
        self.bytes += bytes.len() as u64;
        let at = done.div_ceil(1000);
        self.queue.push_back((at, bytes));
        at
    }

    /// When the next chunk arrives, µs.
    pub fn next_arrival(&self) -> Option<u64> {
        self.queue.front().map(|(t, _)| *t)
    }

    /// Take everything that has arrived by `t_us`.
    pub fn take_arrived(&mut self, t_us: u64) -> Option<Vec<u8>> {
        let mut out: Option<Vec<u8>> = None;
        while let Some((t, _)) = self.queue.front() {
            if *t > t_us {
                break;
            }
            if let Some((_, b)) = self.queue.pop_front() {
                out.get_or_insert_with(Vec::new).extend_from_slice(&b);
            }
        }
        out
    }
}
