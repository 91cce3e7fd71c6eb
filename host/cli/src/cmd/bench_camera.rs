//! `ferrobot bench camera`: the simulator's real-time factor for the LoCoBot with its camera
//! streaming at 30 Hz while the base drives, per scene, beside the same run without frames.

use std::time::Instant;

use ferrobot::Robot;
use serde::Serialize;

use super::common::print_json;

/// One scene's row, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct RowJson {
    /// Frames taken.
    frames: usize,
    /// Wall time per frame, including the simulation between frames, ms.
    ms_per_frame: f64,
    /// Simulated seconds per wall-clock second, camera streaming.
    real_time_factor: f64,
    /// Simulated seconds per wall-clock second, the same program without frames.
    real_time_factor_blind: f64,
    /// The scene.
    scene: String,
    /// Simulated time of the run with the camera, s.
    sim_seconds: f64,
}

/// Drive `seconds` of simulated time in `scene`: the base on a 0.5 m circle, a frame every
/// camera period (with `camera`), or the same waits without frames. Returns (frames, simulated
/// s, wall s) of the loop.
fn drive(scene: &str, seconds: f64, camera: bool) -> ferrobot::Result<(usize, f64, f64)> {
    let bot = Robot::builder("locobot").scene(scene).build()?;
    let cam = bot.camera()?;
    bot.head()?.set_pan_tilt(0.0, 0.3)?;
    let period = 1.0 / 30.0;
    let n = (seconds / period).round() as usize;
    let (t0, s0) = (Instant::now(), bot.time());
    let _drive = bot.base()?.set_vel_async(0.15, 0.3, seconds)?;
    for _ in 0..n {
        if camera {
            cam.get_frame()?;
        } else {
            bot.wait(period)?;
        }
    }
    Ok((n, bot.time() - s0, t0.elapsed().as_secs_f64()))
}

/// `ferrobot bench camera`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Scenes (repeatable; default tabletop and apartment).
    #[arg(long)]
    pub scene: Vec<String>,
    /// Simulated seconds per run.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Print one JSON object per scene, one per line, instead of Markdown.
    #[arg(long)]
    pub json: bool,
}

/// Run the benchmark for the scenes (default: tabletop and apartment), `--seconds` of
/// simulated time each.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let scenes = if a.scene.is_empty() {
        vec!["tabletop".to_string(), "apartment".to_string()]
    } else {
        a.scene.clone()
    };
    let (seconds, json) = (a.seconds, a.json);
    ferrobot::validate::in_range("seconds", seconds, 0.1, 600.0)?;
    if !json {
        say!("| scene | simulated s | frames | wall ms per frame | real-time factor (camera at 30 Hz) | real-time factor (no camera) |");
        say!("|---|---|---|---|---|---|");
    }
    for scene in &scenes {
        let (frames, sim, wall) = drive(scene, seconds, true)?;
        let (_, sim_blind, blind) = drive(scene, seconds, false)?;
        let row = RowJson {
            frames,
            ms_per_frame: 1e3 * wall / frames.max(1) as f64,
            real_time_factor: sim / wall,
            real_time_factor_blind: sim_blind / blind,
            scene: scene.clone(),
            sim_seconds: sim,
        };
        if json {
            print_json(&row);
        } else {
            say!(
                "| {} | {:.1} | {} | {:.2} | {:.1} | {:.0} |",
                row.scene,
                row.sim_seconds,
                row.frames,
                row.ms_per_frame,
                row.real_time_factor,
                row.real_time_factor_blind
            );
        }
    }
    Ok(())
}
