//! Ferrobot firmware for QEMU's MPS2 AN386 (Cortex-M4F).
//!
//! * UART0: host link; UART1: Dynamixel servo bus; UART2: mobile base; UART3: defmt log;
//!   UART4: the virtual-time link to the plants' conductor.
//! * Time: simulated time, granted by the conductor beside the simulated plants ([`clock`]):
//!   the firmware and the plants agree on time, and a slow or busy host machine gives the same
//!   results, only later. Thread mode reports to the conductor when the board is idle, then
//!   sleeps in `wfi`.
//! * Tasks run in an embassy `InterruptExecutor` (QEMU does not sleep on `wfe`, so the stock
//!   thread executor would spin the host CPU).
//! * The firmware core is the unmodified `ferrobot-firmware`, fed bytes and time by one task.
//!
//! QEMU's UARTs move about 20 KB/s of wall time, so the servo loop runs at `FERROBOT_LOOP_US`
//! (build-time environment variable, default 25 000 µs) to keep the emulation near real time;
//! everything else (bus timing, telemetry) is the robot's own profile.
#![no_std]
#![no_main]

mod clock;
#[cfg(feature = "tick-bench")]
mod tick_bench;
mod uart;

use core::future::poll_fn;
use core::task::Poll;

use cortex_m::peripheral::NVIC;
use cortex_m_rt::entry;
use embassy_executor::InterruptExecutor;
use embassy_futures::select::select;
use embassy_time::{Instant, Timer};
use ferrobot_firmware::config;
use ferrobot_firmware::time;
use ferrobot_firmware::{Firmware, Link};

use uart::{ClockUart, Uart, ACTIVITY};

/// Interrupts of the AN386 image this firmware uses (AN385 numbering).
#[derive(Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum Interrupt {
    /// UART0 receive.
    UART0RX = 0,
    /// UART0 transmit.
    UART0TX = 1,
    /// UART1 receive.
    UART1RX = 2,
    /// UART1 transmit.
    UART1TX = 3,
    /// UART2 receive.
    UART2RX = 4,
    /// UART2 transmit.
    UART2TX = 5,
    /// UART4 receive.
    UART4RX = 20,
    /// UART4 transmit.
    UART4TX = 21,
    /// An interrupt line no device drives: the executor's.
    EXECUTOR = 30,
}

// SAFETY: the numbers are valid interrupt lines of the AN386 NVIC (fewer than 32 used).
unsafe impl cortex_m::interrupt::InterruptNumber for Interrupt {
    fn number(self) -> u16 {
        self as u16
    }
}

/// A vector-table entry.
pub union Vector {
    handler: unsafe extern "C" fn(),
    reserved: usize,
}

extern "C" {
    fn UART0RX();
    fn UART0TX();
    fn UART1RX();
    fn UART1TX();
    fn UART2RX();
    fn UART2TX();
    fn UART4RX();
    fn UART4TX();
}

/// The device interrupt vectors (cortex-m-rt places them after the exceptions).
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
pub static __INTERRUPTS: [Vector; 32] = {
    const R: Vector = Vector { reserved: 0 };
    let mut v = [R; 32];
    v[0] = Vector { handler: UART0RX };
    v[1] = Vector { handler: UART0TX };
    v[2] = Vector { handler: UART1RX };
    v[3] = Vector { handler: UART1TX };
    v[4] = Vector { handler: UART2RX };
    v[5] = Vector { handler: UART2TX };
    v[20] = Vector { handler: UART4RX };
    v[21] = Vector { handler: UART4TX };
    v[30] = Vector { handler: EXECUTOR };
    v
};

/// Host link, servo bus, base, log.
pub static UART0: Uart = Uart::new(0x4000_4000);
/// Servo bus.
pub static UART1: Uart = Uart::new(0x4000_5000);
/// Base.
pub static UART2: Uart = Uart::new(0x4000_6000);
/// defmt log: written by polling, read never (rings of one byte, unused).
pub static UART3: Uart<1, 1> = Uart::new(0x4000_7000);
/// The virtual-time link to the conductor: `Advance` frames in (a few dozen bytes each, taken
/// at every receive interrupt), idle reports out by polling.
pub static UART4: ClockUart = Uart::new(0x4000_9000);

static EXECUTOR_IRQ: InterruptExecutor = InterruptExecutor::new();

/// Servo-loop period, µs (`FERROBOT_LOOP_US` at build time).
const LOOP_US: u32 = match option_env!("FERROBOT_LOOP_US") {
    Some(s) => parse_u32(s),
    None => 25_000,
};

const fn parse_u32(s: &str) -> u32 {
    let b = s.as_bytes();
    let mut i = 0;
    let mut v = 0u32;
    while i < b.len() {
        v = v * 10 + (b[i] - b'0') as u32;
        i += 1;
    }
    v
}

#[no_mangle]
unsafe extern "C" fn EXECUTOR() {
    // SAFETY: this is the executor's own interrupt, started in `main`.
    unsafe { EXECUTOR_IRQ.on_interrupt() }
}

