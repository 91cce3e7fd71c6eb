//! Ferrobot firmware for ROBOTIS OpenCR 1.0 (STM32F746ZG, 216 MHz).
//!
//! Pins, from ROBOTIS' OpenCR board support (`variants/OpenCR/variant.cpp`,
//! `hw/driver/drv_uart.c` and `drv_dxl.c`) and ROBOTIS' Dynamixel SDK for the board:
//! * host link: USB OTG FS (PA11 D−, PA12 D+) as a CDC-ACM serial port;
//! * Dynamixel TTL bus: USART3 (PC10 TX, PC11 RX, Arduino `Serial3`), half duplex through the
//!   board's buffer whose direction PC9 selects (high: transmit); the servos' power switch is
//!   PF15 (`BDPIN_DXL_PWR_EN`, high: on);
//! * base: USART2 (PD5 TX, PD6 RX, Arduino `Serial2`, the connector marked UART1) at
//!   115200 bit/s;
//! * log: USART6 TX (PC6, Arduino header D1), defmt at 115200 bit/s (`log`);
//! * user LEDs USER1-4 (PG12, PE5, PE4, PG10, active low): heartbeat, host, fault (`status`),
//!   and the halt code (`fatal`).
//!
//! The servo bus runs at 4 Mbps and the servo loop at 1 kHz, as in the simulator. It builds and
//! links in CI; it cannot run here. Flashing, wiring and the log: docs/opencr.md.
#![no_std]
#![no_main]

mod fatal;
mod log;
mod status;

use cortex_m::peripheral::SYST;
use cortex_m_rt::exception;
use embassy_executor::Spawner;
use embassy_futures::join::join3;
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::peripherals::{
    DMA2_CH6, PA11, PA12, PC10, PC11, PC6, PC9, PD5, PD6, USART2, USART3, USART6, USB_OTG_FS,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::usart::{self, BufferedUart, UartTx};
use embassy_stm32::usb::{self, Driver};
use embassy_stm32::{bind_interrupts, dma, Config, Peri};
use embassy_time::{Duration, Instant, Timer};
use embassy_usb::class::cdc_acm::{CdcAcmClass, Receiver, Sender, State};
use embassy_usb::{Builder, UsbDevice};
use embedded_io_async::{Read as _, Write as _};
use ferrobot_firmware::config;
use ferrobot_firmware::shell::{Bus, Clock, Disconnected, HostRx, HostTx, Shell};
use ferrobot_firmware::time;
use ferrobot_firmware::Firmware;
use static_cell::StaticCell;

bind_interrupts!(struct Irqs {
    OTG_FS => usb::InterruptHandler<USB_OTG_FS>;
    USART3 => usart::BufferedInterruptHandler<USART3>;
    USART2 => usart::BufferedInterruptHandler<USART2>;
    DMA2_STREAM6 => dma::InterruptHandler<DMA2_CH6>;
});

/// How long the servos get to boot after their power comes on before the firmware talks to
/// them (ROBOTIS' Dynamixel SDK for OpenCR waits 1 s after `setPowerOn`).
const SERVO_BOOT: Duration = Duration::from_millis(1000);

fn clocks() -> Config {
    use embassy_stm32::rcc::*;
    let mut c = embassy_stm32::Config::default();
    // 25 MHz crystal → PLL 432 MHz VCO: 216 MHz system clock, 48 MHz for USB.
    c.rcc.hse = Some(Hse {
        freq: Hertz(25_000_000),
        mode: HseMode::Oscillator,
    });
    c.rcc.pll_src = PllSource::HSE;
    c.rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV25,
        mul: PllMul::MUL432,
        divp: Some(PllPDiv::DIV2),
        divq: Some(PllQDiv::DIV9),
        divr: None,
    });
    c.rcc.ahb_pre = AHBPrescaler::DIV1;
    c.rcc.apb1_pre = APBPrescaler::DIV4;
    c.rcc.apb2_pre = APBPrescaler::DIV2;
    c.rcc.sys = Sysclk::PLL1_P;
    c.rcc.mux.clk48sel = mux::Clk48sel::PLL1_Q;
    c
}

#[embassy_executor::task]
async fn usb_task(mut dev: UsbDevice<'static, Driver<'static, USB_OTG_FS>>) -> ! {
    dev.run().await
}

