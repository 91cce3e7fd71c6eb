//! `ferrobot collision-matrix`: a robot's self-collision matrix computed by sampling, printed
//! as the `[collision]` section of its configuration.

use ferrobot::planning::{acm, CollisionModel, SelfCollisionMatrix};
use ferrobot::validate;

use super::common::{load, planning_error};

/// Most random configurations sampled.
pub const MAX_SAMPLES: usize = 1_000_000;

/// The `[collision]` section of `robot` (name or configuration path) from `samples` random
/// configurations of every movable joint, seeded with `seed`.
pub fn section(robot: &str, samples: usize, seed: u64) -> ferrobot::Result<String> {
    validate::count("samples", samples, 1..=MAX_SAMPLES)?;
    let mut cfg = load(robot)?;
    // The matrix stored in the configuration (if any) plays no part in sampling: start from an
    // empty one so that none is computed for nothing.
    cfg.collision = Some(Default::default());
    let model = CollisionModel::from_config(&cfg).map_err(|e| planning_error(&cfg.file, e))?;
    let matrix = SelfCollisionMatrix::compute(&model, samples, seed);
    let entries = matrix.entries();
    let count = |r: acm::Reason| entries.iter().filter(|e| e.2 == r).count();
    let comment = format!(
        "The self-collision matrix: link pairs never checked against each other, from\n\
         `ferrobot collision-matrix {} --samples {samples} --seed {seed}` ({samples} random\n\
         configurations): {} adjacent, {} touching at the default pose, {} touching in at least\n\
         {}% of the samples, {} in none.",
        cfg.name,
        count(acm::Reason::Adjacent),
        count(acm::Reason::Default),
        count(acm::Reason::Always),
        acm::ALWAYS_FRACTION * 100.0,
        count(acm::Reason::Never),
    );
    Ok(matrix.to_toml(&comment))
}

/// `ferrobot collision-matrix`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Random configurations of every movable joint.
    #[arg(long, default_value_t = ferrobot::planning::acm::DEFAULT_SAMPLES)]
    pub samples: usize,
    /// Seed of the sampler.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Print the section.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let text = section(&a.robot, a.samples, a.seed)?;
    say!("{}", text.trim_end());
    Ok(())
}
