//! Base feedback: the Kobuki and Create 2 parsers, then both firmware base drivers fed the
//! bytes. Nothing may panic.
#![cfg_attr(fuzzing, no_main)]
use ferrobot_firmware::time::Instant;
use ferrobot_firmware::{config, Firmware};
use ferrobot_protocol::{create2, kobuki};

ferrobot_fuzz::target!(run);

/// One input.
fn run(data: &[u8]) {
    let mut k = kobuki::Parser::new();
    let mut c = create2::StreamParser::new();
    for &b in data {
        if let Some(Ok(p)) = k.push(b) {
            for (_id, _d) in kobuki::sub_payloads(p) {}
        }
        let _ = c.push(b);
    }
    for profile in [config::locobot(), config::locobot_lite()] {
        let mut fw = Firmware::new(profile, "fuzz", Instant::ZERO);
        for (i, chunk) in data.chunks(19).enumerate() {
            let now = Instant::from_micros(5000 * i as u64);
            fw.on_base_bytes(now, chunk);
            fw.poll(now);
        }
    }
}
