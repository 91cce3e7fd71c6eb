//! The firmware against a hostile host ([`ferrobot_sim::hostile`]): 20,000 seeded hostile
//! messages per LoCoBot profile through the lockstep simulator, and 10,000 of the pointed mix,
//! with the invariants checked throughout by both checkers, then an emergency stop and a
//! recovery. `FERROBOT_HOSTILE_MESSAGES` sets the
//! messages per profile (CI: 20,000) and `FERROBOT_HOSTILE_SEED` shifts the seeds (CI: 0),
//! for longer searches.

use ferrobot_sim::hostile::{hostile_stream_of, mixed_message, Mix};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The mix `FERROBOT_HOSTILE_MIX` names (`broad`, `pointed`), or `default`.
fn mix_or(default: Mix) -> Mix {
    match std::env::var("FERROBOT_HOSTILE_MIX").as_deref() {
        Ok("broad") => Mix::Broad,
        Ok("pointed") => Mix::Pointed,
        _ => default,
    }
}

fn messages() -> usize {
    std::env::var("FERROBOT_HOSTILE_MESSAGES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20_000)
}

fn assert_clean(robot: &str, seed: u64) {
    assert_clean_of(robot, seed, messages(), Mix::Broad);
}

fn assert_clean_of(robot: &str, seed: u64, n: usize, mix: Mix) {
    // FERROBOT_HOSTILE_SEED shifts the seeds, for longer searches than CI's.
    let seed = seed
        + std::env::var("FERROBOT_HOSTILE_SEED")
            .ok()
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0);
    let (c, t) = hostile_stream_of(&mut ChaCha8Rng::seed_from_u64(seed), robot, seed, n, mix);
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

/// `HostMsg::kind` names every message as its variant is spelled (recordings and logs use
/// it): checked on the broad mix, which makes every variant.
#[test]
fn every_message_s_kind_is_its_variant_s_name() {
    let s = ferrobot_sim::SimHost::start("locobot", 1).expect("simulator");
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut seen = std::collections::BTreeSet::new();
    for _ in 0..5000 {
        let m = mixed_message(&mut rng, &s.sim.fw, Mix::Broad);
        let debug = format!("{m:?}");
        let name = debug.split([' ', '(', '{']).next().unwrap_or_default();
        assert_eq!(m.kind(), name, "{debug}");
        seen.insert(name.to_string());
    }
    assert!(
        seen.len() >= 21,
        "only {} variants made: {seen:?}",
        seen.len()
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

/// The pointed mix ([`Mix::Pointed`]: the holes issue 48's outside review found), half as
/// long as the broad streams in CI.
#[test]
fn pointed_messages_never_drive_the_locobot_outside_its_limits() {
    assert_clean_of("locobot", 3, messages() / 2, mix_or(Mix::Pointed));
}

#[test]
fn pointed_messages_never_drive_the_locobot_lite_outside_its_limits() {
    assert_clean_of("locobot_lite", 4, messages() / 2, mix_or(Mix::Pointed));
}

/// Streams that once found a violation (the survey's seeds), kept as regression cases, each
/// as long as it took: 560, a mode change counted done one bus answer ahead; 364, a joint
/// rebooted after an overload thrown towards where it had been allowed before the fault
/// (5,000 messages each); pointed 10008, a loaded joint ratcheted out past its limit by
/// repeated SetMode to the mode it was in (0.96 rad beyond); broad 20064, a brake's offset
/// taken for a load after one brake, throwing the joint back, brake after brake (1.28 rad/s
/// against 0.77); broad 734, a hostile gravity model confirmed where it was right, whose
/// overstated load elsewhere held joint 2 0.06 rad past its limit (its goal let beyond the
/// limit by the model's offset, and the joint, held off its command by the model's own error,
/// not checked against it); pointed 716, five servos' mode changes chained between two ticks,
/// a current-mode joint's effort left stale for 3 ms (1.09 rad/s against 1.04); pointed 754,
/// a joint outside its limits brought back by its load (0.32 rad/s against 0.05, its goal
/// held at the joint) and, before, a joint still moving after the final emergency stop.
#[test]
fn the_streams_that_found_violations_stay_clean() {
    for (seed, n, mix) in [
        (364u64, 5000, Mix::Broad),
        (560, 5000, Mix::Broad),
        (10008, 20_000, Mix::Pointed),
        (20064, 18_000, Mix::Broad),
        (734, 9_000, Mix::Broad),
        (716, 1_100, Mix::Pointed),
        (754, 8_400, Mix::Pointed),
    ] {
        let robot = if seed % 2 == 0 {
            "locobot_lite"
        } else {
            "locobot"
        };
        let (c, _) = hostile_stream_of(&mut ChaCha8Rng::seed_from_u64(seed), robot, seed, n, mix);
        assert!(
            c.violations.is_empty(),
            "seed {seed}: {} violations, first: {}",
            c.violations.len(),
            c.violations[0]
        );
    }
}

/// A survey for long searches, not run in CI: `FERROBOT_SURVEY_FROM` (first seed, default
/// 300), `FERROBOT_SURVEY_COUNT` (streams, default 80) and `FERROBOT_HOSTILE_MESSAGES`
/// (messages per stream); even seeds run the LoCoBot-Lite, odd ones the LoCoBot. Prints, per
/// stream with a finding, its violation samples and episodes (messages after which a
/// violation was seen) or a failed stop, and a summary line.
#[test]
#[ignore]
fn survey() {
    let env = |k: &str, d: u64| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let (from, count) = (
        env("FERROBOT_SURVEY_FROM", 300),
        env("FERROBOT_SURVEY_COUNT", 80),
    );
    let n = messages();
    let seeds: Vec<u64> = (from..from + count).collect();
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|sc| {
        for chunk in seeds.chunks(seeds.len().div_ceil(2).max(1)) {
            let results = &results;
            sc.spawn(move || {
                for &seed in chunk {
                    let robot = if seed % 2 == 0 {
                        "locobot_lite"
                    } else {
                        "locobot"
                    };
                    let mix = mix_or(Mix::Broad);
                    let r = std::panic::catch_unwind(|| {
                        hostile_stream_of(&mut ChaCha8Rng::seed_from_u64(seed), robot, seed, n, mix)
                    });
                    let found = r.map(|(c, _)| {
                        if let Some(v) = c.violations.first() {
                            eprintln!("seed {seed} first: {v}");
                        }
                        let mut episodes: Vec<&str> = c
                            .violations
                            .iter()
                            .filter_map(|v| v.split(' ').nth(2))
                            .collect();
                        episodes.dedup();
                        (c.violations.len(), episodes.len())
                    });
                    results
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .push((seed, found.ok()));
                }
            });
        }
    });
    let mut r = results.into_inner().unwrap_or_else(|e| e.into_inner());
    r.sort();
    let (mut streams, mut samples, mut episodes, mut failed) = (0, 0, 0, 0);
    for (seed, found) in &r {
        match found {
            Some((0, _)) => {}
            Some((v, e)) => {
                streams += 1;
                samples += v;
                episodes += e;
                eprintln!("seed {seed}: {v} violation samples in {e} episodes");
            }
            None => {
                failed += 1;
                eprintln!("seed {seed}: the stop or the recovery at the end failed");
            }
        }
    }
    eprintln!(
        "survey: {} streams of {n} messages, {streams} with violations ({samples} samples, {episodes} episodes), {failed} failed stops or recoveries",
        r.len()
    );
}
