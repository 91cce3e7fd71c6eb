//! The async shell of a board whose host link comes and goes (USB CDC-ACM): two futures, to be
//! joined in one task, around one [`Firmware`].
//!
//! * [`Shell::control`] polls the core on its deadlines whatever the host does, moves the bytes
//!   of the servo bus and the base, and drops what the core queues for the host while no host
//!   is connected;
//! * [`Shell::host`] waits for a host, then feeds its bytes into the core and sends the core's
//!   frames out, until the link goes down, and waits again.
//!
//! Waiting for a host, or a host that stops reading, never stops the control loop, so the
//! firmware's watchdog stops the base while the host is away. The board supplies the I/O
//! through [`HostRx`], [`HostTx`], [`Bus`] and [`Clock`].

use core::cell::{Cell, RefCell};
use core::future::{poll_fn, Future};
use core::task::{Poll, Waker};

use embassy_futures::select::{select, select4, Either4};

use crate::log::log_info;
use crate::time::Instant;
use crate::{Firmware, Link};

/// The host link went away (USB unplugged, unconfigured or reset).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Disconnected;

/// The receiving half of a host link whose connection comes and goes.
pub trait HostRx {
    /// Wait until a host is connected.
    fn wait_connection(&mut self) -> impl Future<Output = ()>;
    /// Receive up to `buf.len()` bytes from the host; [`Disconnected`] when it has gone.
    fn read(&mut self, buf: &mut [u8]) -> impl Future<Output = Result<usize, Disconnected>>;
}

/// The sending half of a host link.
pub trait HostTx {
    /// Send `bytes` (at most [`HOST_CHUNK`]) to the host; [`Disconnected`] when it has gone.
    fn write(&mut self, bytes: &[u8]) -> impl Future<Output = Result<(), Disconnected>>;
}

/// A device bus (servo bus or base line).
pub trait Bus {
    /// Receive up to `buf.len()` bytes; 0 after a line error.
    fn read(&mut self, buf: &mut [u8]) -> impl Future<Output = usize>;
    /// Send all of `bytes`; false if they did not go out (they are tried again).
    fn write(&mut self, bytes: &[u8]) -> impl Future<Output = bool>;
}

/// The board's time, from any epoch, never going backwards.
pub trait Clock {
    /// The time now.
    fn now(&self) -> Instant;
    /// Complete at time `t`, or at once if it has passed.
    fn at(&self, t: Instant) -> impl Future<Output = ()>;
}

/// Most bytes one [`HostTx::write`] carries (one full-speed USB bulk packet).
pub const HOST_CHUNK: usize = 64;

/// Most bytes one [`Bus::write`] carries.
pub const BUS_CHUNK: usize = 512;

/// A one-slot wake-up between the two futures of one task.
struct Notify {
    set: Cell<bool>,
    waker: Cell<Option<Waker>>,
}

impl Notify {
    const fn new() -> Self {
        Self {
            set: Cell::new(false),
            waker: Cell::new(None),
        }
    }

    fn notify(&self) {
        self.set.set(true);
        if let Some(w) = self.waker.take() {
            w.wake();
        }
    }

    async fn wait(&self) {
        poll_fn(|cx| {
            if self.set.replace(false) {
                Poll::Ready(())
            } else {
                self.waker.set(Some(cx.waker().clone()));
                Poll::Pending
            }
        })
        .await
    }
}

/// The firmware core and the state its two futures share. Not `Sync`: both futures run in one
/// task (`join`).
pub struct Shell {
    fw: RefCell<Firmware>,
    connected: Cell<bool>,
    /// Host bytes reached the core, or the link went down: the control loop looks again.
    kick: Notify,
    /// The core queued bytes for the host.
    host_ready: Notify,
}

impl Shell {
    /// A shell around `fw`, no host connected yet.
    pub const fn new(fw: Firmware) -> Self {
        Self {
            fw: RefCell::new(fw),
            connected: Cell::new(false),
            kick: Notify::new(),
            host_ready: Notify::new(),
        }
    }

    /// Run `f` on the core. Every borrow ends before the next `.await`, and the two futures
    /// run in one task, so borrows never overlap. Not re-entrant: `f` must not call `with`
    /// (it cannot: it gets the core, not the shell).
    pub fn with<R>(&self, f: impl FnOnce(&mut Firmware) -> R) -> R {
        f(&mut self.fw.borrow_mut())
    }

