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
use embassy_futures::select::{select4, Either4};
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::peripherals::{USART2, USART3, USB_OTG_FS};
use embassy_stm32::time::Hertz;
use embassy_stm32::usart::{self, BufferedUart};
use embassy_stm32::usb::{self, Driver};
use embassy_stm32::{bind_interrupts, Config};
use embassy_time::{Instant, Timer};
use embassy_usb::class::cdc_acm::{CdcAcmClass, State};
use embassy_usb::driver::EndpointError;
use embassy_usb::{Builder, UsbDevice};
use embedded_io_async::Read as _;
use ferrobot_firmware::config;
use ferrobot_firmware::{Firmware, Link};
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
    let (mut host_tx, mut host_rx) = class.split();

    // Dynamixel TTL bus, half duplex.
    let mut dxl_cfg = usart::Config::default();
    dxl_cfg.baudrate = 4_000_000;
    static DXL_TX: StaticCell<[u8; 512]> = StaticCell::new();
    static DXL_RX: StaticCell<[u8; 1024]> = StaticCell::new();
    let mut dxl = BufferedUart::new(
        p.USART3,
        p.PC11,
        p.PC10,
        DXL_TX.init([0; 512]),
        DXL_RX.init([0; 1024]),
        Irqs,
        dxl_cfg,
    )
    .unwrap_or_else(|_| panic!("USART3"));
    let mut dxl_dir = Output::new(p.PC9, Level::Low, Speed::VeryHigh);

    // Base.
    let mut base_cfg = usart::Config::default();
    base_cfg.baudrate = 115_200;
    static BASE_TX: StaticCell<[u8; 256]> = StaticCell::new();
    static BASE_RX: StaticCell<[u8; 512]> = StaticCell::new();
    let mut base = BufferedUart::new(
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
    let mut fw = Firmware::new(profile, "opencr", Instant::now().as_micros());
    let mut host_buf = [0u8; 64];
    let mut dxl_buf = [0u8; 256];
    let mut base_buf = [0u8; 128];
    loop {
        let now = Instant::now().as_micros();
        if fw.next_deadline() <= now {
            fw.poll(now);
        }
        // Servo bus: drive the line only while sending.
        let out = fw.pending(Link::Servo);
        if !out.is_empty() {
            dxl_dir.set_high();
            let ok = embedded_io_async_write(&mut dxl, out).await;
            let n = out.len();
            let _ = embedded_io_async_flush(&mut dxl).await;
            dxl_dir.set_low();
            if ok {
                fw.consume(Link::Servo, n);
            }
        }
        let out = fw.pending(Link::Base);
        if !out.is_empty() {
            let n = out.len();
            if embedded_io_async_write(&mut base, out).await {
                fw.consume(Link::Base, n);
            }
        }
        let out = fw.pending(Link::Host);
        if !out.is_empty() {
            let n = out.len().min(64);
            let sent = host_tx.write_packet(&out[..n]).await;
            match sent {
                Ok(()) => fw.consume(Link::Host, n),
                Err(EndpointError::Disabled) => fw.consume(Link::Host, out.len()), // no host
                Err(_) => {}
            }
        }
        let deadline = fw.next_deadline();
        let wait = Timer::at(Instant::from_micros(deadline));
        match select4(
            host_rx.read_packet(&mut host_buf),
            dxl.read(&mut dxl_buf),
            base.read(&mut base_buf),
            wait,
        )
        .await
        {
            Either4::First(Ok(n)) => fw.on_host_bytes(Instant::now().as_micros(), &host_buf[..n]),
            Either4::First(Err(_)) => host_rx.wait_connection().await,
            Either4::Second(Ok(n)) => fw.on_servo_bytes(Instant::now().as_micros(), &dxl_buf[..n]),
            Either4::Third(Ok(n)) => fw.on_base_bytes(Instant::now().as_micros(), &base_buf[..n]),
            _ => {}
        }
    }
}

async fn embedded_io_async_write<W: embedded_io_async::Write>(w: &mut W, bytes: &[u8]) -> bool {
    w.write_all(bytes).await.is_ok()
}

async fn embedded_io_async_flush<W: embedded_io_async::Write>(w: &mut W) -> bool {
    w.flush().await.is_ok()
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}
