//! Instruction count of the servo-loop tick (feature `tick-bench`).
//!
//! The unmodified firmware core runs the LoCoBot profile at 1 kHz against a scripted servo
//! chain (nine servos answering every sync read from fixed present values) and a scripted
//! Kobuki (a feedback packet every 20th tick). Only the firmware's own calls are timed — `poll`,
//! `on_servo_bytes`, `on_base_bytes` and draining its transmit queues — with the 25 MHz CMSDK
//! timer 0. Under `qemu -icount shift=0` one instruction is 1 ns of virtual time, so the timed
//! nanoseconds are the instructions executed. The result goes out on UART0 as one text line:
//! `ticks=N instructions_per_tick=I worst_tick_instructions=W`.

use ferrobot_firmware::time::{Duration, Instant};
use ferrobot_firmware::{config, Firmware, Link};
use ferrobot_protocol::dxl::{self, inst, PacketDecoder};
use ferrobot_protocol::{
    encode_frame, kobuki, ArmLink, HostMsg, MAX_WIRE, PROTOCOL_VERSION, SCHEMA_HASH,
};

const TIMER0: usize = 0x4000_0000;

fn clocks() -> u32 {
    // SAFETY: CMSDK timer 0 VALUE register, a 32-bit MMIO read.
    u32::MAX - unsafe { core::ptr::read_volatile((TIMER0 + 4) as *const u32) }
}

fn start_clock() {
    // SAFETY: CMSDK timer 0 RELOAD, VALUE and CTRL registers.
    unsafe {
        core::ptr::write_volatile((TIMER0 + 8) as *mut u32, u32::MAX);
        core::ptr::write_volatile((TIMER0 + 4) as *mut u32, u32::MAX);
        core::ptr::write_volatile(TIMER0 as *mut u32, 1);
    }
}

/// Scripted servos: answer ping, write, read and sync read; remember nothing.
struct FakeChain {
    decoder: PacketDecoder<256>,
    out: heapless::Vec<u8, 1024>,
}

impl FakeChain {
    fn status(&mut self, id: u8, params: &[u8]) {
        let mut b = [0u8; 32];
        if let Ok(n) = dxl::status(&mut b, id, 0, params) {
            let _ = self.out.extend_from_slice(&b[..n]);
        }
    }

    fn on_bytes(&mut self, bytes: &[u8]) {
        let mut packets: heapless::Vec<(u8, u8, heapless::Vec<u8, 32>), 4> = heapless::Vec::new();
        for &b in bytes {
            if let Some(Ok(p)) = self.decoder.push(b) {
                let params = heapless::Vec::from_slice(&p.params[..p.params.len().min(32)])
                    .unwrap_or_default();
                let _ = packets.push((p.id, p.instruction, params));
            }
        }
        for (id, ins, p) in packets {
            match ins {
                inst::PING => self.status(id, &[0xFC, 0x03, 46]),
                inst::WRITE | inst::REBOOT => self.status(id, &[]),
                inst::READ => {
                    let n = dxl::le_u16(&p, 2) as usize;
                    let data = 2048u32.to_le_bytes();
                    self.status(id, &data[..n.min(4)]);
                }
                inst::SYNC_READ => {
                    for &sid in p.iter().skip(4) {
                        let mut d = [0u8; 10];
                        d[0..2].copy_from_slice(&12i16.to_le_bytes());
                        d[2..6].copy_from_slice(&3i32.to_le_bytes());
                        d[6..10].copy_from_slice(&2100i32.to_le_bytes());
                        self.status(sid, &d);
                    }
                }
                _ => {}
            }
        }
    }
}

fn kobuki_feedback(k: u32) -> ([u8; 24], usize) {
    let e = (k.wrapping_mul(37)) as u16;
    let d = kobuki::BasicSensorData {
        left_encoder: e,
        right_encoder: e.wrapping_add(5),
        ..Default::default()
    };
    let mut payload = [0u8; 17];
    payload[0] = kobuki::FB_BASIC_SENSOR_DATA;
    payload[1] = 15;
    payload[2..].copy_from_slice(&d.to_bytes());
    let mut b = [0u8; 24];
    let n = kobuki::encode_packet(&payload, &mut b).unwrap_or(0);
    (b, n)
}

/// The arm's gravity model the bench's build was given (`FERROBOT_TICK_BENCH_MODEL`: per
/// link `joint,origin(3),rpy(3),axis(3),mass,com(3)`, links separated by `;`, as the host
/// derives it from the LoCoBot's description); none when it was not given.
fn model() -> heapless::Vec<ArmLink, 8> {
    let mut links = heapless::Vec::new();
    for l in option_env!("FERROBOT_TICK_BENCH_MODEL").unwrap_or("").split(';') {
        let mut v = [0.0f32; 14];
        let mut n = 0;
        for (x, f) in v.iter_mut().zip(l.split(',')) {
            *x = f.trim().parse().unwrap_or(f32::NAN);
            n += 1;
        }
        let t = |i: usize| [v[i], v[i + 1], v[i + 2]];
        if n == 14 {
            let _ = links.push(ArmLink {
                joint: v[0] as u8,
                origin: t(1),
                rpy: t(4),
                axis: t(7),
                mass: v[10],
                com: t(11),
            });
        }
    }
    links
}

