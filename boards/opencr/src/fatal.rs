//! What the board does when it cannot go on (a panic or a hard fault): stop driving, say why,
//! and blink a code for ever.
//!
//! 1. Interrupts off: no driver, no executor and no USB runs again, so nothing more is queued
//!    on any bus and the host sees the link die.
//! 2. The Dynamixel line is released (direction pin PC9 low: the board's buffer stops driving
//!    the bus), so a packet the halt cut in two never completes (its CRC fails) and no further
//!    instruction reaches the servos. The servos keep their power and their last goal: in
//!    position mode each joint holds where it was (the arm does not fall); a joint left in
//!    velocity, current or PWM mode keeps that goal, which only the servo's own Bus Watchdog
//!    (control table address 98, not set by this firmware) or a power cut ends. The firmware
//!    core's host watchdog no longer runs.
//! 3. The base is told to stop (three stop commands on its UART, enough for its parser to
//!    resynchronise after a command the halt cut in two): the Kobuki and Create 2
//!    documentation we read gives neither base a command timeout of its own, so a base left
//!    driving would drive on.
//! 4. The log says what went wrong (the panic's message and location, or the faulting
//!    address), written straight to the log UART.
//! 5. The user LEDs blink the halt code ([`blink_forever`]).
//!
//! An exception or interrupt without a handler halts the board the same way (cortex-m-rt's
//! default handler would spin silently).
//!
//! Only registers are used here (through the PAC): the drivers that own these peripherals
//! never run again, so nothing else touches them.

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m_rt::{exception, ExceptionFrame};
use embassy_stm32::pac;
use embassy_stm32::pac::gpio::vals::Moder;
use embassy_stm32::pac::rcc::vals::Sw;
use ferrobot_protocol::{create2, kobuki};

use crate::log;

/// Set by the first halt; a fault inside the halt path goes straight to the blinking.
static HALTING: AtomicBool = AtomicBool::new(false);

/// Why the board halted: the number of flashes that open each cycle of the blink code.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Halt {
    /// A Rust panic: 2 flashes, then the panic's line number.
    Panic = 2,
    /// A hard fault: 3 flashes.
    HardFault = 3,
    /// An exception or interrupt without a handler: 4 flashes.
    Unexpected = 4,
}

/// The user LEDs, active low (ROBOTIS `variant.cpp`: `setLedOn` writes LOW): USER1 PG12,
/// USER2 PE5, USER3 PE4, USER4 PG10.
const LEDS: [(pac::gpio::Gpio, usize); 4] = [
    (pac::GPIOG, 12),
    (pac::GPIOE, 5),
    (pac::GPIOE, 4),
    (pac::GPIOG, 10),
];

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    let line = info.location().map_or(0, |l| l.line());
    if stop_everything() {
        match info.location() {
            Some(l) => defmt::error!(
                "halted: panic at {=str}:{=u32}: {}",
                l.file(),
                l.line(),
                defmt::Display2Format(&info.message())
            ),
            None => defmt::error!("halted: panic: {}", defmt::Display2Format(&info.message())),
        }
    }
    blink_forever(Halt::Panic, line)
}

// SAFETY (of the `unsafe fn` the attribute requires): the handler only reads the stacked
// frame it is given and never returns.
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    if stop_everything() {
        defmt::error!(
            "halted: hard fault at pc {=u32:#010x}, lr {=u32:#010x}",
            frame.pc(),
            frame.lr()
        );
    }
    blink_forever(Halt::HardFault, 0)
}

// SAFETY (of the `unsafe fn` the attribute requires): the handler never returns, so the
// exception it was given is never resumed.
#[exception]
unsafe fn DefaultHandler(irqn: i16) -> ! {
    if stop_everything() {
        defmt::error!(
            "halted: exception or interrupt {=i16} without a handler",
            irqn
        );
    }
    blink_forever(Halt::Unexpected, 0)
}

