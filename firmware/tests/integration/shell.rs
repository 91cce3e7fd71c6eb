//! The async shell (`ferrobot_firmware::shell`, the OpenCR board's loop) against a fake host
//! link that goes down and comes back, fake buses and a hand-driven clock: the control loop
//! keeps polling the core while the host is away, so the watchdog stops the base, and a host
//! that comes back is served again.

use std::cell::{Cell, RefCell};
use std::collections::VecDeque;
use std::future::poll_fn;
use std::rc::Rc;
use std::task::Poll;

use embassy_futures::block_on;
use embassy_futures::join::join;
use embassy_futures::select::select;
use embassy_futures::yield_now;
use ferrobot_firmware::shell::{Bus, Clock, Disconnected, HostRx, HostTx, Shell};
use ferrobot_firmware::time::Instant;
use ferrobot_firmware::{config, Firmware};
use ferrobot_protocol::*;

/// Virtual time, µs: only the test script moves it.
#[derive(Default)]
struct FakeClock(Cell<u64>);

impl FakeClock {
    /// The time now, µs (the script's unit).
    fn micros(&self) -> u64 {
        self.0.get()
    }
}

impl Clock for FakeClock {
    fn now(&self) -> Instant {
        Instant::from_micros(self.0.get())
    }

    async fn at(&self, t: Instant) {
        poll_fn(|cx| {
            if self.now() >= t {
                Poll::Ready(())
            } else {
                cx.waker().wake_by_ref();
                Poll::Pending
            }
        })
        .await
    }
}

/// The host's end of the link.
#[derive(Default)]
struct Wire {
    up: Cell<bool>,
    /// Up, but the host reads nothing: every write waits.
    stalled: Cell<bool>,
    to_fw: RefCell<VecDeque<u8>>,
    from_fw: RefCell<Vec<u8>>,
}

impl Wire {
    fn send(&self, seq: u16, m: &HostMsg) {
        let mut b = [0u8; MAX_WIRE];
        let n = encode_frame(seq, m, &mut b).expect("fits");
        self.to_fw.borrow_mut().extend(&b[..n]);
    }

    /// Every whole frame the firmware sent since the last call.
    fn replies(&self) -> Vec<DeviceMsg> {
        let bytes = std::mem::take(&mut *self.from_fw.borrow_mut());
        let mut out = Vec::new();
        FrameDecoder::new().feed::<DeviceMsg>(&bytes, |f| out.extend(f.ok().map(|f| f.msg)));
        out
    }
}

struct LinkRx(Rc<Wire>);
struct LinkTx(Rc<Wire>);

impl HostRx for LinkRx {
    async fn wait_connection(&mut self) {
        poll_fn(|cx| {
            if self.0.up.get() {
                Poll::Ready(())
            } else {
                cx.waker().wake_by_ref();
                Poll::Pending
            }
        })
        .await
    }

    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Disconnected> {
        poll_fn(|cx| {
            let mut q = self.0.to_fw.borrow_mut();
            if !self.0.up.get() {
                q.clear();
                return Poll::Ready(Err(Disconnected));
            }
            let n = q.len().min(buf.len());
            if n == 0 {
                cx.waker().wake_by_ref();
                return Poll::Pending;
            }
            for (d, s) in buf.iter_mut().zip(q.drain(..n)) {
                *d = s;
            }
            Poll::Ready(Ok(n))
        })
        .await
    }
}

impl HostTx for LinkTx {
    async fn write(&mut self, bytes: &[u8]) -> Result<(), Disconnected> {
        poll_fn(|cx| {
            if !self.0.up.get() {
                Poll::Ready(Err(Disconnected))
            } else if self.0.stalled.get() {
                cx.waker().wake_by_ref();
                Poll::Pending
            } else {
                self.0.from_fw.borrow_mut().extend_from_slice(bytes);
                Poll::Ready(Ok(()))
            }
        })
        .await
    }
}

/// What the firmware wrote on a bus: (time µs, bytes) per write.
type BusLog = RefCell<Vec<(u64, Vec<u8>)>>;

/// A bus that logs what the firmware writes, with the time, and never answers.
struct MuteBus {
    clock: Rc<FakeClock>,
    log: Rc<BusLog>,
}

impl Bus for MuteBus {
    async fn read(&mut self, _buf: &mut [u8]) -> usize {
        poll_fn(|_| Poll::Pending).await
    }

    async fn write(&mut self, bytes: &[u8]) -> bool {
        self.log
            .borrow_mut()
            .push((self.clock.micros(), bytes.to_vec()));
        true
    }
}

/// Every Kobuki base-control command on the base line: (time µs, speed mm/s, radius mm).
fn base_commands(log: &[(u64, Vec<u8>)]) -> Vec<(u64, i16, i16)> {
    let mut p = kobuki::Parser::new();
    let mut out = Vec::new();
    for (t, bytes) in log {
        for &b in bytes {
            if let Some(Ok(payload)) = p.push(b) {
                for (id, d) in kobuki::sub_payloads(payload) {
                    if id == kobuki::CMD_BASE_CONTROL && d.len() == 4 {
                        let speed = i16::from_le_bytes([d[0], d[1]]);
                        let radius = i16::from_le_bytes([d[2], d[3]]);
                        out.push((*t, speed, radius));
                    }
                }
            }
        }
    }
    out
}

fn hello() -> HostMsg {
    HostMsg::Hello {
        protocol_version: PROTOCOL_VERSION,
        schema_hash: SCHEMA_HASH,
    }
}

fn drive(v: f32) -> HostMsg {
    HostMsg::BaseVelocity {
        v,
        w: 0.0,
        duration_ms: 10_000,
    }
}

