//! The recording's writer, sans thread: the robot's telemetry, frames and events in, MCAP
//! records out through any `Write + Seek` (a file, or a test's sink that fails). The chunks are
//! compressed with lz4, and one is closed at least every [`Bag::flush_every`] of the robot's
//! time, so that a recording cut short (a crash, `kill -9`, a full disk) reads back to within
//! that of its end.

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::time::Duration;

use crate::error::RecordError;
use crate::ros2::robot::Messages;
use crate::topics::Topic;

pub use crate::ros2::robot::{Item, RobotInfo};

/// How much a recording holds so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BagStats {
    /// Messages written.
    pub messages: u64,
    /// Camera frames written.
    pub frames: u64,
    /// Telemetry reports written.
    pub telemetry: u64,
    /// Events written.
    pub events: u64,
    /// Payload bytes written (CDR, before compression).
    pub payload_bytes: u64,
    /// The newest message's time on the robot's clock, ns.
    pub last_ns: u64,
}

/// An MCAP recording being written.
pub struct Bag<W: Write + Seek> {
    mcap: mcap::Writer<W>,
    messages: Messages,
    channels: BTreeMap<&'static str, u16>,
    schemas: BTreeMap<&'static str, u16>,
    sequence: u32,
    /// Close a chunk at least this often (the robot's time).
    pub flush_every: Duration,
    last_flush: Duration,
    stats: BagStats,
    /// The disk filled: every later write is refused as that.
    full: bool,
}

/// Nanoseconds of `t`, as MCAP's times are.
fn ns(t: Duration) -> u64 {
    t.as_nanos().min(u128::from(u64::MAX)) as u64
}

impl<W: Write + Seek> Bag<W> {
    /// A recording of `robot` into `sink`, starting at `start` (the robot's clock): the URDF
    /// and the fixed joints' transforms are written first. lz4 at `level` (1 is fast).
    pub fn new(
        sink: W,
        robot: RobotInfo,
        start: Duration,
        level: u32,
    ) -> Result<Self, RecordError> {
        let mcap = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("ferrobot-record ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Lz4))
            .compression_level(level)
            .chunk_size(Some(4 << 20))
            .create(sink)?;
        let mut bag = Bag {
            mcap,
            messages: Messages::new(robot),
            channels: BTreeMap::new(),
            schemas: BTreeMap::new(),
            sequence: 0,
            flush_every: Duration::from_millis(500),
            last_flush: start,
            stats: BagStats::default(),
            full: false,
        };
        for (topic, data) in bag.messages.latched(start) {
            bag.write(topic, start, &data)?;
        }
        Ok(bag)
    }

    /// What has been written so far.
    pub fn stats(&self) -> BagStats {
        self.stats
    }

    /// Writes one message on `topic` at `t`; its channel (and its type's schema) first, the
    /// first time.
    fn write(&mut self, topic: Topic, t: Duration, data: &[u8]) -> Result<(), RecordError> {
        let channel = match self.channels.get(topic.name) {
            Some(&c) => c,
            None => {
                let schema = match self.schemas.get(topic.msg.name) {
                    Some(&s) => s,
                    None => {
                        let text = topic.msg.schema();
                        let s = self
                            .mcap
                            .add_schema(topic.msg.name, "ros2msg", text.as_bytes())?;
                        self.schemas.insert(topic.msg.name, s);
                        s
                    }
                };
                let c = self
                    .mcap
                    .add_channel(schema, topic.name, "cdr", &BTreeMap::new())?;
                self.channels.insert(topic.name, c);
                c
            }
        };
        self.sequence = self.sequence.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: ns(t),
            publish_time: ns(t),
        };
        self.mcap.write_to_known_channel(&header, data)?;
        self.stats.messages += 1;
        self.stats.payload_bytes += data.len() as u64;
        self.stats.last_ns = self.stats.last_ns.max(ns(t));
        Ok(())
    }

    /// Writes `item`, then closes the chunk if the last was closed
    /// [`Bag::flush_every`] or longer before it. A full disk is [`RecordError::DiskFull`]:
    /// what was written up to the last closed chunk stays readable.
    pub fn push(&mut self, item: &Item) -> Result<(), RecordError> {
        if self.full {
            return Err(self.disk_full());
        }
        self.push_item(item).map_err(|e| self.typed(e))
    }

    /// `e`, or [`RecordError::DiskFull`] when it is the disk filling (remembered: nothing
    /// more is written).
    fn typed(&mut self, e: RecordError) -> RecordError {
        match e {
            RecordError::Mcap(m) if RecordError::is_disk_full(&m) => {
                self.full = true;
                self.disk_full()
            }
            e => e,
        }
    }

    fn disk_full(&self) -> RecordError {
        RecordError::DiskFull {
            written_s: self.stats.last_ns as f64 * 1e-9,
        }
    }

    fn push_item(&mut self, item: &Item) -> Result<(), RecordError> {
        let t = item.time();
        for (topic, data) in self.messages.of(item) {
            self.write(topic, t, &data)?;
        }
        match item {
            Item::Telemetry(_) => self.stats.telemetry += 1,
            Item::Frame(_) => self.stats.frames += 1,
            Item::Event(_) => self.stats.events += 1,
        }
        if t.saturating_sub(self.last_flush) >= self.flush_every {
            self.mcap.flush()?;
            self.last_flush = t;
        }
        Ok(())
    }

    /// Ends the recording: the last chunk, the summary (indexes, statistics) and the footer.
    pub fn finish(mut self) -> Result<BagStats, RecordError> {
        if self.full {
            return Err(self.disk_full());
        }
        match self.mcap.finish() {
            Ok(_) => Ok(self.stats),
            Err(m) => Err(self.typed(m.into())),
        }
    }
}
