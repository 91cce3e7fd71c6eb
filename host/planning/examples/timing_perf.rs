//! Times [`ferrobot_planning::timing::time_optimal`] on random 20-waypoint 7-DOF paths.
//!
//! `cargo run --release -p ferrobot-planning --example timing_perf`

use std::time::Instant;

use ferrobot_planning::timing::{time_optimal, Limits, TimingOptions};
use rand::{Rng, SeedableRng};

fn main() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(20);
    let limits = Limits {
        velocity: vec![2.0, 2.0, 2.5, 2.5, 3.0, 3.0, 3.0],
        acceleration: vec![4.0, 4.0, 5.0, 5.0, 8.0, 8.0, 8.0],
    };
    let mut times = Vec::new();
    let mut durations = Vec::new();
    for _ in 0..200 {
        // A path as a planner returns it after shortcutting: waypoints well apart.
        let path: Vec<Vec<f64>> = (0..20)
            .map(|_| (0..7).map(|_| rng.random_range(-2.5..2.5)).collect())
            .collect();
        let start = Instant::now();
        let traj = match time_optimal(&path, &limits, &TimingOptions::default()) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("failed: {e}");
                return;
            }
        };
        times.push(start.elapsed().as_secs_f64() * 1e3);
        durations.push(traj.duration());
    }
    times.sort_by(f64::total_cmp);
    let mean = times.iter().sum::<f64>() / times.len() as f64;
    println!(
        "20 waypoints, 7 DOF, max_deviation 0.05 rad, time_step 1 ms, {} paths: \
         median {:.3} ms, mean {:.3} ms, max {:.3} ms (trajectory durations {:.1}..{:.1} s)",
        times.len(),
        times[times.len() / 2],
        mean,
        times[times.len() - 1],
        durations.iter().copied().fold(f64::INFINITY, f64::min),
        durations.iter().copied().fold(0.0, f64::max),
    );
}
