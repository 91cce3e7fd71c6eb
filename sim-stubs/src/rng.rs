//! Seeded randomness for the plants: every run with the same seed is bit-identical.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A seeded generator with the few distributions the plants need.
#[derive(Debug, Clone)]
pub struct SimRng(ChaCha8Rng);

impl SimRng {
    /// A generator for `seed`; `stream` separates independent plants sharing a seed.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut r = ChaCha8Rng::seed_from_u64(seed);
        r.set_stream(stream);
        SimRng(r)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0.random::<f64>()
    }

    /// Normal with mean 0 and standard deviation `std` (Box-Muller).
    pub fn normal(&mut self, std: f64) -> f64 {
        if std == 0.0 {
            return 0.0;
        }
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        std * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}
