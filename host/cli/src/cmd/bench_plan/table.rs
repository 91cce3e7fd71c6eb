//! The figures of `bench plan`: one JSON object, or a Markdown table of our planner (and
//! OMPL's beside it with `--ompl`) with the run's settings above and its first failures
//! below. Times in ms, path lengths in rad.

use ferrobot::planning::bench;
use serde::Serialize;

use super::{finite, Args, REACH_FACTOR};
use crate::cmd::common::print_json;

/// `bench plan --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct SummaryJson {
    /// Sphere-level collision checks (covering and bounding spheres against obstacles and
    /// each other, as run) per second of planning time.
    collision_checks_per_s: f64,
    /// Joint-space path length of the solved problems, rad.
    path_length_rad: LengthJson,
    /// OMPL's summary on the same problems (with `--ompl`).
    #[serde(skip_serializing_if = "Option::is_none")]
    peer: Option<serde_json::Value>,
    /// The planner.
    planner: String,
    /// Edge proofs started over all problems (a walk in lanes handed to the advancement
    /// counts twice).
    edges_checked: u64,
    /// How edges were proven (`Lanes`, `Baseline`, `Scalar` or `Advancement`).
    engine: String,
    /// Problems planned.
    problems: usize,
    /// The robot.
    robot: String,
    /// The scene (or the problems file).
    scene: String,
    /// States measured over all problems (the walks', their exact stages' and the
    /// advancement's).
    states_checked: u64,
    /// Fraction solved.
    success_rate: f64,
    /// Time per problem (failures at their full time), ms.
    time_ms: TimeJson,
    /// Generated candidates dropped because an end did not reach the arm's home within
    /// `REACH_FACTOR` times the time limit, at most the planner's 600 s (absent for problems files and when home is not
    /// free).
    #[serde(skip_serializing_if = "Option::is_none")]
    unreached: Option<usize>,
}

/// Path length statistics.
#[derive(Serialize)]
struct LengthJson {
    /// Median, rad (null when nothing was solved).
    median: Option<f64>,
}

/// Time statistics, ms.
#[derive(Serialize)]
struct TimeJson {
    /// Largest.
    max: f64,
    /// Median.
    median: f64,
    /// 95th percentile (nearest rank).
    p95: f64,
}

/// Milliseconds to one decimal, or `-`.
fn ms(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.1}"))
}

/// What a run found.
pub(super) struct Report<'a> {
    /// The robot's name.
    pub(super) robot: &'a str,
    /// The planner's name.
    pub(super) planner: &'a str,
    /// How edges were proven.
    pub(super) engine: ferrobot::planning::checker::Engine,
    /// The scene's name or the problems file.
    pub(super) label: String,
    /// Our planner's summary.
    pub(super) summary: &'a bench::Summary,
    /// Generated candidates dropped as unsolvable, if checked.
    pub(super) unreached: Option<usize>,
    /// OMPL's summary (with `--ompl`).
    pub(super) peer: Option<serde_json::Value>,
    /// Each problem's outcome.
    pub(super) outcomes: &'a [bench::Outcome],
}

/// Print the report: one JSON object with `--json`, else the table.
pub(super) fn print(a: &Args, ompl_time_limit: f64, r: Report) {
    let summary = r.summary;
    if a.json {
        print_json(&SummaryJson {
            collision_checks_per_s: summary.sphere_checks_per_s,
            path_length_rad: LengthJson {
                median: finite(summary.path_length_median),
            },
            peer: r.peer,
            planner: r.planner.to_string(),
            edges_checked: summary.edges,
            engine: format!("{:?}", r.engine),
            problems: summary.problems,
            robot: r.robot.to_string(),
            scene: r.label,
            states_checked: summary.states,
            success_rate: summary.success_rate,
            time_ms: TimeJson {
                max: summary.time_ms[2],
                median: summary.time_ms[0],
                p95: summary.time_ms[1],
            },
            unreached: r.unreached,
        });
        return;
    }
    say!(
        "{} in {}: {} problems, {} s per problem at most{}",
        r.robot,
        r.label,
        summary.problems,
        a.time_limit,
        if a.ompl {
            format!(" ({} s for OMPL)", ompl_time_limit)
        } else {
            String::new()
        }
    );
    if let Some(k) = r.unreached {
        say!(
            "({k} candidates dropped: an end did not reach the arm's home within {} s)",
            REACH_FACTOR * a.time_limit
        );
    }
    say!("(edges proven by {:?})", r.engine);
    say!("");
    print_table(r.planner, summary, r.peer.as_ref());
    print_failures(r.outcomes);
}

/// The table: our planner's row, and OMPL's with the ratio of the medians below.
fn print_table(planner: &str, summary: &bench::Summary, peer: Option<&serde_json::Value>) {
    say!("| planner | success | median ms | p95 ms | max ms | median path rad | sphere checks/s |");
    say!("|---|---|---|---|---|---|---|");
    say!(
        "| {} | {:.1}% | {:.2} | {:.2} | {:.2} | {} | {:.3e} |",
        planner,
        100.0 * summary.success_rate,
        summary.time_ms[0],
        summary.time_ms[1],
        summary.time_ms[2],
        finite(summary.path_length_median).map_or("-".into(), |v| format!("{v:.3}")),
        summary.sphere_checks_per_s
    );
    if let Some(v) = peer {
        let t = &v["time_ms"];
        say!(
            "| OMPL {} RRTConnect + simplify | {:.1}% | {} | {} | {} | {} | - |",
            v["ompl_version"].as_str().unwrap_or("?"),
            100.0 * v["success_rate"].as_f64().unwrap_or(f64::NAN),
            ms(t["median"].as_f64()),
            ms(t["p95"].as_f64()),
            ms(t["max"].as_f64()),
            v["path_length_rad"]["median"]
                .as_f64()
                .map_or("-".into(), |v| format!("{v:.3}")),
        );
        say!("");
        say!(
            "OMPL's median time / ours: {}",
            v["ratio_median"]
                .as_f64()
                .map_or("-".into(), |r| format!("{r:.1}")),
        );
    }
}

/// The first five failures, if any.
fn print_failures(outcomes: &[bench::Outcome]) {
    let failed: Vec<String> = outcomes
        .iter()
        .enumerate()
        .filter(|(_, o)| !o.success)
        .take(5)
        .map(|(i, o)| format!("problem {i}: {}", o.error.as_deref().unwrap_or("failed")))
        .collect();
    if !failed.is_empty() {
        say!("");
        say!("failures (first {}):", failed.len());
        for f in failed {
            say!("  {f}");
        }
    }
}
