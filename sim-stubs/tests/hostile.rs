//! The firmware against a hostile host ([`ferrobot_sim::hostile`]): 20,000 seeded hostile
//! messages per LoCoBot profile through the lockstep simulator, with the invariants checked
//! throughout, then an emergency stop and a recovery. `FERROBOT_HOSTILE_MESSAGES` sets the
//! messages per profile (CI: 20,000) and `FERROBOT_HOSTILE_SEED` shifts the seeds (CI: 0),
//! for longer searches.

use ferrobot_sim::hostile::hostile_stream;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn messages() -> usize {
    std::env::var("FERROBOT_HOSTILE_MESSAGES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20_000)
}

fn assert_clean(robot: &str, seed: u64) {
    let n = messages();
    // FERROBOT_HOSTILE_SEED shifts the seeds, for longer searches than CI's.
    let seed = seed
        + std::env::var("FERROBOT_HOSTILE_SEED")
            .ok()
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0);
    let (c, t) = hostile_stream(&mut ChaCha8Rng::seed_from_u64(seed), robot, seed, n);
    eprintln!(
        "{robot}: {n} hostile messages over {:.1} s simulated, {} checks, {} violations; worst: {:.4} rad beyond a position limit, {:.3} rad/s over a velocity limit",
        t as f64 * 1e-6,
        c.samples,
        c.violations.len(),
        c.worst.0,
        c.worst.1
    );
    eprintln!(
        "worst position: {}\nworst speed: {}",
        c.worst_at.0, c.worst_at.1
    );
    assert!(
        c.violations.is_empty(),
        "{robot}: {} violations, first ones:\n{}",
        c.violations.len(),
        c.violations
            .iter()
            .step_by((c.violations.len() / 12).max(1))
            .take(12)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
}

#[test]
fn hostile_messages_never_drive_the_locobot_outside_its_limits() {
    assert_clean("locobot", 1);
}

#[test]
fn hostile_messages_never_drive_the_locobot_lite_outside_its_limits() {
    assert_clean("locobot_lite", 2);
}
