//! The user LEDs while the board runs (active low, ROBOTIS `variant.cpp`): USER1 blinks once a
//! second while the executor runs (a steady USER1 means a hung board), USER2 is on while a
//! host is connected, USER3 while a fault holds (emergency stop, host watchdog, a servo lost
//! or in hardware error, the base lost or its bumper, cliff or wheel-drop sensors), USER4 is
//! off. When the board halts, `fatal` takes all four over for its blink code.

use embassy_stm32::gpio::{Level, Output, Pin, Speed};
use embassy_stm32::peripherals::{PE4, PE5, PG10, PG12};
use embassy_stm32::Peri;
use embassy_time::Timer;
use ferrobot_firmware::shell::Shell;
use ferrobot_firmware::time;
use ferrobot_protocol::fault_flags as ff;

/// The fault flags that light USER3 (not the passing ones: configuring, loop overrun).
const FAULTS: u16 = ff::ESTOP
    | ff::WATCHDOG
    | ff::SERVO_LOST
    | ff::SERVO_HARDWARE
    | ff::BASE_LOST
    | ff::BASE_SAFETY;

/// How often the LEDs are updated, ms.
const PERIOD_MS: u64 = 250;

/// The four user LEDs.
pub struct Leds {
    heartbeat: Output<'static>,
    host: Output<'static>,
    fault: Output<'static>,
    /// Kept off (and its pin an output) until a halt.
    _spare: Output<'static>,
}

impl Leds {
    /// The LEDs USER1-4, all off.
    pub fn new(
        user1: Peri<'static, PG12>,
        user2: Peri<'static, PE5>,
        user3: Peri<'static, PE4>,
        user4: Peri<'static, PG10>,
    ) -> Self {
        Self {
            heartbeat: off(user1),
            host: off(user2),
            fault: off(user3),
            _spare: off(user4),
        }
    }
}

/// An active-low LED's pin as an output, the LED off.
fn off(pin: Peri<'static, impl Pin>) -> Output<'static> {
    Output::new(pin, Level::High, Speed::Low)
}

/// Light an active-low LED.
fn set(led: &mut Output<'static>, on: bool) {
    led.set_level(if on { Level::Low } else { Level::High });
}

/// Update the LEDs from the shell's state every [`PERIOD_MS`], for ever.
pub async fn run(shell: &Shell, mut leds: Leds) {
    let mut tick = 0u32;
    loop {
        Timer::after_millis(PERIOD_MS).await;
        tick = tick.wrapping_add(1);
        set(&mut leds.heartbeat, tick % 4 < 2);
        set(&mut leds.host, shell.connected());
        let now = time::Instant::from_micros(embassy_time::Instant::now().as_micros());
        let faults = shell.with(|fw| fw.telemetry(now).faults);
        set(&mut leds.fault, faults & FAULTS != 0);
    }
}
