//! Runs 2 simulated seconds of the busy LoCoBot scenario, for profilers:
//! `valgrind --tool=callgrind target/release/examples/lockstep_profile`.

use ferrobot_sim::HostSide;

fn main() {
    let mut s = ferrobot_sim::lockstep::locobot_busy(5).expect("sim");
    let t = std::time::Instant::now();
    s.run_for(2_000_000);
    println!("2 s simulated in {:?}", t.elapsed());
}