    /// Whether a host is connected.
    pub fn connected(&self) -> bool {
        self.connected.get()
    }

    /// Drop what the core queued for the host.
    fn drop_host_tx(fw: &mut Firmware) {
        let n = fw.pending(Link::Host).len();
        fw.consume(Link::Host, n);
    }

    /// Send what the core queued on `link`, through `bus`, in chunks of [`BUS_CHUNK`].
    async fn flush(&self, link: Link, bus: &mut impl Bus, chunk: &mut [u8; BUS_CHUNK]) {
        loop {
            let n = self.with(|fw| {
                let p = fw.pending(link);
                let n = p.len().min(BUS_CHUNK);
                if let (Some(dst), Some(src)) = (chunk.get_mut(..n), p.get(..n)) {
                    dst.copy_from_slice(src);
                }
                n
            });
            if n == 0 || !bus.write(chunk.get(..n).unwrap_or_default()).await {
                return;
            }
            self.with(|fw| fw.consume(link, n));
        }
    }

    /// The control loop: polls the core no later than its deadline, exchanges bytes with the
    /// servo bus and the base, and drops host frames while no host is connected. Never
    /// returns.
    pub async fn control(&self, clock: &impl Clock, servo: &mut impl Bus, base: &mut impl Bus) {
        let mut chunk = [0u8; BUS_CHUNK];
        let mut servo_rx = [0u8; 256];
        let mut base_rx = [0u8; 128];
        loop {
            let now = clock.now();
            let connected = self.connected.get();
            let for_host = self.with(|fw| {
                if fw.next_deadline() <= now {
                    fw.poll(now);
                }
                if !connected {
                    Self::drop_host_tx(fw);
                }
                !fw.pending(Link::Host).is_empty()
            });
            if for_host {
                self.host_ready.notify();
            }
            self.flush(Link::Servo, servo, &mut chunk).await;
            self.flush(Link::Base, base, &mut chunk).await;
            let deadline = self.with(|fw| fw.next_deadline());
            match select4(
                servo.read(&mut servo_rx),
                base.read(&mut base_rx),
                clock.at(deadline),
                self.kick.wait(),
            )
            .await
            {
                Either4::First(n) => {
                    let bytes = servo_rx.get(..n).unwrap_or_default();
                    self.with(|fw| fw.on_servo_bytes(clock.now(), bytes));
                }
                Either4::Second(n) => {
                    let bytes = base_rx.get(..n).unwrap_or_default();
                    self.with(|fw| fw.on_base_bytes(clock.now(), bytes));
                }
                Either4::Third(()) | Either4::Fourth(()) => {}
            }
        }
    }

    /// The host link: waits for a host, then feeds its bytes to the core and sends the core's
    /// frames, [`HOST_CHUNK`] bytes at a time, until either direction finds it gone; then
    /// drops what was queued for it and waits again. Never returns.
    pub async fn host(&self, clock: &impl Clock, rx: &mut impl HostRx, tx: &mut impl HostTx) {
        let mut inbound = [0u8; HOST_CHUNK];
        let mut outbound = [0u8; HOST_CHUNK];
        loop {
            rx.wait_connection().await;
            self.connected.set(true);
            log_info!("host link up");
            let receive = async {
                while let Ok(n) = rx.read(&mut inbound).await {
                    let bytes = inbound.get(..n).unwrap_or_default();
                    self.with(|fw| fw.on_host_bytes(clock.now(), bytes));
                    self.kick.notify();
                }
            };
            let send = async {
                loop {
                    let n = self.with(|fw| {
                        let p = fw.pending(Link::Host);
                        let n = p.len().min(HOST_CHUNK);
                        if let (Some(dst), Some(src)) = (outbound.get_mut(..n), p.get(..n)) {
                            dst.copy_from_slice(src);
                        }
                        n
                    });
                    if n == 0 {
                        self.host_ready.wait().await;
                        continue;
                    }
                    if tx
                        .write(outbound.get(..n).unwrap_or_default())
                        .await
                        .is_err()
                    {
                        return;
                    }
                    self.with(|fw| fw.consume(Link::Host, n));
                }
            };
            select(receive, send).await;
            self.connected.set(false);
            log_info!("host link down");
            self.with(Self::drop_host_tx);
            self.kick.notify();
        }
    }
}
