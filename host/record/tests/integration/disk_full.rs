//! A full disk: the recording stops with a typed error, and what was written before it reads
//! back with the MCAP library's own reader to within a second of the robot's time.

use std::io::{Cursor, Seek, SeekFrom, Write};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ferrobot::Robot;
use ferrobot_record::bag::{Bag, Item, RobotInfo};
use ferrobot_record::RecordError;

/// A disk of `room` bytes: past it every write fails with `StorageFull`. The test keeps a
/// handle on what it holds.
struct SmallDisk {
    data: Arc<Mutex<Cursor<Vec<u8>>>>,
    room: u64,
}

impl Write for SmallDisk {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let mut data = self.data.lock().unwrap();
        if data.position() + buf.len() as u64 > self.room {
            return Err(std::io::Error::new(
                std::io::ErrorKind::StorageFull,
                "no space left on device",
            ));
        }
        data.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for SmallDisk {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.data.lock().unwrap().seek(pos)
    }
}

/// 4 s of the simulated LoCoBot's telemetry and camera frames, in time order.
fn items(robot: &Robot) -> Vec<Item> {
    let tel = robot.subscribe_telemetry(10_000).unwrap();
    let frames = robot.camera().unwrap().subscribe(10_000).unwrap();
    robot.base().unwrap().set_vel(0.2, 0.2, 4.0).unwrap();
    let mut items: Vec<Item> = tel.drain().into_iter().map(Item::Telemetry).collect();
    items.extend(frames.drain().into_iter().map(Item::Frame));
    items.sort_by_key(Item::time);
    items
}

#[test]
fn a_full_disk_is_a_typed_error_and_what_came_before_reads_back() {
    let robot = Robot::new("locobot").unwrap();
    let info = RobotInfo::of(&robot).unwrap();
    let items = items(&robot);
    // 20 MB: one to two seconds of the recording (RGB-D at 30 Hz, lz4-compressed).
    let held = Arc::new(Mutex::new(Cursor::new(Vec::new())));
    let disk = SmallDisk {
        data: held.clone(),
        room: 20_000_000,
    };
    let mut bag = Bag::new(disk, info, Duration::ZERO, 1).unwrap();
    let mut failed_at = None;
    for item in &items {
        match bag.push(item) {
            Ok(()) => {}
            Err(RecordError::DiskFull { written_s }) => {
                failed_at = Some((item.time(), written_s));
                break;
            }
            Err(e) => panic!("not a full disk: {e}"),
        }
    }
    let (at, written_s) = failed_at.expect("the disk never filled");
    assert!(at.as_secs_f64() > 1.0, "filled already at {at:?}");
    let end = bag.finish();
    assert!(matches!(end, Err(RecordError::DiskFull { .. })), "{end:?}");
    // The MCAP library's own reader, message by message, until the bytes end. Where the disk
    // filled, a chunk's lengths may not have been written back: the Rust reader then panics
    // ("capacity overflow") where the Python one reports an error. Either ends the reading.
    let bytes = held.lock().unwrap().get_ref().clone();
    let mut read = 0;
    let mut last = 0u64;
    let mut stream = mcap::MessageStream::new(&bytes).unwrap();
    while let Ok(Some(Ok(m))) =
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| stream.next()))
    {
        read += 1;
        last = last.max(m.log_time);
    }
    let last = last as f64 * 1e-9;
    println!(
        "the disk filled at {:.3} s ({written_s:.3} s written); {read} messages read back, to {last:.3} s",
        at.as_secs_f64()
    );
    assert!(read > 100, "{read} messages read back");
    assert!(
        last >= at.as_secs_f64() - 1.0,
        "read back to {last:.3} s; the disk filled at {at:?}"
    );
}
