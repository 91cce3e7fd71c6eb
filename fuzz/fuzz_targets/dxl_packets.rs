//! Dynamixel packets: the packet decoder alone, then the firmware's bus master fed the bytes
//! as servo replies while it runs its loop. Nothing may panic.
#![cfg_attr(fuzzing, no_main)]
use ferrobot_firmware::time::{Duration, Instant};
use ferrobot_firmware::{config, Firmware, Link};
use ferrobot_protocol::dxl::PacketDecoder;

ferrobot_fuzz::target!(run);

/// One input.
fn run(data: &[u8]) {
    let mut d = PacketDecoder::<256>::new();
    for &b in data {
        let _ = d.push(b);
    }
    // The bulk path must agree with the byte path on every packet.
    let mut by_byte = 0u32;
    let mut d = PacketDecoder::<256>::new();
    for &b in data {
        if let Some(Ok(_)) = d.push(b) {
            by_byte += 1;
        }
    }
    let mut by_slice = 0u32;
    let mut d = PacketDecoder::<256>::new();
    let mut rest = data;
    while !rest.is_empty() {
        let (n, r) = d.push_slice(rest);
        if let Some(Ok(_)) = r {
            by_slice += 1;
        }
        rest = &rest[n.max(1).min(rest.len())..];
    }
    assert_eq!(by_byte, by_slice);
    let mut fw = Firmware::new(config::locobot(), "fuzz", Instant::ZERO);
    for (i, chunk) in data.chunks(23).enumerate() {
        let now = Instant::from_micros(250 * i as u64);
        fw.poll(now);
        fw.on_servo_bytes(now + Duration::from_micros(100), chunk);
        for link in [Link::Host, Link::Servo, Link::Base] {
            let n = fw.pending(link).len();
            fw.consume(link, n);
        }
    }
}
