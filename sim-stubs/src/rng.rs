//! Seeded randomness for the plants: every run with the same seed is bit-identical.

use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A seeded generator with the few distributions the plants need.
#[derive(Debug, Clone)]
pub struct SimRng {
    rng: ChaCha8Rng,
    spare: Option<f64>,
}

impl SimRng {
    /// A generator for `seed`; `stream` separates independent plants sharing a seed.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        SimRng { rng, spare: None }
    }

    /// 64 uniform random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.rng.next_u64()
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.rng.random::<f64>()
    }

    /// Normal with mean 0 and standard deviation `std` (Box-Muller; each pair of uniforms
    /// gives two normals).
    pub fn normal(&mut self, std: f64) -> f64 {
        if std == 0.0 {
            return 0.0;
        }
        if let Some(z) = self.spare.take() {
            return std * z;
        }
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        self.spare = Some(r * s);
        std * r * c
    }
}
