//! The conductor against a board that keeps the clock rules of `boards/mps2-an386` (consume
//! only released bytes, report when idle), with the firmware core running natively and every
//! line delivering its bytes in random pieces and in random order, as pseudo-terminals and
//! QEMU's one-byte UARTs do. The plants must end up identical whatever the delivery order.

use std::collections::VecDeque;

use ferrobot_firmware::time::{Duration, Instant};
use ferrobot_firmware::{config, Firmware, Link};
use ferrobot_protocol::clock::{Advance, Idle};
use ferrobot_protocol::{encode_frame, Frame, FrameDecoder, MAX_WIRE};
use ferrobot_sim::conductor::{Conductor, LINES};
use ferrobot_sim::hardware::Hardware;
use ferrobot_sim::robots;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The board side of the virtual-time link, as the QEMU board implements it.
struct Board {
    fw: Firmware,
    now: u64,
    release: [u32; 2],
    consumed: [u32; 2],
    sent: [u32; 2],
    rx: [VecDeque<u8>; 2],
    clock: FrameDecoder,
    last: Option<Idle>,
}

impl Board {
    fn new() -> Self {
        let mut profile = config::locobot();
        profile.loop_period = Duration::from_millis(25);
        Board {
            fw: Firmware::new(profile, "fake", Instant::ZERO),
            now: 0,
            release: [0; 2],
            consumed: [0; 2],
            sent: [0; 2],
            rx: Default::default(),
            clock: FrameDecoder::new(),
            last: None,
        }
    }

    fn on_clock(&mut self, bytes: &[u8]) {
        let mut got = Vec::new();
        self.clock
            .feed(bytes, |r: Result<Frame<Advance>, _>| got.extend(r.ok()));
        for f in got {
            self.now = self.now.max(f.msg.now_us);
            self.release = f.msg.release;
        }
    }

    /// The firmware task and the idle loop: consume released bytes, poll when due, send;
    /// returns bytes for each plant line and the clock report, if any.
    fn run(&mut self) -> ([Vec<u8>; 2], Vec<u8>) {
        let now = Instant::from_micros(self.now);
        for (i, link) in LINES.iter().enumerate() {
            let n = (self.release[i].wrapping_sub(self.consumed[i]) as usize).min(self.rx[i].len());
            if n > 0 {
                let bytes: Vec<u8> = self.rx[i].drain(..n).collect();
                self.consumed[i] = self.consumed[i].wrapping_add(n as u32);
                match link {
                    Link::Servo => self.fw.on_servo_bytes(now, &bytes),
                    _ => self.fw.on_base_bytes(now, &bytes),
                }
            }
        }
        if self.fw.next_deadline() <= now {
            self.fw.poll(now);
        }
        let mut out: [Vec<u8>; 2] = Default::default();
        for (i, link) in LINES.iter().enumerate() {
            let p = self.fw.pending(*link).to_vec();
            self.fw.consume(*link, p.len());
            self.sent[i] = self.sent[i].wrapping_add(p.len() as u32);
            out[i] = p;
        }
        let n = self.fw.pending(Link::Host).len();
        self.fw.consume(Link::Host, n);
        let mut report = Vec::new();
        if self.release == self.consumed {
            let idle = Idle {
                now_us: self.now,
                next_us: self.fw.next_deadline().as_micros(),
                rx: self.consumed,
                tx: self.sent,
            };
            if self.last != Some(idle) {
                self.last = Some(idle);
                let mut b = [0u8; MAX_WIRE];
                let n = encode_frame(0, &idle, &mut b).expect("fits");
                report = b[..n].to_vec();
            }
        }
        (out, report)
    }
}

/// Run the LoCoBot's firmware on its own (it configures its servos and runs its loop) to
/// `until_us`, with deliveries shuffled by `seed`; a snapshot of the plants.
fn run(seed: u64, until_us: u64) -> String {
    let desc = robots::by_name("locobot").expect("robot");
    let mut c = Conductor::new(Hardware::new(&desc, 5));
    let mut board = Board::new();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // In flight: conductor → board (clock, servo, base) and board → conductor (clock, servo, base).
    let mut down: [VecDeque<u8>; 3] = Default::default();
    let mut up: [VecDeque<u8>; 3] = Default::default();
    let mut steps = 0u64;
    while c.now_us() < until_us {
        steps += 1;
        assert!(steps < 5_000_000, "no progress at {} us", c.now_us());
        if let Some(next) = c.poll() {
            c.advance(next);
        }
        down[0].extend(c.take_clock_output());
        for (i, link) in LINES.iter().enumerate() {
            down[i + 1].extend(c.take_board_output(*link));
        }
        // Deliver a random piece of a random line, in either direction.
        let k = rng.random_range(0..6);
        let q = if k < 3 { &mut down[k] } else { &mut up[k - 3] };
        let n = rng.random_range(0..=q.len().min(40));
        let piece: Vec<u8> = q.drain(..n).collect();
        match k {
            0 => board.on_clock(&piece),
            1 | 2 => board.rx[k - 1].extend(piece),
            3 => c.on_clock_bytes(&piece),
            _ => c.on_board_bytes(LINES[k - 4], &piece),
        }
        let (out, report) = board.run();
        for (i, b) in out.into_iter().enumerate() {
            up[i + 1].extend(b);
        }
        up[0].extend(report);
    }
    let hw = c.hardware();
    hw.chain.advance_to(until_us);
    let mut s = format!(
        "lines {:?} bus {:?}",
        hw.line_bytes(),
        hw.chain.stats.statuses
    );
    for id in 1..=9 {
        let sv = hw.chain.servo(id).expect("servo");
        s += &format!(" {id}:{:e}/{}", sv.theta, sv.torque_enabled());
    }
    s
}

#[test]
fn the_plants_do_not_depend_on_how_the_lines_deliver() {
    let a = run(1, 3_000_000);
    assert_eq!(a, run(2, 3_000_000));
    assert_eq!(a, run(3, 3_000_000));
    // The firmware really configured the chain (all nine servos hold torque) and then read it
    // every tick: hundreds of status packets went back.
    assert_eq!(a.matches("/true").count(), 9, "{a}");
    let statuses: u64 = a
        .split("bus ")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .expect("count");
    assert!(statuses > 250, "{a}");
}
