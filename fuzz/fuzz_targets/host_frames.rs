//! Host frames: the frame decoder alone (both message directions), then the firmware core fed
//! the same bytes after a valid handshake, then every message postcard can read from the
//! bytes, framed validly (so that arbitrary commands and values reach the firmware's
//! handlers past the CRC). Nothing may panic.
#![cfg_attr(fuzzing, no_main)]
use ferrobot_firmware::time::Instant;
use ferrobot_firmware::{config, Firmware, Link};
use ferrobot_protocol::*;

ferrobot_fuzz::target!(run);

/// One input.
fn run(data: &[u8]) {
    let mut d = FrameDecoder::new();
    for &b in data {
        let _ = d.push::<HostMsg>(b);
    }
    let mut d = FrameDecoder::new();
    for &b in data {
        let _ = d.push::<DeviceMsg>(b);
    }
    let mut fw = Firmware::new(config::locobot(), "fuzz", Instant::ZERO);
    let mut hello = [0u8; MAX_WIRE];
    if let Ok(n) = encode_frame(
        0,
        &HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH,
        },
        &mut hello,
    ) {
        fw.on_host_bytes(Instant::ZERO, &hello[..n]);
    }
    for (i, chunk) in data.chunks(17).enumerate() {
        let now = Instant::from_millis(i as u64);
        fw.on_host_bytes(now, chunk);
        fw.poll(now);
        for link in [Link::Host, Link::Servo, Link::Base] {
            let n = fw.pending(link).len();
            fw.consume(link, n);
        }
    }
    let mut rest = data;
    let mut seq = 1u16;
    while !rest.is_empty() {
        match postcard::take_from_bytes::<HostMsg>(rest) {
            Ok((msg, tail)) => {
                let mut buf = [0u8; MAX_WIRE];
                if let Ok(n) = encode_frame(seq, &msg, &mut buf) {
                    let now = Instant::from_millis(seq as u64);
                    fw.on_host_bytes(now, &buf[..n]);
                    fw.poll(now);
                    for link in [Link::Host, Link::Servo, Link::Base] {
                        let n = fw.pending(link).len();
                        fw.consume(link, n);
                    }
                }
                seq = seq.wrapping_add(1);
                rest = tail;
            }
            Err(_) => rest = &rest[1..],
        }
    }
}
