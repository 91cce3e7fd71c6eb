//! `ferrobot bench base`: PyRobot's base accuracy trials for every controller, and the
//! circle-tracking plots.

use std::path::PathBuf;

use ferrobot::odometry_calibration::WheelGeometry;
use ferrobot::{validate, GoalOptions};
use ferrobot_cli::base_trials::{
    jobs, markdown, run_trial, summarize, Row, RowJson, Trial, MAX_TRIALS,
};
use ferrobot_cli::circle_tracking::{circle_path, paper_circle, CircleRun};
use ferrobot_cli::odometry_calibration::calibrate_odometry;
use ferrobot_cli::plot::{Canvas, COLOURS};
use rayon::prelude::*;
use serde::Serialize;

use super::calibrate_odometry::{calibration_text, CalibrationJson};
use super::common::print_json;

/// `bench base --json`: one robot's table, circle plots and settings, fields in alphabetical
/// order, here and below (see [`print_json`]).
#[derive(Serialize)]
struct BenchBaseJson<'a> {
    /// How far each circle run ended from the reference's end.
    circle_end_error_m: Vec<CircleEndJson>,
    /// The circle plot's file.
    circle_plot: String,
    /// The file of the plot zoomed on the end of the lap.
    circle_plot_end: String,
    /// The odometry calibration the trials used (with `--calibrate` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    odometry_calibration: Option<CalibrationJson>,
    /// The robot.
    robot: &'a str,
    /// The table's rows.
    rows: Vec<RowJson>,
    /// Trial k's seed is this + k.
    seed: u64,
    /// Trials per target.
    trials_per_target: usize,
}

/// Where one circle run ended.
#[derive(Serialize)]
struct CircleEndJson {
    /// Distance from the reference's end, m.
    error: f64,
    /// The run's name.
    run: &'static str,
}

/// `ferrobot bench base`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robots (repeatable; default locobot and locobot_lite).
    #[arg(long)]
    pub robot: Vec<String>,
    /// Trials per target (the paper: 5).
    #[arg(long, default_value_t = 5)]
    pub trials: usize,
    /// Seed of trial k is SEED + k (the same for every controller).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object per robot, one per line, instead of Markdown.
    #[arg(long)]
    pub json: bool,
    /// Where the circle plots go.
    #[arg(long, default_value = "target/bench-base")]
    pub plot_dir: std::path::PathBuf,
    /// First calibrate each base's odometry (as `ferrobot calibrate-odometry` with seed
    /// SEED + 1000) and run every trial with the calibrated geometry.
    #[arg(long)]
    pub calibrate: bool,
}

/// Run the trials (`trials` per target, trial k seeded `seed + k`) on each of the robots
/// (default: locobot and locobot_lite), draw the circle plots into `plot_dir`, and print
/// one Markdown table or one JSON line per robot. With `calibrate`, each base's odometry is
/// first calibrated (seed `seed + 1000`) and the trials use the estimate.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    validate::count("trials", a.trials, 1..=MAX_TRIALS)?;
    let robots = if a.robot.is_empty() {
        vec!["locobot".to_string(), "locobot_lite".to_string()]
    } else {
        a.robot.clone()
    };
    std::fs::create_dir_all(&a.plot_dir)?;
    for robot in robots {
        bench_robot(a, &robot)?;
    }
    Ok(())
}

/// One robot's table and circle plots, printed.
fn bench_robot(a: &Args, robot: &str) -> ferrobot::Result<()> {
    let calibration = if a.calibrate {
        Some(calibrate_odometry(robot, a.seed + 1000)?)
    } else {
        None
    };
    let geometry = calibration.as_ref().map(|c| c.estimate);
    // Each trial is seeded, so running them on rayon's pool (all cores) in any order gives
    // the same results.
    let jobs = jobs(a.trials, a.seed);
    let bar = progress_bar(jobs.len() as u64 + CircleRun::ALL.len() as u64, robot);
    // Results come back in the jobs' order; the first error in that order is reported.
    let results: Vec<ferrobot::Result<Trial>> = jobs
        .par_iter()
        .map(|&(c, cat, target, sd)| {
            let trial = run_trial(robot, c, cat, target, GoalOptions::default(), sd, geometry);
            bar.inc(1);
            trial
        })
        .collect();
    let trials_done = results.into_iter().collect::<ferrobot::Result<Vec<_>>>()?;
    let rows = summarize(&trials_done);
    let plots = draw_circles(a, robot, geometry, &bar)?;
    bar.finish_and_clear();
    if a.json {
        print_json(&BenchBaseJson {
            circle_end_error_m: plots
                .ends
                .iter()
                .map(|&(run, error)| CircleEndJson { error, run })
                .collect(),
            circle_plot: plots.png.display().to_string(),
            circle_plot_end: plots.png_zoom.display().to_string(),
            odometry_calibration: calibration.as_ref().map(CalibrationJson::new),
            robot,
            rows: rows.iter().map(Row::json).collect(),
            seed: a.seed,
            trials_per_target: a.trials,
        });
    } else {
        if let Some(c) = &calibration {
            say!("{robot}, seed {}: {}\n", a.seed + 1000, calibration_text(c));
        }
        say!("{}", markdown(robot, a.trials, a.seed, &rows));
        say!(
            "Circle tracking, ground truth, in {} (the end zoomed in {}):",
            plots.png.display(),
            plots.png_zoom.display()
        );
        for l in plots.legend {
            say!("- {l}");
        }
        say!("");
    }
    Ok(())
}