/// One host message, as a frame, to the firmware (its answer drained).
fn host(fw: &mut Firmware, now: Instant, seq: u16, m: &HostMsg) {
    let mut buf = [0u8; MAX_WIRE];
    if let Ok(n) = encode_frame(seq, m, &mut buf) {
        fw.on_host_bytes(now, &buf[..n]);
    }
    let n = fw.pending(Link::Host).len();
    fw.consume(Link::Host, n);
}

/// A session with the firmware, as a host opens it, and the arm's gravity model sent.
fn send_model(fw: &mut Firmware, now: Instant) {
    let model = model();
    let mut msgs: heapless::Vec<HostMsg, 9> = heapless::Vec::new();
    let _ = msgs.push(HostMsg::Hello {
        protocol_version: PROTOCOL_VERSION,
        schema_hash: SCHEMA_HASH,
    });
    for (index, &link) in (0u8..).zip(model.iter()) {
        let count = model.len() as u8;
        let _ = msgs.push(HostMsg::ArmLink { index, count, link });
    }
    for (seq, m) in (1u16..).zip(msgs.iter()) {
        host(fw, now, seq, m);
    }
}

/// Run the measurement and report it on UART0.
pub fn run() -> ! {
    start_clock();
    let mut fw = Firmware::new(config::locobot(), "mps2-an386", Instant::ZERO);
    send_model(&mut fw, Instant::ZERO);
    let mut chain = FakeChain {
        decoder: PacketDecoder::new(),
        out: heapless::Vec::new(),
    };
    let mut now = Instant::ZERO;
    // The servos and the base answer 300 µs after the firmware's time.
    let reply = Duration::from_micros(300);
    let mut measured = false;
    let mut timed: u64 = 0;
    let mut worst: u32 = 0;
    let mut ticks: u32 = 0;
    const TICKS: u32 = 1000;
    // One loop iteration is one servo-loop period (1 ms of firmware time).
    while ticks < TICKS {
        now += Duration::from_millis(1);
        let t0 = clocks();
        fw.poll(now);
        let mut spent = clocks().wrapping_sub(t0);
        // Exchange with the servos until the bus is quiet (a configuration reply is followed
        // by the sync read in the same tick); the servos' side is not timed.
        for _ in 0..4 {
            let t = clocks();
            let tx = fw.pending(Link::Servo).len();
            let mut bus = [0u8; 256];
            let tx_bytes = tx.min(256);
            bus[..tx_bytes].copy_from_slice(&fw.pending(Link::Servo)[..tx_bytes]);
            fw.consume(Link::Servo, tx);
            spent = spent.wrapping_add(clocks().wrapping_sub(t));
            if tx == 0 {
                break;
            }
            chain.out.clear();
            chain.on_bytes(&bus[..tx_bytes]);
            let replies = chain.out.clone();
            if !replies.is_empty() {
                let t = clocks();
                fw.on_servo_bytes(now + reply, &replies);
                spent = spent.wrapping_add(clocks().wrapping_sub(t));
            }
        }
        let ms = now.as_micros() / 1000;
        // The host's heartbeat keeps the watchdog fed (not timed: the tick is).
        if ms.is_multiple_of(100) {
            host(&mut fw, now, 100 + ms as u16, &HostMsg::Heartbeat);
        }
        let t1 = clocks();
        if ms.is_multiple_of(20) {
            let (b, n) = kobuki_feedback(ms as u32);
            fw.on_base_bytes(now + reply, &b[..n]);
        }
        for l in [Link::Servo, Link::Base, Link::Host] {
            let n = fw.pending(l).len();
            fw.consume(l, n);
        }
        spent = spent.wrapping_add(clocks().wrapping_sub(t1));
        // Measure once every servo is configured and in the loop.
        if !measured {
            measured = fw
                .bus()
                .servos
                .iter()
                .all(|s| s.status == ferrobot_firmware::bus::ServoStatus::Ok && s.ops == 0);
            continue;
        }
        timed += spent as u64;
        worst = worst.max(spent);
        ticks += 1;
    }
    // 25 MHz timer clocks → ns → instructions (icount shift 0: 1 instruction per ns).
    let per_tick = timed * 40 / TICKS as u64;
    let mut line: heapless::String<96> = heapless::String::new();
    let _ = core::fmt::write(
        &mut line,
        format_args!(
            "ticks={TICKS} instructions_per_tick={per_tick} worst_tick_instructions={}\n",
            worst as u64 * 40
        ),
    );
    crate::UART0.write_blocking(line.as_bytes());
    loop {
        cortex_m::asm::wfi();
    }
}