/// ROBOTIS' bootloader jumps to the firmware with SysTick still interrupting (its
/// `bsp_deinit` leaves the HAL's tick on), and cortex-m-rt's default handler would take the
/// first tick as a fault: the first tick switches SysTick off instead (this firmware's time
/// comes from one of the MCU's timers, not SysTick).
#[exception]
fn SysTick() {
    // SAFETY: a single write to SysTick's control register, which nothing else here uses;
    // SysTick's registers are always mapped on a Cortex-M.
    unsafe { (*SYST::PTR).csr.write(0) }
}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // The instruction cache: ROBOTIS' bootloader turns it off before the jump, and code runs
    // from flash with 7 wait states at 216 MHz. (Not the data cache: DMA buffers are not kept
    // coherent with it.)
    if let Some(mut core) = cortex_m::Peripherals::take() {
        core.SCB.enable_icache();
    }
    let p = embassy_stm32::init(clocks());
    start_log(spawner, p.USART6, p.PC6, p.DMA2_CH6);
    let profile = if cfg!(feature = "locobot-lite") {
        config::locobot_lite()
    } else {
        config::locobot()
    };
    defmt::info!(
        "boot: ferrobot firmware on OpenCR 1.0 for {=str}",
        profile.robot.as_str()
    );
    // The servos' power first, so that they boot while the rest is set up; kept on for good
    // (dropping the pin would float it, and the switch would open).
    let _servo_power = Output::new(p.PF15, Level::High, Speed::Low);
    let powered_at = Instant::now();
    defmt::info!("boot: Dynamixel power on");
    let leds = status::Leds::new(p.PG12, p.PE5, p.PE4, p.PG10);
    let (host_tx, host_rx) = usb_link(spawner, p.USB_OTG_FS, p.PA12, p.PA11);
    let mut servo = servo_bus(p.USART3, p.PC11, p.PC10, p.PC9);
    let mut base = base_uart(p.USART2, p.PD6, p.PD5);
    Timer::at(powered_at + SERVO_BOOT).await;

    defmt::info!(
        "boot: firmware core started, servo loop {=u64} us; waiting for a host on USB",
        profile.loop_period.as_micros()
    );
    let shell = Shell::new(Firmware::new(profile, "opencr", BoardClock.now()));
    // The control loop, the host link and the LEDs run side by side: waiting for a host, or a
    // host that stops reading, never stops the control loop (nor the watchdog).
    join3(
        shell.control(&BoardClock, &mut servo, &mut base),
        shell.host(&BoardClock, &mut UsbRx(host_rx), &mut UsbTx(host_tx)),
        status::run(&shell, leds),
    )
    .await;
}

/// The log UART (TX only, by DMA) and the task that drains the log into it.
fn start_log(
    spawner: Spawner,
    uart: Peri<'static, USART6>,
    tx: Peri<'static, PC6>,
    dma: Peri<'static, DMA2_CH6>,
) {
    let mut cfg = usart::Config::default();
    cfg.baudrate = log::BAUD;
    let tx = UartTx::new(uart, tx, dma, Irqs, cfg).unwrap_or_else(|_| panic!("USART6"));
    spawner.spawn(log::drain(tx).unwrap_or_else(|_| panic!("task arena")));
}

/// The USB CDC-ACM host link, its device task spawned.
fn usb_link(
    spawner: Spawner,
    otg: Peri<'static, USB_OTG_FS>,
    dp: Peri<'static, PA12>,
    dm: Peri<'static, PA11>,
) -> (Sender<'static, Usb>, Receiver<'static, Usb>) {
    static EP_OUT: StaticCell<[u8; 256]> = StaticCell::new();
    let mut usb_cfg = usb::Config::default();
    usb_cfg.vbus_detection = true;
    let driver = Driver::new_fs(otg, Irqs, dp, dm, EP_OUT.init([0; 256]), usb_cfg);
    let mut cfg = embassy_usb::Config::new(0x16d0, 0x0f3b);
    cfg.manufacturer = Some("Ferrobot");
    cfg.product = Some("Ferrobot OpenCR");
    cfg.max_power = 100;
    cfg.max_packet_size_0 = 64;
    static DESC: StaticCell<[u8; 256]> = StaticCell::new();
    static BOS: StaticCell<[u8; 256]> = StaticCell::new();
    static CTRL: StaticCell<[u8; 64]> = StaticCell::new();
    static CDC: StaticCell<State> = StaticCell::new();
    let mut builder = Builder::new(
        driver,
        cfg,
        DESC.init([0; 256]),
        BOS.init([0; 256]),
        &mut [],
        CTRL.init([0; 64]),
    );
    let class = CdcAcmClass::new(&mut builder, CDC.init(State::new()), 64);
    let usb = builder.build();
    spawner.spawn(usb_task(usb).unwrap_or_else(|_| panic!("task arena")));
    class.split()
}