/// Steps 1 to 3 of the module's list, and the log's switch to blocking writes; false if the
/// board was already halting (a fault in the halt path), which then only blinks.
fn stop_everything() -> bool {
    cortex_m::interrupt::disable();
    if HALTING.swap(true, Ordering::Relaxed) {
        return false;
    }
    // Release the Dynamixel line (a no-op if PC9 was never made an output: then it never
    // drove the bus).
    pac::GPIOC.bsrr().write(|w| w.set_br(9, true));
    stop_base();
    log::enter_halt();
    true
}

/// Send the base's stop command three times on USART2 (if it was ever enabled).
fn stop_base() {
    let mut stop = [0u8; 16];
    let n = if cfg!(feature = "locobot-lite") {
        let cmd = create2::drive_direct(0, 0);
        if let Some(s) = stop.get_mut(..cmd.len()) {
            s.copy_from_slice(&cmd);
        }
        cmd.len()
    } else {
        kobuki::encode_base_control(0, 0, &mut stop).unwrap_or(0)
    };
    for _ in 0..3 {
        log::write_blocking(pac::USART2, stop.get(..n).unwrap_or_default());
    }
}

/// CPU cycles per millisecond, from the clock the core runs on (the halt may come before or
/// after `embassy_stm32::init` set up the PLL).
fn cycles_per_ms() -> u32 {
    match pac::RCC.cfgr().read().sws() {
        Sw::PLL1_P => 216_000,
        Sw::HSE => 25_000,
        _ => 16_000,
    }
}

/// Wait about `ms` milliseconds (a Cortex-M7 retires about one iteration of the delay loop
/// per cycle; the code needs no better).
fn sleep_ms(ms: u32) {
    cortex_m::asm::delay(cycles_per_ms().saturating_mul(ms));
}

/// Set the LEDs in `mask` (bit i: USER(i+1)) on and the others off.
fn leds(mask: u8) {
    for (i, (port, pin)) in LEDS.into_iter().enumerate() {
        let on = mask & (1 << i) != 0;
        // Active low: on is low (reset), off is high (set).
        port.bsrr().write(|w| {
            w.set_br(pin, on);
            w.set_bs(pin, !on);
        });
    }
}

/// `n` flashes of the LEDs in `mask`, `on_ms` on and `off_ms` off each.
fn flash(mask: u8, n: u32, on_ms: u32, off_ms: u32) {
    for _ in 0..n {
        leds(mask);
        sleep_ms(on_ms);
        leds(0);
        sleep_ms(off_ms);
    }
}

/// Blink the halt code for ever: each cycle, all four user LEDs flash `kind` times (2 panic,
/// 3 hard fault, 4 unexpected exception or interrupt); for a panic, USER1 then blinks each decimal digit of the panic's line
/// number (a digit d as d blinks, 0 as ten, a pause between digits); then a long pause.
fn blink_forever(kind: Halt, line: u32) -> ! {
    // The LED pins as outputs, whether or not `main` got as far as setting them up.
    pac::RCC.ahb1enr().modify(|w| {
        w.set_gpioeen(true);
        w.set_gpiogen(true);
    });
    for (port, pin) in LEDS {
        port.moder().modify(|w| w.set_moder(pin, Moder::OUTPUT));
    }
    let mut digits = [0u8; 10];
    let mut count = 0;
    let mut rest = line;
    while rest > 0 && count < digits.len() {
        if let Some(d) = digits.get_mut(count) {
            *d = (rest % 10) as u8;
        }
        rest /= 10;
        count += 1;
    }
    loop {
        flash(0b1111, kind as u32, 150, 150);
        if kind == Halt::Panic {
            sleep_ms(1000);
            for &d in digits.iter().take(count).rev() {
                let blinks = if d == 0 { 10 } else { u32::from(d) };
                flash(0b0001, blinks, 200, 300);
                sleep_ms(800);
            }
        }
        sleep_ms(2000);
    }
}