/// The progress bar of `len` steps, named after `robot`.
fn progress_bar(len: u64, robot: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} {elapsed}")
            .expect("template")
            .progress_chars("=> "),
    );
    bar.set_message(robot.to_string());
    bar
}

/// The circle plots' files, how far each run ended from the reference's end, and the legend.
struct CirclePlots {
    /// The whole lap.
    png: PathBuf,
    /// The end of the lap, zoomed in.
    png_zoom: PathBuf,
    /// Per run: its name and its end's distance from the reference's end, m.
    ends: Vec<(&'static str, f64)>,
    /// The legend's lines, colour first.
    legend: Vec<String>,
}

/// The circle comparison: the whole lap, and a zoom on its end (±6 cm).
fn draw_circles(
    a: &Args,
    robot: &str,
    geometry: Option<WheelGeometry>,
    bar: &indicatif::ProgressBar,
) -> ferrobot::Result<CirclePlots> {
    let reference: Vec<[f64; 2]> = paper_circle().states.iter().map(|s| [s[0], s[1]]).collect();
    let end_ref = reference.last().copied().unwrap_or([0.0; 2]);
    let mut canvas = Canvas::new(800, [0.0, 0.4], 1.2, 0.1)?;
    let mut zoom = Canvas::new(800, end_ref, 0.12, 0.01)?;
    let mut entries = vec![(COLOURS[0].1, "reference circle (r = 0.4 m)".to_string())];
    let mut legend = vec![format!("{}: reference circle (r = 0.4 m)", COLOURS[0].0)];
    let mut ends = Vec::new();
    let runs = CircleRun::ALL.len();
    for (k, run) in CircleRun::ALL.into_iter().enumerate() {
        let (path, end) = circle_path(robot, run, a.seed, geometry)?;
        // Earlier series wider, so that identical paths stay visible.
        let width = 2 + 2 * (runs - 1 - k);
        canvas.polyline(&path, COLOURS[k + 1].1, width);
        zoom.polyline(&path, COLOURS[k + 1].1, 2 * width);
        let label = format!(
            "{}: ends {:.1} mm from the reference end",
            run.name(),
            end * 1000.0
        );
        legend.push(format!("{}: {label}", COLOURS[k + 1].0));
        entries.push((COLOURS[k + 1].1, label));
        ends.push((run.name(), end));
        bar.inc(1);
    }
    // The reference last, thin, on top.
    canvas.polyline(&reference, COLOURS[0].1, 1);
    zoom.polyline(&reference, COLOURS[0].1, 2);
    let what = if a.calibrate {
        ", calibrated odometry"
    } else {
        ""
    };
    canvas.legend(&entries);
    canvas.caption(&format!(
        "{robot}{what}: circle tracking, ground truth; grid 0.1 m"
    ));
    zoom.legend(&entries);
    zoom.caption(&format!("{robot}{what}: the end of the lap; grid 1 cm"));
    let suffix = if a.calibrate { "_calibrated" } else { "" };
    let png = a.plot_dir.join(format!("circle_{robot}{suffix}.png"));
    let png_zoom = a.plot_dir.join(format!("circle_{robot}{suffix}_end.png"));
    canvas.save(&png)?;
    zoom.save(&png_zoom)?;
    Ok(CirclePlots {
        png,
        png_zoom,
        ends,
        legend,
    })
}