/// The Dynamixel TTL bus at 4 Mbps, half duplex, the line released.
fn servo_bus(
    uart: Peri<'static, USART3>,
    rx: Peri<'static, PC11>,
    tx: Peri<'static, PC10>,
    dir: Peri<'static, PC9>,
) -> Dxl {
    let mut cfg = usart::Config::default();
    cfg.baudrate = 4_000_000;
    static TX: StaticCell<[u8; 512]> = StaticCell::new();
    static RX: StaticCell<[u8; 1024]> = StaticCell::new();
    let uart = BufferedUart::new(
        uart,
        rx,
        tx,
        TX.init([0; 512]),
        RX.init([0; 1024]),
        Irqs,
        cfg,
    )
    .unwrap_or_else(|_| panic!("USART3"));
    Dxl {
        uart,
        dir: Output::new(dir, Level::Low, Speed::VeryHigh),
    }
}

/// The base's UART at 115200 bit/s.
fn base_uart(uart: Peri<'static, USART2>, rx: Peri<'static, PD6>, tx: Peri<'static, PD5>) -> Uart {
    let mut cfg = usart::Config::default();
    cfg.baudrate = 115_200;
    static TX: StaticCell<[u8; 256]> = StaticCell::new();
    static RX: StaticCell<[u8; 512]> = StaticCell::new();
    let uart = BufferedUart::new(
        uart,
        rx,
        tx,
        TX.init([0; 256]),
        RX.init([0; 512]),
        Irqs,
        cfg,
    )
    .unwrap_or_else(|_| panic!("USART2"));
    Uart(uart)
}

/// Embassy's time driver (1 MHz ticks) as the firmware's clock.
struct BoardClock;

impl Clock for BoardClock {
    fn now(&self) -> time::Instant {
        time::Instant::from_micros(Instant::now().as_micros())
    }

    async fn at(&self, t: time::Instant) {
        Timer::at(Instant::from_micros(t.as_micros())).await
    }
}

type Usb = Driver<'static, USB_OTG_FS>;

/// The CDC-ACM receiver: an endpoint error means the host has gone.
struct UsbRx(Receiver<'static, Usb>);

impl HostRx for UsbRx {
    async fn wait_connection(&mut self) {
        self.0.wait_connection().await
    }

    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Disconnected> {
        self.0.read_packet(buf).await.map_err(|_| Disconnected)
    }
}

/// The CDC-ACM sender.
struct UsbTx(Sender<'static, Usb>);

impl HostTx for UsbTx {
    async fn write(&mut self, bytes: &[u8]) -> Result<(), Disconnected> {
        self.0.write_packet(bytes).await.map_err(|_| Disconnected)
    }
}

/// The half-duplex Dynamixel bus: the board drives the line only while sending.
struct Dxl {
    uart: BufferedUart<'static>,
    dir: Output<'static>,
}

impl Bus for Dxl {
    async fn read(&mut self, buf: &mut [u8]) -> usize {
        self.uart.read(buf).await.unwrap_or(0)
    }

    async fn write(&mut self, bytes: &[u8]) -> bool {
        self.dir.set_high();
        let ok = self.uart.write_all(bytes).await.is_ok();
        // Release the line only once the last byte is out.
        let _ = self.uart.flush().await;
        self.dir.set_low();
        ok
    }
}

/// A full-duplex UART (the base).
struct Uart(BufferedUart<'static>);

impl Bus for Uart {
    async fn read(&mut self, buf: &mut [u8]) -> usize {
        self.0.read(buf).await.unwrap_or(0)
    }

    async fn write(&mut self, bytes: &[u8]) -> bool {
        self.0.write_all(bytes).await.is_ok()
    }
}
