//! Ferrobot firmware for ROBOTIS OpenCR 1.0 (STM32F746ZG, 216 MHz).
//!
//! Pins, from ROBOTIS' OpenCR board support (`variants/OpenCR/hw/driver/drv_uart.c` and
//! `drv_dxl.c`):
//! * host link: USB OTG FS (PA11 D−, PA12 D+) as a CDC-ACM serial port;
//! * Dynamixel TTL bus: USART3 (PC10 TX, PC11 RX, Arduino `Serial3`), half duplex through the
//!   board's buffer whose direction PC9 selects (high: transmit);
//! * base: USART2 (PD5 TX, PD6 RX, Arduino `Serial2`) at 115200 bit/s.
//!
//! The servo bus runs at 4 Mbps and the servo loop at 1 kHz, as in the simulator. It builds and
//! links in CI; it cannot run here.
#![no_std]
#![no_main]

use embassy_executor::Spawner;
use embassy_futures::join::join;
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::peripherals::{USART2, USART3, USB_OTG_FS};
use embassy_stm32::time::Hertz;
use embassy_stm32::usart::{self, BufferedUart};
use embassy_stm32::usb::{self, Driver};
use embassy_stm32::{bind_interrupts, Config};
use embassy_time::{Instant, Timer};
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
});

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

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = embassy_stm32::init(clocks());

    // USB CDC-ACM host link.
    static EP_OUT: StaticCell<[u8; 256]> = StaticCell::new();
    let mut usb_cfg = usb::Config::default();
    usb_cfg.vbus_detection = true;
    let driver = Driver::new_fs(
        p.USB_OTG_FS,
        Irqs,
        p.PA12,
        p.PA11,
        EP_OUT.init([0; 256]),
        usb_cfg,
    );
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
    let (host_tx, host_rx) = class.split();

    // Dynamixel TTL bus, half duplex.
    let mut dxl_cfg = usart::Config::default();
    dxl_cfg.baudrate = 4_000_000;
    static DXL_TX: StaticCell<[u8; 512]> = StaticCell::new();
    static DXL_RX: StaticCell<[u8; 1024]> = StaticCell::new();
    let dxl = BufferedUart::new(
        p.USART3,
        p.PC11,
        p.PC10,
        DXL_TX.init([0; 512]),
        DXL_RX.init([0; 1024]),
        Irqs,
        dxl_cfg,
    )
    .unwrap_or_else(|_| panic!("USART3"));
    let dxl_dir = Output::new(p.PC9, Level::Low, Speed::VeryHigh);

    // Base.
    let mut base_cfg = usart::Config::default();
    base_cfg.baudrate = 115_200;
    static BASE_TX: StaticCell<[u8; 256]> = StaticCell::new();
    static BASE_RX: StaticCell<[u8; 512]> = StaticCell::new();
    let base = BufferedUart::new(
        p.USART2,
        p.PD6,
        p.PD5,
        BASE_TX.init([0; 256]),
        BASE_RX.init([0; 512]),
        Irqs,
        base_cfg,
    )
    .unwrap_or_else(|_| panic!("USART2"));

    let profile = if cfg!(feature = "locobot-lite") {
        config::locobot_lite()
    } else {
        config::locobot()
    };
    let shell = Shell::new(Firmware::new(profile, "opencr", BoardClock.now()));
    let mut servo = Dxl {
        uart: dxl,
        dir: dxl_dir,
    };
    let mut base = Uart(base);
    // The control loop and the host link run side by side: waiting for a host, or a host
    // that stops reading, never stops the control loop (nor the watchdog).
    join(
        shell.control(&BoardClock, &mut servo, &mut base),
        shell.host(&BoardClock, &mut UsbRx(host_rx), &mut UsbTx(host_tx)),
    )
    .await;
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

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}
