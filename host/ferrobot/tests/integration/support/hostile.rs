//! Strategies and judges shared by the hostile-value property tests of the library and of the
//! command line's library half: ordinary values mixed with every kind of hostile one, and the
//! rule that an absurd input must give `Err`.
#![allow(dead_code)]

use std::time::Duration;

use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};

/// Cases per entry-point group (CI); the environment variable `HOSTILE_CASES` overrides it.
pub fn cases() -> u32 {
    std::env::var("HOSTILE_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(200)
}

pub fn runner(salt: u64) -> TestRunner {
    let cfg = Config {
        cases: cases(),
        failure_persistence: None,
        ..Config::default()
    };
    TestRunner::new_with_rng(
        cfg,
        proptest::test_runner::TestRng::from_seed(proptest::test_runner::RngAlgorithm::ChaCha, &{
            let mut s = [7u8; 32];
            s[..8].copy_from_slice(&salt.to_le_bytes());
            s
        }),
    )
}

/// Ordinary values mixed with every kind of hostile one.
pub fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1.5..1.5f64,
        2 => prop::sample::select(vec![
            0.0,
            -0.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            -f64::MAX,
            f64::MIN_POSITIVE,
            5e-324,
            -5e-324,
            1e38,
            -1e38,
            1e300,
            -1e300,
            1e-300,
            1e9,
            -1e9,
        ]),
        1 => any::<f64>(),
    ]
}

pub fn vector(len: std::ops::Range<usize>) -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(value(), len)
}

pub fn triple() -> impl Strategy<Value = [f64; 3]> {
    [value(), value(), value()]
}

pub fn duration() -> impl Strategy<Value = Duration> {
    prop_oneof![
        Just(Duration::MAX),
        Just(Duration::ZERO),
        (0u64..u64::MAX).prop_map(Duration::from_nanos),
        (0u64..u64::MAX).prop_map(Duration::from_secs),
        (0u64..30_000).prop_map(Duration::from_millis),
    ]
}

pub fn count() -> impl Strategy<Value = usize> {
    prop_oneof![
        Just(0usize),
        Just(usize::MAX),
        Just(usize::MAX / 2 + 1),
        Just(1usize << 32),
        0usize..200,
    ]
}

/// Not finite, or beyond 1e6 in magnitude: no entry point may accept it.
pub fn absurd(values: &[f64]) -> bool {
    values.iter().any(|v| !v.is_finite() || v.abs() > 1e6)
}

/// `Err` is required when `hostile`; a panic anywhere fails the case.
pub fn judge<T: std::fmt::Debug, E: std::fmt::Debug>(
    what: &str,
    hostile: bool,
    r: &Result<T, E>,
) -> Result<(), TestCaseError> {
    if hostile && r.is_ok() {
        return Err(TestCaseError::fail(format!(
            "{what}: accepted hostile input: {r:?}"
        )));
    }
    Ok(())
}

/// Tally of one test's cases, printed for BENCHMARKS.md.
pub fn report(what: &str, calls: usize) {
    println!("hostile_api {what}: {calls} calls, 0 panics, every absurd input refused");
}
