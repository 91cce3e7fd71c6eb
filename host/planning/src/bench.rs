//! Planning benchmarks: seeded sets of start/goal pairs that must go around things, and a
//! runner that plans each and summarises success, time and path length.

use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::checker::Checker;
use crate::planner::{path_length, PlanOptions, Planner};
use crate::{Error, Result};

/// Most problems in one set.
pub const MAX_PROBLEMS: usize = 100_000;

/// A start and a goal, rad.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// Start configuration.
    pub start: Vec<f64>,
    /// Goal configuration.
    pub goal: Vec<f64>,
}

/// How [`generate`] makes sure a problem can be solved.
#[derive(Debug, Clone, PartialEq)]
pub struct Reach {
    /// A free configuration both ends must reach (the robot's home, rad).
    pub hub: Vec<f64>,
    /// RRT-Connect's time for each end to reach the hub (seeds apart from the benchmark's).
    pub within: std::time::Duration,
}

/// A generated problem set.
#[derive(Debug, Clone, PartialEq)]
pub struct ProblemSet {
    /// The problems.
    pub problems: Vec<Problem>,
    /// Candidates dropped because an end did not reach the hub ([`Reach`]) in time: in a
    /// cage or a shelf some free configurations are cut off from the rest (a link threaded
    /// between bars), and no planner can solve a problem that starts there.
    pub unreached: usize,
}

/// `n` problems for `checker`'s robot in its scene, seeded with `seed`: both ends free, the
/// straight joint-space line between them not, and each end's links near the scene (within
/// `near` m of some object) so that problems are about getting around things; with `reach`,
/// both ends also connected to its hub (a problem whose ends both reach the hub can be
/// solved through it). Gives up with an error after `n × 200` candidates of `20000` samples
/// each.
pub fn generate(
    checker: &Checker,
    n: usize,
    seed: u64,
    near: f64,
    reach: Option<&Reach>,
) -> Result<ProblemSet> {
    check_request(checker, n, reach)?;
    let limits = checker.model().limits().to_vec();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let sample_free = |rng: &mut ChaCha8Rng| -> Option<Vec<f64>> {
        for _ in 0..20_000 {
            let q = crate::joint_space::sample(rng, &limits);
            if checker.is_free(&q) && (near <= 0.0 || checker.near_world(&q, near)) {
                return Some(q);
            }
        }
        None
    };
    let reaches = |q: &[f64], k: u64| -> bool {
        reach.is_none_or(|r| {
            let opts = PlanOptions {
                time_limit: r.within,
                // Apart from the benchmark's seeds (`seed` plus the problem's index).
                seed: seed ^ 0x68_75_62 ^ k.rotate_left(32),
                shortcuts: 0,
                ..PlanOptions::default()
            };
            crate::planner::RrtConnect
                .plan(checker, &r.hub, q, &opts)
                .is_ok()
        })
    };
    let mut set = ProblemSet {
        problems: Vec::with_capacity(n),
        unreached: 0,
    };
    let mut tries = 0u64;
    while set.problems.len() < n {
        tries += 1;
        if tries > n.max(1) as u64 * 200 {
            return Err(Error::Invalid {
                what: "problem set".into(),
                why: format!(
                    "found only {} of {n} problems whose straight line collides{}",
                    set.problems.len(),
                    if set.unreached > 0 {
                        format!(" and whose ends reach the hub ({} did not)", set.unreached)
                    } else {
                        String::new()
                    }
                ),
            });
        }
        let (Some(start), Some(goal)) = (sample_free(&mut rng), sample_free(&mut rng)) else {
            return Err(Error::Invalid {
                what: "problem set".into(),
                why: "no free configuration near the scene in 20000 samples".into(),
            });
        };
        if checker.motion_free(&start, &goal) {
            continue;
        }
        if !(reaches(&start, 2 * tries) && reaches(&goal, 2 * tries + 1)) {
            set.unreached += 1;
            continue;
        }
        set.problems.push(Problem { start, goal });
    }
    Ok(set)
}

