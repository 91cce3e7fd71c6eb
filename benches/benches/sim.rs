//! Benchmarks of the firmware core and the lockstep simulator.
//! Run: `cargo bench -p ferrobot-benches --bench sim`.
//!
//! * `firmware tick`: one servo-loop tick of the firmware core for the LoCoBot's 9 servos plus
//!   the Kobuki: poll (sync read out), the 9 status packets in (recorded from the simulated
//!   chain), control and the sync write out, and one Kobuki feedback packet parsed into
//!   odometry (the base's feedback comes every 20th tick; charging it to every tick bounds the
//!   cost from above). Plant physics excluded.
//! * `lockstep 1 s`: one simulated second of the LoCoBot with the arm and the base moving, 1 kHz
//!   servo loop, everything (firmware, servo physics at 4 kHz, base physics at 1 kHz, wires).
//! * `lockstep 1 s in the tabletop`: as `lockstep 1 s`, in the tabletop scene with the physics
//!   world at 1 kHz, the objects at rest, the arm on a slow move and the base still.
//! * `physics step`: one 1 ms step of the physics world (rapier3d) with the LoCoBot's links in
//!   the tabletop and apartment scenes: idle (the objects asleep, the links still), and with
//!   the base turning in place at 1 rad/s (every link moving each step).

use criterion::{criterion_group, criterion_main, Criterion};
use ferrobot_firmware::time;
use ferrobot_firmware::{config, Firmware, Link};
use ferrobot_protocol::*;
use ferrobot_sim::lockstep::locobot_busy;
use ferrobot_sim::HostSide;
use ferrobot_sim::LockstepSim;
use std::hint::black_box;
use std::time::Instant;

/// Record one tick's status replies and a Kobuki feedback packet from the running simulator.
fn recorded_bytes() -> (Vec<u8>, Vec<u8>) {
    let mut s = locobot_busy(5).expect("sim");
    s.run_for(100_000);
    let sim = &mut s.sim;
    // A sync read as the firmware sends it.
    let ids: Vec<u8> = (1..=9).collect();
    let mut req = [0u8; 64];
    let n = dxl::sync_read(&mut req, dxl::addr::PRESENT_CURRENT, 10, &ids).expect("fits");
    let now = sim.now_us();
    let replies: Vec<u8> = sim
        .hw
        .chain
        .on_bytes(now, &req[..n])
        .into_iter()
        .flat_map(|r| r.bytes)
        .collect();
    let base = sim.hw.base.as_mut().expect("base");
    base.advance_to(now + 40_000);
    let fb = base.take_output();
    (replies, fb)
}

/// The LoCoBot in the tabletop scene, configured, the objects at rest (rapier puts them to
/// sleep about 2 s after the start), its arm on a slow move.
fn tabletop_busy() -> ferrobot_sim::SimHost {
    let scene =
        std::sync::Arc::new(ferrobot_sim::scene::Scene::bundled("tabletop").expect("scene"));
    let sim = LockstepSim::with_scene(
        ferrobot_sim::robots::by_name("locobot").expect("robot"),
        config::locobot(),
        5,
        scene,
    )
    .expect("fits");
    let mut s = ferrobot_sim::SimHost::new(sim);
    s.handshake().expect("hello");
    s.wait_telemetry(2_000_000, |t| t.faults & fault_flags::CONFIGURING == 0)
        .expect("configured");
    s.run_for(3_000_000);
    let points = [0.6f32, -0.3, 0.3, 0.0, 0.5]
        .iter()
        .map(|&p| JointPoint::at_rest(p))
        .collect();
    s.command(&HostMsg::Waypoint {
        joints: 0b1_1111,
        duration_us: 30_000_000,
        points,
    })
    .expect("waypoint");
    s
}

fn bench(c: &mut Criterion) {
    let (statuses, feedback) = recorded_bytes();
    c.bench_function("firmware tick (LoCoBot: 9 servos + Kobuki)", |b| {
        // A firmware configured against the real chain, taken out of the simulator.
        let mut sim = LockstepSim::new("locobot", 5).expect("sim");
        sim.run_until(300_000);
        let mut now = time::Instant::from_micros(sim.now_us());
        let mut fw = std::mem::replace(
            &mut sim.fw,
            Firmware::new(config::locobot(), "bench", time::Instant::ZERO),
        );
        let reply = time::Duration::from_micros(300);
        b.iter(|| {
            now += time::Duration::from_millis(1);
            fw.poll(now);
            let n = fw.pending(Link::Servo).len();
            fw.consume(Link::Servo, n);
            fw.on_servo_bytes(now + reply, black_box(&statuses));
            fw.on_base_bytes(now + reply, black_box(&feedback));
            for link in [Link::Servo, Link::Base, Link::Host] {
                let n = fw.pending(link).len();
                fw.consume(link, n);
            }
        })
    });
    let mut group = c.benchmark_group("lockstep");
    group.sample_size(20);
    group.bench_function(
        "1 s simulated (LoCoBot arm + base moving, 1 kHz loop)",
        |b| {
            b.iter_custom(|iters| {
                let mut total = std::time::Duration::ZERO;
                for _ in 0..iters {
                    let mut s = locobot_busy(5).expect("sim");
                    let t = Instant::now();
                    s.run_for(1_000_000);
                    total += t.elapsed();
                    black_box(&s.telemetry);
                }
                total
            })
        },
    );
    group.bench_function("1 s simulated in the tabletop (LoCoBot arm moving)", |b| {
        b.iter_custom(|iters| {
            let mut total = std::time::Duration::ZERO;
            for _ in 0..iters {
                let mut s = tabletop_busy();
                let t = Instant::now();
                s.run_for(1_000_000);
                total += t.elapsed();
                black_box(&s.telemetry);
            }
            total
        })
    });
    group.finish();
    let mut group = c.benchmark_group("physics step");
    for scene in ["tabletop", "apartment"] {
        for turning in [false, true] {
            let desc = ferrobot_sim::robots::by_name("locobot").expect("robot");
            let sc = ferrobot_sim::scene::Scene::bundled(scene).expect("scene");
            let mut chain = ferrobot_sim::chain::ServoChain::new(&desc.servos, &desc.arm, 1);
            let theta: Vec<f64> = chain.servos.iter().map(|s| s.theta).collect();
            let mut w =
                ferrobot_sim::world::World::new(&sc, desc.body.as_ref(), sc.robot_pose, &theta)
                    .expect("world");
            let mut pose = sc.robot_pose;
            // Let the objects come to rest.
            for _ in 0..2000 {
                w.step(pose, &mut chain);
            }
            let what = if turning { "base turning" } else { "idle" };
            group.bench_function(format!("{scene}, LoCoBot {what}"), |b| {
                b.iter(|| {
                    if turning {
                        pose[2] += 0.001;
                    }
                    w.step(black_box(pose), &mut chain);
                })
            });
        }
    }
    group.finish();
    // The real-time factor, measured the same way, printed for BENCHMARKS.md.
    let mut s = locobot_busy(5).expect("sim");
    let t = Instant::now();
    s.run_for(10_000_000);
    let factor = 10.0 / t.elapsed().as_secs_f64();
    println!("lockstep real-time factor over 10 simulated s: {factor:.0}x");
}

criterion_group!(benches, bench);
criterion_main!(benches);
