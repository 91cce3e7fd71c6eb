//! The recorder: the robot's streams into an MCAP file, on a thread of its own.
//!
//! It subscribes to the telemetry, the camera's frames and the robot's events; the robot fills
//! those queues as its time passes and never waits for the recorder. The recorder's thread
//! takes what they hold, in time order, and writes it ([`crate::bag::Bag`]). A disk slower than
//! the robot's streams fills the queues: the oldest items are dropped whole and counted
//! ([`RecordStats`]), and the control loop goes on. On the in-process simulator, whose time
//! is virtual, nothing is dropped: a full queue holds the simulation until the recorder has
//! caught up. Memory is bounded by the queues' lengths.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use ferrobot::subscription::MAX_QUEUE;
use ferrobot::{Bell, Robot, Subscription};
use parking_lot::Mutex;

use crate::bag::{Bag, BagStats, RobotInfo};
use crate::error::{check, RecordError};
use crate::ros2::robot::Feeds;

/// What to record, and how.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordOptions {
    /// Record the camera's frames (when the robot has a camera).
    pub camera: bool,
    /// Frames the queue holds before the oldest is dropped (each 640x480 RGB-D frame is about
    /// 2.1 MB).
    pub frame_queue: usize,
    /// Telemetry reports the queue holds (100 per second of the robot's time).
    pub telemetry_queue: usize,
    /// Events the queue holds.
    pub event_queue: usize,
    /// lz4's level: 1 (fast, the default) to 12 (high compression, slower).
    pub level: u32,
}

impl Default for RecordOptions {
    fn default() -> Self {
        RecordOptions {
            camera: true,
            frame_queue: 16,
            telemetry_queue: 2000,
            event_queue: 2000,
            level: 1,
        }
    }
}

/// How a recording went.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RecordStats {
    /// What was written.
    pub written: BagStats,
    /// Camera frames dropped because the disk fell behind.
    pub frames_dropped: u64,
    /// Telemetry reports dropped because the disk fell behind.
    pub telemetry_dropped: u64,
    /// Events dropped because the disk fell behind.
    pub events_dropped: u64,
}

/// What the disk fell behind on.
fn dropped(feeds: &Feeds, written: BagStats) -> RecordStats {
    RecordStats {
        written,
        frames_dropped: feeds.frames.as_ref().map_or(0, Subscription::dropped),
        telemetry_dropped: feeds.telemetry.dropped(),
        events_dropped: feeds.events.dropped(),
    }
}

/// A recording under way ([`Recorder::start`]); [`Recorder::finish`] ends it.
pub struct Recorder {
    path: PathBuf,
    shared: Shared,
    thread: Option<JoinHandle<Result<RecordStats, RecordError>>>,
}

/// What the thread shares with the handle.
#[derive(Clone)]
struct Shared {
    stop: Arc<AtomicBool>,
    bell: Arc<Bell>,
    stats: Arc<Mutex<RecordStats>>,
}

impl Shared {
    /// Tells the thread to write what is left and end the file.
    fn stop_thread(&self) {
        self.stop.store(true, Ordering::SeqCst);
        self.bell.ring();
    }
}

impl Recorder {
    /// Starts recording `robot` into the new file `path`; a path that exists is
    /// [`std::io::ErrorKind::AlreadyExists`] (nothing is replaced).
    pub fn start(
        robot: &Robot,
        path: impl AsRef<Path>,
        opts: RecordOptions,
    ) -> Result<Recorder, RecordError> {
        check("frame queue", opts.frame_queue, MAX_QUEUE)?;
        check("telemetry queue", opts.telemetry_queue, MAX_QUEUE)?;
        check("event queue", opts.event_queue, MAX_QUEUE)?;
        check("lz4 level", opts.level as usize, 12)?;
        let path = path.as_ref().to_path_buf();
        let info = RobotInfo::of(robot)?;
        let bell = Bell::new();
        let feeds = Feeds {
            telemetry: robot.subscribe_telemetry(opts.telemetry_queue)?,
            frames: match robot.config().camera.is_some() && opts.camera {
                true => Some(robot.camera()?.subscribe(opts.frame_queue)?),
                false => None,
            },
            events: robot.subscribe_events(opts.event_queue)?,
        };
        // On the simulator, nothing is dropped: a full queue holds the robot's virtual time
        // until the recorder catches up (a real robot's refuses, and drops its oldest).
        let lossless = feeds.telemetry.pause_when_full().is_ok();
        feeds.ring(&bell);
        if lossless {
            feeds.events.pause_when_full()?;
        }
        if let Some(f) = feeds.frames.as_ref().filter(|_| lossless) {
            f.pause_when_full()?;
        }
        let file = File::create_new(&path).map_err(|source| RecordError::Io {
            what: "creating",
            path: path.clone(),
            source,
        })?;
        let start = Duration::from_secs_f64(robot.time());
        let bag = Bag::new(
            BufWriter::with_capacity(1 << 20, file),
            info,
            start,
            opts.level,
        )?;
        let shared = Shared {
            stop: Arc::new(AtomicBool::new(false)),
            bell,
            stats: Arc::new(Mutex::new(RecordStats::default())),
        };
        let theirs = shared.clone();
        let thread = std::thread::Builder::new()
            .name("ferrobot-recorder".into())
            .spawn(move || run(bag, feeds, theirs))
            .map_err(|source| RecordError::Io {
                what: "starting the recorder's thread for",
                path: path.clone(),
                source,
            })?;
        Ok(Recorder {
            path,
            shared,
            thread: Some(thread),
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What has been written and dropped so far.
    pub fn stats(&self) -> RecordStats {
        *self.shared.stats.lock()
    }

    /// Writes what the robot delivered until now, ends the file (its summary and footer) and
    /// returns how it went; the first error the recording met, if any (what was written before
    /// it stays readable).
    pub fn finish(mut self) -> Result<RecordStats, RecordError> {
        self.shared.stop_thread();
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            _ => Err(RecordError::Thread),
        }
    }
}

impl Drop for Recorder {
    /// A recorder dropped without [`Recorder::finish`] still ends its file.
    fn drop(&mut self) {
        self.shared.stop_thread();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The recorder's thread: write what arrives until told to stop, then what is left.
fn run<W: std::io::Write + std::io::Seek>(
    mut bag: Bag<W>,
    feeds: Feeds,
    shared: Shared,
) -> Result<RecordStats, RecordError> {
    loop {
        let stopping = shared.stop.load(Ordering::SeqCst);
        let items = feeds.take();
        for item in &items {
            bag.push(item)?;
        }
        *shared.stats.lock() = dropped(&feeds, bag.stats());
        if stopping {
            break;
        }
        if items.is_empty() {
            shared.bell.wait(Duration::from_millis(200));
        }
    }
    let stats = dropped(&feeds, bag.stats());
    bag.finish()?;
    Ok(stats)
}
