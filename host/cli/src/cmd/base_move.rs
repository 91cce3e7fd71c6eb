//! `ferrobot base-move`: one base motion on the simulated robot.

use ferrobot::config::BaseController;
use ferrobot::GoalOptions;
use serde_json::json;

use super::common::round;

/// Drive the simulated `robot` (plants seeded by `seed`) from rest at the origin to `target`
/// `[x, y, θ]` (m, m, rad) relative to its start, and print the target, the odometry and the
/// ground truth. In text mode a failed motion is the error; with `json` it is reported in
/// the object.
pub fn run(
    robot: &str,
    target: [f64; 3],
    controller: Option<&str>,
    smooth: bool,
    open_loop: bool,
    seed: u64,
    json: bool,
) -> ferrobot::Result<()> {
    let controller = controller.map(str::parse::<BaseController>).transpose()?;
    let bot = ferrobot_cli::bench_base::base_robot(robot, seed, None)?;
    let opts = GoalOptions {
        controller,
        smooth,
        close_loop: !open_loop,
        ..Default::default()
    };
    let r = bot.base()?.go_to_relative_with(target, opts)?.wait();
    let odometry = bot.base()?.get_state()?;
    let truth = bot
        .simulator()
        .and_then(|s| s.base_truth())
        .unwrap_or([f64::NAN; 3]);
    if json {
        let mut o = json!({
            "success": r.is_ok(),
            "target": target,
            "odometry": odometry,
            "ground_truth": truth,
        });
        if let Err(e) = &r {
            o["error"] = json!(e.to_string());
        }
        println!("{o}");
        return Ok(());
    }
    println!("target       {:?}", round(&target));
    println!("odometry     {:?}", round(&odometry));
    println!("ground truth {:?}", round(&truth));
    r
}
