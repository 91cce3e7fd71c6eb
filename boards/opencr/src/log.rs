//! The board's log: defmt frames out of USART6's TX pin (PC6, pin D1 of the Arduino header;
//! ROBOTIS' `variant.cpp` and e-manual pin map, "UART6_TX") at [`BAUD`] bit/s, 8N1, 3.3 V.
//! Everything the firmware logs goes here: boot, host connect and disconnect, the core's
//! handshakes, rejected commands and faults, and, when the board halts, the panic or fault
//! that stopped it. Read it with a 3.3 V USB-serial adapter and `defmt-print -e ELF`
//! (docs/opencr.md).
//!
//! Why a UART and not defmt-rtt: RTT needs a debug probe on the OpenCR's SWD header, which
//! few users of the board have; a USB-serial adapter is cheap and the same log then works on
//! any robot. Why not the USB link: it carries the host protocol and stops when the board
//! halts.
//!
//! A log line must not hold up the control loop, nor interrupts for long (a 4 Mbps servo reply
//! leaves 2.5 µs per byte): the logger encodes the frame into a buffer of its own inside
//! defmt's critical section, then copies it into a queue in one go; [`drain`] sends the queue
//! out by DMA. A frame that does not fit in the queue is dropped whole. Once the board halts,
//! [`enter_halt`] sends what is queued and switches the logger to blocking writes on the data
//! register, with interrupts off.

use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicBool, Ordering};

use embassy_stm32::mode::Async;
use embassy_stm32::pac;
use embassy_stm32::usart::UartTx;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;

/// The log's baud rate, bit/s.
pub const BAUD: u32 = 115_200;

/// Encoded log bytes waiting for the UART (about 0.2 s of output at [`BAUD`]).
static QUEUE: Pipe<CriticalSectionRawMutex, 2048> = Pipe::new();
/// The board has halted: frames go straight to the data register.
static HALTED: AtomicBool = AtomicBool::new(false);
/// [`drain`] is in a DMA transfer (a halt cuts its frame).
static SENDING: AtomicBool = AtomicBool::new(false);

/// The log UART's registers, for the halt path.
const UART: pac::usart::Usart = pac::USART6;

/// Send the queued log out of `tx`, for ever.
#[embassy_executor::task]
pub async fn drain(mut tx: UartTx<'static, Async>) -> ! {
    let mut chunk = [0u8; 64];
    loop {
        let n = QUEUE.read(&mut chunk).await;
        SENDING.store(true, Ordering::Relaxed);
        // A UART without flow control reports no write errors; a lost chunk is a lost line.
        let _ = tx.write(chunk.get(..n).unwrap_or_default()).await;
        SENDING.store(false, Ordering::Relaxed);
    }
}

/// Write `bytes` on `uart` by polling its data register. Only for the halt path, with
/// interrupts off (no driver then touches the UART); does nothing if the UART is not enabled.
pub fn write_blocking(uart: pac::usart::Usart, bytes: &[u8]) {
    if !uart.cr1().read().ue() {
        return;
    }
    for &b in bytes {
        while !uart.isr().read().txe() {}
        uart.tdr().write(|w| w.set_dr(u16::from(b)));
    }
    while !uart.isr().read().tc() {}
}

/// Switch the log to the halt path: stop the DMA, send what is queued, and from then on write
/// every frame straight to the UART. Call with interrupts disabled.
pub fn enter_halt() {
    if HALTED.swap(true, Ordering::Relaxed) {
        return;
    }
    // No more DMA requests: the CPU owns the data register from here.
    UART.cr3().modify(|w| w.set_dmat(false));
    if SENDING.load(Ordering::Relaxed) {
        // End the frame the DMA was cut in, so that the decoder drops it alone.
        write_blocking(UART, &[0]);
    }
    let mut chunk = [0u8; 64];
    while let Ok(n) = QUEUE.try_read(&mut chunk) {
        write_blocking(UART, chunk.get(..n).unwrap_or_default());
    }
    // SAFETY: interrupts are off and the halt path runs once (HALTED above), so nothing else
    // touches the logger's state: a logger call the halt interrupted (a fault inside it) never
    // resumes. Its frame is abandoned: a fresh encoder starts the next frame with a `0x00`,
    // which ends whatever of the abandoned one went out.
    unsafe {
        let state = &mut *addr_of_mut!(STATE);
        if state.taken {
            state.encoder = defmt::Encoder::new();
            state.taken = false;
        }
    }
}

/// Longest encoded log frame, bytes (a longer one is dropped).
const FRAME: usize = 256;

/// The logger's state, touched only between `acquire` and `release`.
struct State {
    encoder: defmt::Encoder,
    restore: critical_section::RestoreState,
    /// A frame is being written.
    taken: bool,
    /// The frame being encoded, until `release` queues it.
    frame: Frame,
}

/// An encoded frame being built.
struct Frame {
    bytes: [u8; FRAME],
    len: usize,
    /// It outgrew `bytes`: it will be dropped.
    overflow: bool,
}

impl Frame {
    /// Take encoded bytes: straight to the UART once halted, else into the frame.
    fn sink(&mut self, bytes: &[u8]) {
        if HALTED.load(Ordering::Relaxed) {
            write_blocking(UART, bytes);
            return;
        }
        let end = self.len + bytes.len();
        match self.bytes.get_mut(self.len..end) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                self.len = end;
            }
            None => self.overflow = true,
        }
    }
}

static mut STATE: State = State {
    encoder: defmt::Encoder::new(),
    restore: critical_section::RestoreState::invalid(),
    taken: false,
    frame: Frame {
        bytes: [0; FRAME],
        len: 0,
        overflow: false,
    },
};

#[defmt::global_logger]
struct Logger;

// SAFETY: `acquire` opens a critical section that `release` closes, and every use of STATE
// happens between the two, so it is never accessed concurrently (one core; the halt path runs
// with interrupts off); defmt guarantees that acquire and release alternate.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        // SAFETY: paired with the release in `release`.
        let restore = unsafe { critical_section::acquire() };
        // SAFETY: inside the critical section, nothing else touches STATE.
        let state = unsafe { &mut *addr_of_mut!(STATE) };
        state.restore = restore;
        state.taken = true;
        state.frame.len = 0;
        state.frame.overflow = false;
        let frame = &mut state.frame;
        state.encoder.start_frame(|b| frame.sink(b));
    }

    unsafe fn flush() {}

    unsafe fn release() {
        // SAFETY: inside the critical section opened by `acquire`.
        let state = unsafe { &mut *addr_of_mut!(STATE) };
        let frame = &mut state.frame;
        state.encoder.end_frame(|b| frame.sink(b));
        let bytes = frame.bytes.get(..frame.len).unwrap_or_default();
        // Whole or not at all: a frame cut short would garble the next one too.
        if !frame.overflow && QUEUE.free_capacity() >= bytes.len() {
            let _ = QUEUE.try_write(bytes);
        }
        state.taken = false;
        // SAFETY: closes the critical section opened by `acquire`, with its saved state.
        unsafe { critical_section::release(state.restore) };
    }

    unsafe fn write(bytes: &[u8]) {
        // SAFETY: inside the critical section opened by `acquire`.
        let state = unsafe { &mut *addr_of_mut!(STATE) };
        let frame = &mut state.frame;
        state.encoder.write(bytes, |b| frame.sink(b));
    }
}

defmt::timestamp!("{=u64:us}", embassy_time::Instant::now().as_micros());