/// [`generate`]'s request: at most [`MAX_PROBLEMS`] problems; with `reach`, a time within
/// (0, [`crate::planner::MAX_TIME_LIMIT`]] s and a hub free in the scene.
fn check_request(checker: &Checker, n: usize, reach: Option<&Reach>) -> Result<()> {
    if n > MAX_PROBLEMS {
        return Err(Error::Invalid {
            what: "problem count".into(),
            why: format!("{n} is more than {MAX_PROBLEMS}"),
        });
    }
    if let Some(r) = reach {
        // Checked here: a plan refuses it, which would count every candidate as unreached.
        let within = r.within.as_secs_f64();
        if !(within > 0.0 && within <= crate::planner::MAX_TIME_LIMIT) {
            return Err(Error::Invalid {
                what: "hub reach time".into(),
                why: format!(
                    "{within} s is not in (0, {}] s",
                    crate::planner::MAX_TIME_LIMIT
                ),
            });
        }
        if !checker.is_free(&r.hub) {
            return Err(Error::Invalid {
                what: "hub".into(),
                why: format!("{:?} is not free in the scene", r.hub),
            });
        }
    }
    Ok(())
}

/// One problem's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// Whether a path was found.
    pub success: bool,
    /// Time spent, ms.
    pub time_ms: f64,
    /// The path (empty on failure), rad.
    pub path: Vec<Vec<f64>>,
    /// Why it failed, if it did.
    pub error: Option<String>,
}

/// Summary of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Problems.
    pub problems: usize,
    /// Fraction solved.
    pub success_rate: f64,
    /// Median, 95th percentile (nearest rank) and largest time, ms (failures at their full
    /// time).
    pub time_ms: [f64; 3],
    /// Median joint-space path length of the solved problems, rad.
    pub path_length_median: f64,
    /// Sphere-level checks ([`crate::checker::Counters::sphere_checks`]) per second of
    /// planning time.
    pub sphere_checks_per_s: f64,
    /// States measured in all ([`crate::checker::Counters::states`]).
    pub states: u64,
    /// Edge proofs started in all ([`crate::checker::Counters::edges`]).
    pub edges: u64,
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[k - 1]
}

/// Median of `v` (NaN when empty).
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    if s.is_empty() {
        return f64::NAN;
    }
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        (s[n / 2 - 1] + s[n / 2]) / 2.0
    }
}

/// Plans every problem with `planner` (each seeded with `opts.seed` plus its index).
pub fn run(
    checker: &Checker,
    planner: &dyn Planner,
    problems: &[Problem],
    opts: &PlanOptions,
) -> (Vec<Outcome>, Summary) {
    use std::sync::atomic::Ordering;
    let c = checker.counters();
    let load = |a: &std::sync::atomic::AtomicU64| a.load(Ordering::Relaxed);
    let before = [&c.sphere_checks, &c.states, &c.edges].map(load);
    let t0 = Instant::now();
    let outcomes: Vec<Outcome> = problems
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let o = PlanOptions {
                seed: opts.seed.wrapping_add(i as u64),
                ..opts.clone()
            };
            let t = Instant::now();
            let r = planner.plan(checker, &p.start, &p.goal, &o);
            let time_ms = t.elapsed().as_secs_f64() * 1e3;
            match r {
                Ok(plan) => Outcome {
                    success: true,
                    time_ms,
                    path: plan.path,
                    error: None,
                },
                Err(e) => Outcome {
                    success: false,
                    time_ms,
                    path: Vec::new(),
                    error: Some(e.to_string()),
                },
            }
        })
        .collect();
    let elapsed = t0.elapsed().as_secs_f64();
    let after = [&c.sphere_checks, &c.states, &c.edges].map(load);
    let [checks, states, edges] = [0, 1, 2].map(|i| after[i] - before[i]);
    let mut times: Vec<f64> = outcomes.iter().map(|o| o.time_ms).collect();
    times.sort_by(f64::total_cmp);
    let lengths: Vec<f64> = outcomes
        .iter()
        .filter(|o| o.success)
        .map(|o| path_length(&o.path))
        .collect();
    let summary = Summary {
        problems: problems.len(),
        success_rate: if problems.is_empty() {
            1.0
        } else {
            outcomes.iter().filter(|o| o.success).count() as f64 / problems.len() as f64
        },
        time_ms: [
            median(&times),
            quantile(&times, 0.95),
            times.last().copied().unwrap_or(f64::NAN),
        ],
        path_length_median: median(&lengths),
        sphere_checks_per_s: checks as f64 / elapsed.max(1e-9),
        states,
        edges,
    };
    (outcomes, summary)
}
