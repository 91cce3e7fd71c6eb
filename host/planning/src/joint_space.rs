//! Joint space: the Euclidean distance between two joint vectors (rad, or m for a prismatic
//! joint), and configurations drawn uniformly within joint limits.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// The Euclidean distance between joint vectors `a` and `b` (rad, or m for a prismatic joint),
/// over the joints both have.
pub fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// A configuration drawn uniformly within `limits` (rad).
pub(crate) fn sample(rng: &mut ChaCha8Rng, limits: &[(f64, f64)]) -> Vec<f64> {
    let mut q = Vec::with_capacity(limits.len());
    sample_into(rng, limits, &mut q);
    q
}

/// [`sample`] into `q` (its values replaced): the same draws, without an allocation.
pub(crate) fn sample_into(rng: &mut ChaCha8Rng, limits: &[(f64, f64)], q: &mut Vec<f64>) {
    q.clear();
    q.extend(limits.iter().map(|&(lo, hi)| rng.random_range(lo..=hi)));
}
