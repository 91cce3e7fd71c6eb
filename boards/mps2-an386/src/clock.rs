//! The board's clock: simulated time granted by the plants' conductor over UART4 (the
//! virtual-time link, `ferrobot_protocol::clock`), as an embassy-time driver.
//!
//! The emulated board has no time of its own: [`on_clock_link`] moves it forward when an
//! `Advance` arrives, waking every timer that falls due, and releases the bytes the plants
//! wrote for that time ([`released`]: the firmware consumes no others); [`idle_report`] tells
//! the conductor, once everything due has run, that the board waits and when it next wants to
//! run. Computing takes no simulated time, so the firmware's timing is the same on any host
//! machine, however busy. Ticks are microseconds.

use core::cell::{Cell, RefCell};
use core::task::Waker;

use critical_section::{CriticalSection, Mutex};
use embassy_time_driver::Driver;
use embassy_time_queue_utils::Queue;
use ferrobot_protocol::clock::{Advance, Idle, PLANT_LINES};
use ferrobot_protocol::{encode_frame, Frame, FrameDecoder, MAX_WIRE};

use crate::uart::{ClockUart, Uart, ACTIVITY};

struct VirtualClock {
    now: Mutex<Cell<u64>>,
    release: Mutex<Cell<[u32; PLANT_LINES]>>,
    alarm: Mutex<Cell<u64>>,
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: VirtualClock = VirtualClock {
    now: Mutex::new(Cell::new(0)),
    release: Mutex::new(Cell::new([0; PLANT_LINES])),
    alarm: Mutex::new(Cell::new(u64::MAX)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

impl VirtualClock {
    /// Wake what is due and note the next expiry.
    fn rearm(&self, cs: CriticalSection) {
        let next = self
            .queue
            .borrow_ref_mut(cs)
            .next_expiration(self.now.borrow(cs).get());
        self.alarm.borrow(cs).set(next);
    }
}

impl Driver for VirtualClock {
    fn now(&self) -> u64 {
        critical_section::with(|cs| self.now.borrow(cs).get())
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            if self.queue.borrow_ref_mut(cs).schedule_wake(at, waker) {
                self.rearm(cs);
            }
        })
    }
}

static DECODER: Mutex<RefCell<FrameDecoder>> = Mutex::new(RefCell::new(FrameDecoder::new()));
static RUNNING: Mutex<Cell<bool>> = Mutex::new(Cell::new(false));

/// Take what arrived on the clock link: each `Advance` moves time forward.
pub fn on_clock_link(link: &ClockUart) {
    let mut buf = [0u8; 64];
    loop {
        let n = link.read(&mut buf);
        if n == 0 {
            return;
        }
        for &b in buf.get(..n).unwrap_or_default() {
            let advance = critical_section::with(|cs| {
                match DECODER.borrow_ref_mut(cs).push::<Advance>(b) {
                    Some(Ok(Frame { msg, .. })) => Some(msg),
                    _ => None,
                }
            });
            if let Some(a) = advance {
                let first = critical_section::with(|cs| {
                    let now = DRIVER.now.borrow(cs);
                    now.set(now.get().max(a.now_us));
                    DRIVER.release.borrow(cs).set(a.release);
                    DRIVER.rearm(cs);
                    !RUNNING.borrow(cs).replace(true)
                });
                // Released bytes may already wait in the receive rings.
                ACTIVITY.wake();
                if first {
                    defmt::info!("virtual clock: first step to {=u64} us", a.now_us);
                }
            }
        }
    }
}

/// Bytes released on each plant line so far (servo bus, base), wrapping: the firmware
/// consumes no more.
pub fn released() -> [u32; PLANT_LINES] {
    critical_section::with(|cs| DRIVER.release.borrow(cs).get())
}

/// The time (µs) and the bytes released for it, read together: a byte released by an
/// `Advance` is never consumed at the time before it.
pub fn now_and_released() -> (u64, [u32; PLANT_LINES]) {
    critical_section::with(|cs| (DRIVER.now.borrow(cs).get(), DRIVER.release.borrow(cs).get()))
}

static LAST: Mutex<Cell<Option<Idle>>> = Mutex::new(Cell::new(None));

/// The board is idle (the executor has nothing to run): if every released byte has been
/// consumed, the plant lines' transmit rings are drained and anything changed since the last
/// report, the framed `Idle` report to send on the clock link.
pub fn idle_report(servo: &Uart, base: &Uart, out: &mut [u8; MAX_WIRE]) -> Option<usize> {
    let (s_rx, s_tx, s_empty) = servo.counts();
    let (b_rx, b_tx, b_empty) = base.counts();
    if !(s_empty && b_empty) || released() != [s_rx, b_rx] {
        return None;
    }
    let idle = critical_section::with(|cs| Idle {
        now_us: DRIVER.now.borrow(cs).get(),
        next_us: DRIVER.alarm.borrow(cs).get(),
        rx: [s_rx, b_rx],
        tx: [s_tx, b_tx],
    });
    let changed = critical_section::with(|cs| {
        let last = LAST.borrow(cs);
        let changed = last.get() != Some(idle);
        last.set(Some(idle));
        changed
    });
    if !changed {
        return None;
    }
    // The sequence number is not used by the conductor; the low bits of time keep it varied.
    encode_frame(idle.now_us as u16, &idle, out).ok()
}