#[entry]
fn main() -> ! {
    let mut cp = cortex_m::Peripherals::take().unwrap_or_else(|| panic!("peripherals taken twice"));
    for u in [&UART0, &UART1, &UART2] {
        u.init(true);
    }
    UART3.init(false);
    UART4.init(true);
    if cfg!(feature = "tick-bench") {
        #[cfg(feature = "tick-bench")]
        tick_bench::run();
    }
    // Device interrupts preempt the executor.
    // SAFETY: priorities are set before the interrupts are unmasked; nothing relies on them yet.
    unsafe {
        for irq in [
            Interrupt::UART0RX,
            Interrupt::UART0TX,
            Interrupt::UART1RX,
            Interrupt::UART1TX,
            Interrupt::UART2RX,
            Interrupt::UART2TX,
            Interrupt::UART4RX,
            Interrupt::UART4TX,
        ] {
            cp.NVIC.set_priority(irq, 0x20);
            NVIC::unmask(irq);
        }
        cp.NVIC.set_priority(Interrupt::EXECUTOR, 0xE0);
    }
    defmt::info!(
        "ferrobot firmware on mps2-an386, servo loop {=u32} us; waiting for the conductor on UART4",
        LOOP_US
    );
    let spawner = EXECUTOR_IRQ.start(Interrupt::EXECUTOR);
    spawner.spawn(firmware_task().unwrap_or_else(|_| panic!("task arena")));
    let mut report = [0u8; ferrobot_protocol::MAX_WIRE];
    loop {
        // With interrupts masked, decide whether the board is idle; `wfi` still wakes on a
        // pending interrupt, which then runs when they are unmasked.
        cortex_m::interrupt::disable();
        let idle = if NVIC::is_pending(Interrupt::EXECUTOR) {
            None
        } else {
            clock::idle_report(&UART1, &UART2, &mut report)
        };
        if idle.is_none() {
            cortex_m::asm::wfi();
        }
        // SAFETY: re-enables the interrupts masked above; no critical section spans this point.
        unsafe { cortex_m::interrupt::enable() };
        if let Some(n) = idle {
            UART4.write_blocking(report.get(..n).unwrap_or_default());
        }
    }
}

/// How many bytes of `link` the firmware may have consumed by now: all on the host link, the
/// released ones on the plant lines.
fn limit(link: Link, released: [u32; 2]) -> Option<u32> {
    match link {
        Link::Host => None,
        Link::Servo => released.first().copied(),
        Link::Base => released.get(1).copied(),
    }
}

/// Drain a UART's receive ring into the firmware, up to `total` bytes since start.
fn feed(u: &Uart, now: time::Instant, fw: &mut Firmware, link: Link, total: Option<u32>) {
    let mut buf = [0u8; 64];
    loop {
        let n = u.read_until(&mut buf, total);
        if n == 0 {
            return;
        }
        let bytes = buf.get(..n).unwrap_or_default();
        match link {
            Link::Host => fw.on_host_bytes(now, bytes),
            Link::Servo => fw.on_servo_bytes(now, bytes),
            Link::Base => fw.on_base_bytes(now, bytes),
        }
    }
}

#[embassy_executor::task]
async fn firmware_task() {
    let mut profile = if cfg!(feature = "locobot-lite") {
        config::locobot_lite()
    } else {
        config::locobot()
    };
    profile.loop_period = time::Duration::from_micros(u64::from(LOOP_US));
    let mut fw = Firmware::new(
        profile,
        "mps2-an386",
        time::Instant::from_micros(Instant::now().as_micros()),
    );
    let links = [
        (&UART0, Link::Host),
        (&UART1, Link::Servo),
        (&UART2, Link::Base),
    ];
    loop {
        // The time and the bytes released for it, read together.
        let (now_us, released) = clock::now_and_released();
        let now = time::Instant::from_micros(now_us);
        for (u, l) in links {
            feed(u, now, &mut fw, l, limit(l, released));
        }
        if fw.next_deadline() <= now {
            fw.poll(now);
        }
        for (u, l) in links {
            let n = u.write(fw.pending(l));
            fw.consume(l, n);
        }
        let deadline = fw.next_deadline();
        let more_tx = links.iter().any(|(_, l)| !fw.pending(*l).is_empty());
        let activity = poll_fn(|cx| {
            ACTIVITY.register(cx.waker());
            let released = clock::released();
            if links.iter().any(|(u, l)| u.has_rx_until(limit(*l, released)))
                || (more_tx && links.iter().any(|(u, _)| u.tx_space() > 0))
            {
                Poll::Ready(())
            } else {
                Poll::Pending
            }
        });
        if deadline > now {
            let at = Instant::from_micros(deadline.as_micros());
            select(activity, Timer::at(at)).await;
        }
    }
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic");
    loop {
        cortex_m::asm::wfi();
    }
}

defmt::timestamp!("{=u64:us}", Instant::now().as_micros());

/// defmt over UART3, polled.
#[defmt::global_logger]
struct Logger;

static mut ENCODER: defmt::Encoder = defmt::Encoder::new();
static mut CS_RESTORE: critical_section::RestoreState = critical_section::RestoreState::invalid();

// SAFETY: acquire/release bracket every use of ENCODER in a critical section, so it is never
// accessed concurrently; defmt guarantees acquire and release alternate.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        // SAFETY: paired with the release below.
        let restore = unsafe { critical_section::acquire() };
        // SAFETY: inside the critical section, nothing else touches these statics.
        unsafe {
            CS_RESTORE = restore;
            (*core::ptr::addr_of_mut!(ENCODER)).start_frame(|b| UART3.write_blocking(b));
        }
    }
    unsafe fn flush() {}
    unsafe fn release() {
        // SAFETY: inside the critical section opened by acquire.
        unsafe {
            (*core::ptr::addr_of_mut!(ENCODER)).end_frame(|b| UART3.write_blocking(b));
            critical_section::release(CS_RESTORE);
        }
    }
    unsafe fn write(bytes: &[u8]) {
        // SAFETY: inside the critical section opened by acquire.
        unsafe { (*core::ptr::addr_of_mut!(ENCODER)).write(bytes, |b| UART3.write_blocking(b)) }
    }
}
