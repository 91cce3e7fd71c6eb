//! Runs 2 simulated seconds of the LoCoBot with arm and base moving, for profilers:
//! `valgrind --tool=callgrind target/release/examples/lockstep_profile`.
use ferrobot_protocol::*;
use ferrobot_sim::SimSession;

fn main() {
    let mut s = SimSession::start("locobot", 5).expect("sim");
    s.run_for(300_000);
    let pts: heapless::Vec<JointPoint, MAX_JOINTS> = [0.6f32, 0.4, -0.4, 0.3, 0.5]
        .iter()
        .map(|&p| JointPoint {
            position: p,
            velocity: 0.0,
            effort: 0.0,
        })
        .collect();
    s.command(&HostMsg::Waypoint {
        joints: 0b1_1111,
        duration_us: 30_000_000,
        points: pts,
    })
    .expect("waypoint");
    s.command(&HostMsg::BaseVelocity {
        v: 0.2,
        w: 0.1,
        duration_ms: 30_000,
    })
    .expect("base");
    let t = std::time::Instant::now();
    s.run_for(2_000_000);
    println!("2 s simulated in {:?}", t.elapsed());
}
