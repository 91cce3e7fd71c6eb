//! CMSDK APB UART driver: interrupt-driven receive and transmit through rings.

use core::cell::RefCell;

use critical_section::Mutex;
use embassy_sync::waitqueue::AtomicWaker;
use heapless::Deque;

/// The virtual-time link's UART ([`crate::UART4`]).
pub type ClockUart = Uart<512, 1>;

/// Woken on every received byte and whenever transmit space frees up.
pub static ACTIVITY: AtomicWaker = AtomicWaker::new();

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const INTSTATUS: usize = 0x0C;
const BAUDDIV: usize = 0x10;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;
const CTRL_TX_INT: u32 = 1 << 2;
const CTRL_RX_INT: u32 = 1 << 3;
const INT_TX: u32 = 1 << 0;
const INT_RX: u32 = 1 << 1;

struct Rings<const RX: usize, const TX: usize> {
    rx: Deque<u8, RX>,
    tx: Deque<u8, TX>,
    rx_dropped: u32,
    /// Bytes taken out of the receive ring since start, wrapping.
    consumed: u32,
    /// Bytes handed to the data register since start, wrapping.
    sent: u32,
}

/// One CMSDK UART with receive and transmit rings of `RX` and `TX` bytes: by default those of
/// a data line (host link, servo bus, base), which at 1 Mbit/s hold 10 and 20 ms of traffic.
/// A line written by polling only ([`Uart::write_blocking`]) needs no transmit ring.
pub struct Uart<const RX: usize = 1024, const TX: usize = 2048> {
    base: usize,
    rings: Mutex<RefCell<Rings<RX, TX>>>,
}

impl<const RX: usize, const TX: usize> Uart<RX, TX> {
    /// The UART at `base`.
    pub const fn new(base: usize) -> Self {
        Self {
            base,
            rings: Mutex::new(RefCell::new(Rings {
                rx: Deque::new(),
                tx: Deque::new(),
                rx_dropped: 0,
                consumed: 0,
                sent: 0,
            })),
        }
    }

    fn reg(&self, off: usize) -> *mut u32 {
        (self.base + off) as *mut u32
    }

    fn read_reg(&self, off: usize) -> u32 {
        // SAFETY: `base` is a CMSDK UART of the AN386 memory map; its registers are 32-bit MMIO.
        unsafe { core::ptr::read_volatile(self.reg(off)) }
    }

    fn write_reg(&self, off: usize, v: u32) {
        // SAFETY: as in `read_reg`.
        unsafe { core::ptr::write_volatile(self.reg(off), v) }
    }

    /// Enable transmit and receive (and the receive interrupt when `interrupts`). QEMU needs a
    /// baud divider of at least 16.
    pub fn init(&self, interrupts: bool) {
        self.write_reg(BAUDDIV, 16);
        let mut ctrl = CTRL_TX_EN | CTRL_RX_EN;
        if interrupts {
            ctrl |= CTRL_RX_INT;
        }
        self.write_reg(CTRL, ctrl);
    }

    /// Receive interrupt: move bytes to the ring.
    pub fn on_rx_interrupt(&self) {
        // Clear first, then drain: a byte arriving meanwhile raises the interrupt again.
        self.write_reg(INTSTATUS, INT_RX);
        critical_section::with(|cs| {
            let mut r = self.rings.borrow_ref_mut(cs);
            while self.read_reg(STATE) & STATE_RX_FULL != 0 {
                let b = self.read_reg(DATA) as u8;
                if r.rx.push_back(b).is_err() {
                    r.rx_dropped = r.rx_dropped.wrapping_add(1);
                }
            }
        });
        ACTIVITY.wake();
    }

    /// Transmit interrupt: refill the data register from the ring.
    pub fn on_tx_interrupt(&self) {
        self.write_reg(INTSTATUS, INT_TX);
        critical_section::with(|cs| self.pump(&mut self.rings.borrow_ref_mut(cs)));
        ACTIVITY.wake();
    }

