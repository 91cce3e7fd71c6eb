//! The self-collision matrices stored in the bundled robots' configurations (`[collision]`,
//! written by `ferrobot collision-matrix ROBOT --samples 10000 --seed 1`) are the ones the
//! sampling computes now: a change to a URDF, to the collision model or to the sampler that
//! changes a matrix fails here until the section is written again. The full 10000 samples
//! are drawn (about 0.1 s per robot with the workspace's test profile, opt-level 1).

use ferrobot_description::{RobotConfig, BUNDLED};
use ferrobot_planning::{acm, CollisionModel, SelfCollisionMatrix};

/// Samples and seed of the stored matrices.
const SAMPLES: usize = 10_000;
const SEED: u64 = 1;

#[test]
fn stored_matrices_equal_the_ones_computed_now() {
    for name in BUNDLED {
        let cfg = RobotConfig::bundled(name).expect("bundled");
        assert!(
            cfg.collision.is_some(),
            "{name}: no [collision] section; run `ferrobot collision-matrix {name}`"
        );
        let model = CollisionModel::from_config(&cfg).expect("model");
        let stored = model.acm().clone();
        let t = std::time::Instant::now();
        let now = SelfCollisionMatrix::compute(&model, SAMPLES, SEED);
        eprintln!(
            "{name}: {SAMPLES} samples in {:.2} s",
            t.elapsed().as_secs_f64()
        );
        if now != stored {
            let s = stored.entries();
            let n = now.entries();
            let gone: Vec<_> = s.iter().filter(|e| !n.contains(e)).collect();
            let new: Vec<_> = n.iter().filter(|e| !s.contains(e)).collect();
            panic!(
                "{name}: the stored matrix differs from the one computed now; stored only: \
                 {gone:?}; computed only: {new:?}; write it again with `ferrobot \
                 collision-matrix {name} --samples {SAMPLES} --seed {SEED}`"
            );
        }
        // A matrix without its adjacent pairs would be an empty section, not a computed one.
        assert!(stored
            .entries()
            .iter()
            .any(|e| e.2 == acm::Reason::Adjacent));
    }
}
