//! `ferrobot base-move`: one base motion on the simulated robot.

use ferrobot::config::BaseController;
use ferrobot::GoalOptions;
use serde::Serialize;

use super::common::{print_json, round};

/// `base-move --json`, fields in alphabetical order (see [`print_json`]). Poses are
/// `[x, y, θ]` (m, m, rad) in the start pose's frame.
#[derive(Serialize)]
struct BaseMoveJson {
    /// Why the motion failed; absent when it succeeded.
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
    /// The simulator's ground truth (`null`s without one).
    ground_truth: [f64; 3],
    /// The base's odometry.
    odometry: [f64; 3],
    /// Whether the motion succeeded.
    success: bool,
    /// The relative target.
    target: [f64; 3],
}

/// `ferrobot base-move`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Relative target X Y THETA (m, m, rad) in the start pose's frame.
    #[arg(long, num_args = 3, allow_negative_numbers = true, required = true, value_names = ["X", "Y", "THETA"])]
    pub relative: Vec<f64>,
    /// proportional, lqr, ilqr or dwa (default: the configuration's).
    #[arg(long)]
    pub controller: Option<String>,
    /// LQR/ILQR: a smooth (Bézier) reference.
    #[arg(long)]
    pub smooth: bool,
    /// LQR/ILQR: play the reference open loop.
    #[arg(long)]
    pub open_loop: bool,
    /// Seed of the plants' noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Drive the simulated robot (plants seeded by `--seed`) from rest at the origin to the target
/// `[x, y, θ]` (m, m, rad) relative to its start, and print the target, the odometry and the
/// ground truth. In text mode a failed motion is the error; with `--json` it is reported in
/// the object.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let target = [a.relative[0], a.relative[1], a.relative[2]];
    let controller = a
        .controller
        .as_deref()
        .map(str::parse::<BaseController>)
        .transpose()?;
    let bot = ferrobot_cli::base_trials::base_robot(&a.robot, a.seed, None)?;
    let opts = GoalOptions {
        controller,
        smooth: a.smooth,
        close_loop: !a.open_loop,
        ..Default::default()
    };
    let r = bot.base()?.go_to_relative_with(target, opts)?.wait();
    let odometry = bot.base()?.get_state()?;
    let truth = bot
        .simulator()
        .and_then(|s| s.base_truth())
        .unwrap_or([f64::NAN; 3]);
    if a.json {
        print_json(&BaseMoveJson {
            error: r.as_ref().err().map(ToString::to_string),
            ground_truth: truth,
            odometry,
            success: r.is_ok(),
            target,
        });
        return Ok(());
    }
    say!("target       {:?}", round(&target));
    say!("odometry     {:?}", round(&odometry));
    say!("ground truth {:?}", round(&truth));
    r
}