/// Run the shell (both futures, joined as on the board) beside `script`, on the fake clock.
fn with_shell(script: impl AsyncFnOnce(&Shell, &FakeClock, &Wire, &BusLog, &BusLog)) {
    let clock = Rc::new(FakeClock::default());
    let wire = Rc::new(Wire::default());
    let servo_log = Rc::new(RefCell::new(Vec::new()));
    let base_log = Rc::new(RefCell::new(Vec::new()));
    let shell = Shell::new(Firmware::new(config::locobot(), "test", Instant::ZERO));
    let (mut rx, mut tx) = (LinkRx(wire.clone()), LinkTx(wire.clone()));
    let mut servo = MuteBus {
        clock: clock.clone(),
        log: servo_log.clone(),
    };
    let mut base = MuteBus {
        clock: clock.clone(),
        log: base_log.clone(),
    };
    let board = join(
        shell.control(&*clock, &mut servo, &mut base),
        shell.host(&*clock, &mut rx, &mut tx),
    );
    block_on(select(
        board,
        script(&shell, &clock, &wire, &servo_log, &base_log),
    ));
}

/// Move virtual time to `t` in 100 µs steps, letting the shell run at each.
async fn run_until(clock: &FakeClock, t: u64) {
    while clock.micros() < t {
        clock.0.set(clock.micros() + 100);
        for _ in 0..4 {
            yield_now().await;
        }
    }
}

/// The locobot's watchdog period, µs.
const WATCHDOG_US: u64 = 500_000;

#[test]
fn watchdog_stops_the_base_while_the_host_is_away_and_a_returning_host_drives_again() {
    with_shell(async |shell, clock, wire, _servo_log, base_log| {
        // A host connects, says hello and drives at 0.3 m/s; it refreshes the command at
        // 100 ms.
        wire.up.set(true);
        wire.send(0, &hello());
        wire.send(1, &drive(0.3));
        run_until(clock, 100_000).await;
        wire.send(2, &drive(0.3));
        run_until(clock, 150_000).await;
        let replies = wire.replies();
        assert!(
            matches!(replies.first(), Some(DeviceMsg::Hello(_))),
            "{replies:?}"
        );
        assert!(replies.contains(&DeviceMsg::Ack { seq: 2 }), "{replies:?}");
        let cmds = base_commands(&base_log.borrow());
        assert_eq!(cmds.last().map(|c| (c.1, c.2)), Some((300, 0)), "{cmds:?}");

        // The link goes down at 150 ms; the last host frame arrived at 100 ms.
        wire.up.set(false);
        let last_rx = 100_000;
        run_until(clock, 1_000_000).await;
        let cmds = base_commands(&base_log.borrow());
        // Kobuki takes a command every 20 ms: 0.3 m/s until the watchdog, zero from then on.
        let stop = cmds
            .iter()
            .position(|c| c.0 > 150_000 && (c.1, c.2) == (0, 0))
            .expect("the watchdog sent no stop while the host was away");
        let trip = last_rx + WATCHDOG_US;
        let at = cmds[stop].0;
        assert!(
            (trip..=trip + 1_000).contains(&at),
            "stop sent at {at} µs, watchdog due at {trip} µs"
        );
        assert!(
            cmds[stop..].iter().all(|c| (c.1, c.2) == (0, 0)),
            "{cmds:?}"
        );
        let faults = shell.with(|fw| fw.telemetry(clock.now()).faults);
        assert_ne!(faults & fault_flags::WATCHDOG, 0);
        // The control loop kept polling the core all along: the base took a command in every
        // 50 ms without a host.
        for w in (150_000..1_000_000).step_by(50_000) {
            assert!(
                cmds.iter().any(|c| (w..w + 50_000).contains(&c.0)),
                "no base command in [{w}, {}) µs without a host",
                w + 50_000
            );
        }
        assert!(wire.replies().is_empty());

        // The host comes back at 1 s: a new hello and a new command are obeyed.
        wire.up.set(true);
        wire.send(0, &hello());
        wire.send(1, &drive(0.2));
        run_until(clock, 1_100_000).await;
        let replies = wire.replies();
        assert!(
            matches!(replies.first(), Some(DeviceMsg::Hello(_))),
            "{replies:?}"
        );
        assert!(replies.contains(&DeviceMsg::Ack { seq: 1 }), "{replies:?}");
        let cmds = base_commands(&base_log.borrow());
        let (t, speed, radius) = *cmds.last().expect("commands");
        assert!(t >= 1_000_000 && (speed, radius) == (200, 0), "{cmds:?}");
    });
}

#[test]
fn a_host_that_stops_reading_does_not_stop_the_control_loop() {
    with_shell(async |_shell, clock, wire, _servo_log, base_log| {
        wire.up.set(true);
        wire.send(0, &hello());
        wire.send(1, &drive(0.3));
        run_until(clock, 50_000).await;
        // Still connected, but the host neither reads nor writes: telemetry piles up unsent.
        wire.stalled.set(true);
        run_until(clock, 700_000).await;
        let cmds = base_commands(&base_log.borrow());
        let stop = cmds
            .iter()
            .position(|c| (c.1, c.2) == (0, 0) && c.0 > 0)
            .expect("the watchdog sent no stop while the host did not read");
        assert!(
            (WATCHDOG_US..=WATCHDOG_US + 1_000).contains(&cmds[stop].0),
            "{cmds:?}"
        );
        assert!(
            cmds[stop..].iter().all(|c| (c.1, c.2) == (0, 0)),
            "{cmds:?}"
        );
    });
}
