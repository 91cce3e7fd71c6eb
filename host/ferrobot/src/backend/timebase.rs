//! What the serial link's timeouts count: the wall clock for a real board, whose clock runs
//! with it; an emulated board's own clock when the emulator is in this process.
//!
//! An emulated board's time runs as fast as the machine lets its emulator run: beside a busy
//! core it can fall to a tenth of the wall clock's pace, and a firmware that reports every
//! 20 ms of its time then reports every 200 ms of wall time. Counting the link's timeouts
//! (a reply, the firmware's silence) on the wall clock would call such a board lost; counting
//! them on its clock keeps the outcome the same on a quiet or a busy machine. An emulator
//! whose clock stops altogether is caught by [`STALL`] of wall time.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Wall time an emulated board's clock may stand still before the link's timeouts count as
/// passed anyway (its emulator has stopped, or the machine has).
pub const STALL: Duration = Duration::from_secs(20);

/// An emulated board's time now, µs (monotonic).
pub type BoardClock = Arc<dyn Fn() -> u64 + Send + Sync>;

/// The clock a link's timeouts count.
#[derive(Clone, Default)]
pub struct Timebase {
    board: Option<Board>,
}

#[derive(Clone)]
struct Board {
    now_us: BoardClock,
    /// The board's time last read, and the wall time it last changed.
    seen: Arc<Mutex<(u64, Instant)>>,
}

/// A point to measure a timeout from ([`Timebase::mark`]).
#[derive(Clone, Copy, Debug)]
pub struct Mark {
    wall: Instant,
    board_us: Option<u64>,
}

impl Timebase {
    /// The wall clock (a real board).
    pub fn wall() -> Self {
        Timebase { board: None }
    }

    /// An emulated board's clock, read by `now_us`.
    pub fn board(now_us: BoardClock) -> Self {
        let t = now_us();
        Timebase {
            board: Some(Board {
                now_us,
                seen: Arc::new(Mutex::new((t, Instant::now()))),
            }),
        }
    }

    /// Whether timeouts count an emulated board's time.
    pub fn is_board(&self) -> bool {
        self.board.is_some()
    }

    /// The board's time now and how long (wall) it has stood still.
    fn read(b: &Board) -> (u64, Duration) {
        let t = (b.now_us)();
        let mut seen = b.seen.lock().unwrap_or_else(|e| e.into_inner());
        if t != seen.0 {
            *seen = (t, Instant::now());
        }
        (t, seen.1.elapsed())
    }

    /// Now, to measure from.
    pub fn mark(&self) -> Mark {
        Mark {
            wall: Instant::now(),
            board_us: self.board.as_ref().map(|b| Self::read(b).0),
        }
    }

    /// Whether `timeout` has passed since `mark`: of wall time; or, on an emulated board, of
    /// its time, or the board's clock has stood still for [`STALL`] (and at least `timeout`).
    pub fn passed(&self, mark: &Mark, timeout: Duration) -> bool {
        let Some(b) = &self.board else {
            return mark.wall.elapsed() >= timeout;
        };
        let (now, still) = Self::read(b);
        let since = Duration::from_micros(now.saturating_sub(mark.board_us.unwrap_or(now)));
        since >= timeout || (still >= STALL.max(timeout) && mark.wall.elapsed() >= timeout)
    }

    /// Whether `timeout` had passed since `mark` at `at`, a later mark: as [`Timebase::passed`],
    /// judged at `at` rather than now (the stand-still clause still counts to now).
    pub fn passed_by(&self, mark: &Mark, at: &Mark, timeout: Duration) -> bool {
        let Some(b) = &self.board else {
            return at.wall.saturating_duration_since(mark.wall) >= timeout;
        };
        let (now, still) = Self::read(b);
        let at_us = at.board_us.unwrap_or(now);
        let since = Duration::from_micros(at_us.saturating_sub(mark.board_us.unwrap_or(at_us)));
        since >= timeout || (still >= STALL.max(timeout) && mark.wall.elapsed() >= timeout)
    }

    /// How long to wait (wall) before looking at a timeout of `timeout` from `mark` again:
    /// until it passes on the wall clock; on a board's clock, which moves without telling,
    /// at most 20 ms.
    pub fn recheck(&self, mark: &Mark, timeout: Duration) -> Duration {
        let left = timeout.saturating_sub(mark.wall.elapsed());
        match self.board {
            None => left,
            Some(_) => Duration::from_millis(20),
        }
    }

    /// The clock's name in messages: "" for the wall clock, " of the board's time" for a
    /// board's.
    pub fn of(&self) -> &'static str {
        if self.is_board() {
            " of the board's time"
        } else {
            ""
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU64, Ordering};

    #[test]
    fn a_board_clock_counts_its_own_time_not_the_wall_clock() {
        let t = Arc::new(AtomicU64::new(1_000));
        let clock = {
            let t = t.clone();
            Timebase::board(Arc::new(move || t.load(Ordering::Relaxed)))
        };
        let mark = clock.mark();
        std::thread::sleep(Duration::from_millis(30));
        // 30 ms of wall time but 0.5 ms of the board's: 10 ms has not passed.
        t.store(1_500, Ordering::Relaxed);
        assert!(!clock.passed(&mark, Duration::from_millis(10)));
        t.store(11_000, Ordering::Relaxed);
        assert!(clock.passed(&mark, Duration::from_millis(10)));
        // The wall clock counts wall time.
        let wall = Timebase::wall();
        let mark = wall.mark();
        assert!(!wall.passed(&mark, Duration::from_secs(5)));
        std::thread::sleep(Duration::from_millis(12));
        assert!(wall.passed(&mark, Duration::from_millis(10)));
    }

    #[test]
    fn a_timeout_judged_at_a_mark_ignores_the_board_time_after_it() {
        let t = Arc::new(AtomicU64::new(1_000));
        let clock = {
            let t = t.clone();
            Timebase::board(Arc::new(move || t.load(Ordering::Relaxed)))
        };
        let mark = clock.mark();
        t.store(6_000, Ordering::Relaxed);
        let at = clock.mark();
        // The board ran on 1 s while the judge was kept from running: at `at`, 5 ms had passed.
        t.store(1_001_000, Ordering::Relaxed);
        assert!(clock.passed(&mark, Duration::from_millis(10)));
        assert!(!clock.passed_by(&mark, &at, Duration::from_millis(10)));
        assert!(clock.passed_by(&mark, &at, Duration::from_millis(5)));
    }
}
