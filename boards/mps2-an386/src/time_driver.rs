//! embassy-time driver on the two CMSDK APB timers (25 MHz): timer 0 counts down from
//! 0xFFFF_FFFF forever and its wrap interrupt extends it to 64 bits; timer 1 is a one-shot
//! alarm for the earliest waker in the queue. Ticks are microseconds.

use core::cell::{Cell, RefCell};
use core::task::Waker;

use critical_section::{CriticalSection, Mutex};
use embassy_time_driver::Driver;
use embassy_time_queue_utils::Queue;

const TIMER0_BASE: usize = 0x4000_0000;
const TIMER1_BASE: usize = 0x4000_1000;
const CTRL: usize = 0x0;
const VALUE: usize = 0x4;
const RELOAD: usize = 0x8;
const INTSTATUS: usize = 0xC;
const CTRL_EN: u32 = 1 << 0;
const CTRL_IRQ_EN: u32 = 1 << 3;
/// Timer clock per microsecond.
const CLOCKS_PER_US: u64 = 25;

fn read(base: usize, off: usize) -> u32 {
    // SAFETY: the CMSDK timers of the AN386 memory map; 32-bit MMIO registers.
    unsafe { core::ptr::read_volatile((base + off) as *const u32) }
}

fn write(base: usize, off: usize, v: u32) {
    // SAFETY: as in `read`.
    unsafe { core::ptr::write_volatile((base + off) as *mut u32, v) }
}

struct CmsdkDriver {
    wraps: Mutex<Cell<u32>>,
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: CmsdkDriver = CmsdkDriver {
    wraps: Mutex::new(Cell::new(0)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

/// Start the clock.
pub fn init() {
    write(TIMER0_BASE, RELOAD, u32::MAX);
    write(TIMER0_BASE, VALUE, u32::MAX);
    write(TIMER0_BASE, CTRL, CTRL_EN | CTRL_IRQ_EN);
    write(TIMER1_BASE, CTRL, 0);
}

impl CmsdkDriver {
    fn now_cs(&self, cs: CriticalSection) -> u64 {
        let v = read(TIMER0_BASE, VALUE);
        let mut wraps = self.wraps.borrow(cs).get() as u64;
        // A wrap that happened but whose interrupt has not run yet: a small elapsed count.
        let elapsed = (u32::MAX - v) as u64;
        if read(TIMER0_BASE, INTSTATUS) & 1 != 0 && elapsed < (1 << 31) {
            wraps += 1;
        }
        ((wraps << 32) | elapsed) / CLOCKS_PER_US
    }

    /// Arm timer 1 for `at`; false if `at` has already passed.
    fn set_alarm(&self, cs: CriticalSection, at: u64) -> bool {
        write(TIMER1_BASE, CTRL, 0);
        write(TIMER1_BASE, INTSTATUS, 1);
        if at == u64::MAX {
            return true;
        }
        let now = self.now_cs(cs);
        if at <= now {
            return false;
        }
        let clocks = ((at - now) * CLOCKS_PER_US).min(u32::MAX as u64) as u32;
        write(TIMER1_BASE, RELOAD, clocks.max(1));
        write(TIMER1_BASE, VALUE, clocks.max(1));
        write(TIMER1_BASE, CTRL, CTRL_EN | CTRL_IRQ_EN);
        true
    }

    fn rearm(&self, cs: CriticalSection) {
        let mut q = self.queue.borrow_ref_mut(cs);
        loop {
            let next = q.next_expiration(self.now_cs(cs));
            if self.set_alarm(cs, next) {
                break;
            }
        }
    }
}

impl Driver for CmsdkDriver {
    fn now(&self) -> u64 {
        critical_section::with(|cs| self.now_cs(cs))
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            let changed = self.queue.borrow_ref_mut(cs).schedule_wake(at, waker);
            if changed {
                self.rearm(cs);
            }
        })
    }
}

#[no_mangle]
unsafe extern "C" fn TIMER0() {
    write(TIMER0_BASE, INTSTATUS, 1);
    critical_section::with(|cs| {
        let w = DRIVER.wraps.borrow(cs);
        w.set(w.get().wrapping_add(1));
    });
}

#[no_mangle]
unsafe extern "C" fn TIMER1() {
    write(TIMER1_BASE, INTSTATUS, 1);
    write(TIMER1_BASE, CTRL, 0);
    critical_section::with(|cs| DRIVER.rearm(cs));
}
