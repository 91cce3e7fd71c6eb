//! Encode plus decode of the LoCoBot telemetry frame (8 joints, base, faults, loop stats).
//! Run: `cargo bench -p ferrobot-benches --bench telemetry`.

use criterion::{criterion_group, criterion_main, Criterion};
use ferrobot_protocol::*;
use std::hint::black_box;

fn locobot_telemetry() -> DeviceMsg {
    DeviceMsg::Telemetry(Telemetry {
        time_us: 123_456_789,
        joints: (0..8)
            .map(|i| JointState {
                position: 0.1 * i as f32,
                velocity: -0.25,
                effort: 0.731,
            })
            .collect(),
        queued: 3,
        gripper: GripperState::Holding,
        odometry: Odometry {
            x: 1.234,
            y: -0.5,
            theta: 0.7,
            v: 0.2,
            w: -0.1,
        },
        wheels: WheelData {
            left: 12.5,
            right: 13.25,
            left_rate: 5.7,
            right_rate: 5.8,
        },
        base_flags: 0,
        faults: 0,
        loop_stats: LoopStats {
            ticks: 1_000_000,
            worst_tick_us: 734,
            overruns: 0,
        },
    })
}

fn bench(c: &mut Criterion) {
    let msg = locobot_telemetry();
    let mut buf = [0u8; MAX_WIRE];
    let n = encode_frame(1, &msg, &mut buf).expect("fits");
    println!("LoCoBot telemetry frame: {n} bytes on the wire");
    c.bench_function("telemetry encode+decode (LoCoBot, 8 joints)", |b| {
        let mut dec = FrameDecoder::new();
        b.iter(|| {
            let n = encode_frame(black_box(7), black_box(&msg), &mut buf).expect("fits");
            let mut out = None;
            for &byte in &buf[..n] {
                if let Some(r) = dec.push::<DeviceMsg>(byte) {
                    out = r.ok();
                }
            }
            black_box(out)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