    fn pump(&self, r: &mut Rings<RX, TX>) {
        while self.read_reg(STATE) & STATE_TX_FULL == 0 {
            match r.tx.pop_front() {
                Some(b) => {
                    self.write_reg(DATA, b as u32);
                    r.sent = r.sent.wrapping_add(1);
                }
                None => break,
            }
        }
        let ctrl = self.read_reg(CTRL);
        if r.tx.is_empty() {
            self.write_reg(CTRL, ctrl & !CTRL_TX_INT);
        } else {
            self.write_reg(CTRL, ctrl | CTRL_TX_INT);
        }
    }

    /// Take received bytes; returns how many.
    pub fn read(&self, out: &mut [u8]) -> usize {
        self.read_until(out, None)
    }

    /// Take received bytes, but stop once `total` bytes have been taken since start (wrapping);
    /// returns how many.
    pub fn read_until(&self, out: &mut [u8], total: Option<u32>) -> usize {
        critical_section::with(|cs| {
            let mut r = self.rings.borrow_ref_mut(cs);
            let limit = total.map_or(out.len(), |t| {
                (t.wrapping_sub(r.consumed) as usize).min(out.len())
            });
            let mut n = 0;
            while n < limit {
                match r.rx.pop_front() {
                    Some(b) => {
                        out[n] = b;
                        n += 1;
                    }
                    None => break,
                }
            }
            r.consumed = r.consumed.wrapping_add(n as u32);
            n
        })
    }

    /// Bytes taken with [`Uart::read`] and bytes handed to the hardware since start
    /// (wrapping), and whether the transmit ring is empty.
    pub fn counts(&self) -> (u32, u32, bool) {
        critical_section::with(|cs| {
            let r = self.rings.borrow_ref(cs);
            (r.consumed, r.sent, r.tx.is_empty())
        })
    }

    /// Whether received bytes wait that [`Uart::read_until`] with `total` would take.
    pub fn has_rx_until(&self, total: Option<u32>) -> bool {
        critical_section::with(|cs| {
            let r = self.rings.borrow_ref(cs);
            !r.rx.is_empty() && total.is_none_or(|t| t != r.consumed)
        })
    }

    /// Free space in the transmit ring.
    pub fn tx_space(&self) -> usize {
        critical_section::with(|cs| {
            let r = self.rings.borrow_ref(cs);
            r.tx.capacity() - r.tx.len()
        })
    }

    /// Queue bytes for transmission; returns how many fit.
    pub fn write(&self, bytes: &[u8]) -> usize {
        if bytes.is_empty() {
            return 0;
        }
        critical_section::with(|cs| {
            let mut r = self.rings.borrow_ref_mut(cs);
            let mut n = 0;
            for &b in bytes {
                if r.tx.push_back(b).is_err() {
                    break;
                }
                n += 1;
            }
            self.pump(&mut r);
            n
        })
    }

    /// Send bytes by polling (the log).
    pub fn write_blocking(&self, bytes: &[u8]) {
        for &b in bytes {
            while self.read_reg(STATE) & STATE_TX_FULL != 0 {}
            self.write_reg(DATA, b as u32);
        }
    }
}

macro_rules! handlers {
    ($($rx:ident, $tx:ident => $uart:ident;)*) => {$(
        #[no_mangle]
        unsafe extern "C" fn $rx() {
            crate::$uart.on_rx_interrupt();
        }
        #[no_mangle]
        unsafe extern "C" fn $tx() {
            crate::$uart.on_tx_interrupt();
        }
    )*};
}

handlers! {
    UART0RX, UART0TX => UART0;
    UART1RX, UART1TX => UART1;
    UART2RX, UART2TX => UART2;
}

/// The clock link: received bytes go to the virtual clock at once.
#[no_mangle]
unsafe extern "C" fn UART4RX() {
    crate::UART4.on_rx_interrupt();
    crate::clock::on_clock_link(&crate::UART4);
}

#[no_mangle]
unsafe extern "C" fn UART4TX() {
    crate::UART4.on_tx_interrupt();
}
