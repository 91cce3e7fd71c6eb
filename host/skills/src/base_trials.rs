//! The base accuracy trials of PyRobot's Table 1 on the simulated bases: each controller
//! drives to the paper's relative targets; errors are measured against the simulator's ground
//! truth (the paper's motion capture) and against odometry (the controller's own view), and
//! summed up in the table's rows. Translation errors are in mm, rotation errors in degrees.

use ferrobot::base_control::wrap;
use ferrobot::config::BaseController;
use ferrobot::error::{Error, Result};
use ferrobot::odometry_calibration::WheelGeometry;
use ferrobot::{Backend, GoalOptions, Robot};
use serde::Serialize;

/// A motion category of the paper's trials.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Category {
    /// ±2 m straight ahead.
    Linear,
    /// ±π/2 in place.
    Rotation,
    /// ±(1, 1) m, same heading.
    Combined,
}

impl Category {
    /// Every category, in the table's order.
    pub const ALL: [Category; 3] = [Category::Linear, Category::Rotation, Category::Combined];

    /// Name in tables and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Category::Linear => "linear",
            Category::Rotation => "rotation",
            Category::Combined => "combined",
        }
    }

    /// The paper's two relative targets `[x, y, θ]` (m, m, rad) of the category.
    pub fn targets(self) -> [[f64; 3]; 2] {
        use std::f64::consts::FRAC_PI_2;
        match self {
            Category::Linear => [[2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]],
            Category::Rotation => [[0.0, 0.0, FRAC_PI_2], [0.0, 0.0, -FRAC_PI_2]],
            Category::Combined => [[1.0, 1.0, 0.0], [-1.0, -1.0, 0.0]],
        }
    }
}

/// One trial: where the base was told to go and where it ended, by odometry and in truth.
#[derive(Debug, Clone, Copy)]
pub struct Trial {
    /// The controller.
    pub controller: BaseController,
    /// The category.
    pub category: Category,
    /// Relative target `[x, y, θ]` from the start pose.
    pub target: [f64; 3],
    /// Whether the motion reported success.
    pub success: bool,
    /// Final odometry pose (odometry reset at the start).
    pub odometry: [f64; 3],
    /// Final ground-truth pose (the base starts at the origin).
    pub truth: [f64; 3],
}

impl Trial {
    /// Translation (m) and rotation (rad) errors of `pose` against the target.
    pub fn errors(&self, pose: [f64; 3]) -> (f64, f64) {
        (
            (pose[0] - self.target[0]).hypot(pose[1] - self.target[1]),
            wrap(pose[2] - self.target[2]).abs(),
        )
    }
}

/// A simulated base-only robot with the plants seeded by `seed`; its odometry uses
/// `geometry` when given (a calibration), else the nominal one.
pub fn base_robot(robot: &str, seed: u64, geometry: Option<WheelGeometry>) -> Result<Robot> {
    let bot = Robot::builder(robot)
        .use_arm(false)
        .use_gripper(false)
        .use_camera(false)
        .backend(Backend::Sim {
            seed,
            realtime: false,
        })
        .build()?;
    if let Some(g) = geometry {
        bot.base()?.set_odometry_geometry(g)?;
    }
    Ok(bot)
}

/// The simulator's ground-truth base pose `[x, y, θ]` (the paper's motion capture).
pub fn truth(bot: &Robot) -> Result<[f64; 3]> {
    bot.simulator()
        .and_then(|s| s.base_truth())
        .ok_or_else(|| Error::Link("the benchmark needs the simulated backend".into()))
}

/// Most trials per target of a table.
pub const MAX_TRIALS: usize = 100;

/// One robot's trials: every controller, category and target, `trials` times each, trial k
/// seeded `seed + k` (the same seeds for every controller).
pub fn jobs(trials: usize, seed: u64) -> Vec<(BaseController, Category, [f64; 3], u64)> {
    let mut jobs = Vec::new();
    for c in BaseController::ALL {
        for cat in Category::ALL {
            for target in cat.targets() {
                for k in 0..trials {
                    jobs.push((c, cat, target, seed + k as u64));
                }
            }
        }
    }
    jobs
}

/// Run one motion from rest at the origin on a fresh simulated `robot` whose odometry uses
/// `geometry` (nominal when `None`).
pub fn run_trial(
    robot: &str,
    controller: BaseController,
    category: Category,
    target: [f64; 3],
    opts: GoalOptions,
    seed: u64,
    geometry: Option<WheelGeometry>,
) -> Result<Trial> {
    let bot = base_robot(robot, seed, geometry)?;
    let opts = GoalOptions {
        controller: Some(controller),
        ..opts
    };
    let success = bot
        .base()?
        .go_to_relative_with(target, opts)?
        .wait()
        .is_ok();
    let odometry = bot.base()?.get_state()?;
    let truth = truth(&bot)?;
    Ok(Trial {
        controller,
        category,
        target,
        success,
        odometry,
        truth,
    })
}

/// Which pose the errors are measured on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Measured {
    /// The simulator's ground truth (the paper's motion capture).
    GroundTruth,
    /// The base's odometry.
    Odometry,
}

/// One row of the table.
#[derive(Debug, Clone)]
pub struct Row {
    /// The controller.
    pub controller: BaseController,
    /// The category.
    pub category: Category,
    /// The pose measured.
    pub reference: Measured,
    /// Mean and sample standard deviation of the translation error, mm.
    pub translation_mm: [f64; 2],
    /// Mean and sample standard deviation of the rotation error, degrees.
    pub rotation_deg: [f64; 2],
    /// Trials that reported success, of all.
    pub successes: (usize, usize),
}

fn mean_std(v: &[f64]) -> [f64; 2] {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = if v.len() > 1 {
        v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    [m, var.sqrt()]
}

/// Mean ± std per controller, category and reference.
pub fn summarize(trials: &[Trial]) -> Vec<Row> {
    let mut rows = Vec::new();
    for c in BaseController::ALL {
        for cat in Category::ALL {
            let ts: Vec<&Trial> = trials
                .iter()
                .filter(|t| t.controller == c && t.category == cat)
                .collect();
            if ts.is_empty() {
                continue;
            }
            for r in [Measured::GroundTruth, Measured::Odometry] {
                let e: Vec<(f64, f64)> = ts
                    .iter()
                    .map(|t| {
                        t.errors(match r {
                            Measured::GroundTruth => t.truth,
                            Measured::Odometry => t.odometry,
                        })
                    })
                    .collect();
                let tr: Vec<f64> = e.iter().map(|e| e.0 * 1000.0).collect();
                let rot: Vec<f64> = e.iter().map(|e| e.1.to_degrees()).collect();
                rows.push(Row {
                    controller: c,
                    category: cat,
                    reference: r,
                    translation_mm: mean_std(&tr),
                    rotation_deg: mean_std(&rot),
                    successes: (ts.iter().filter(|t| t.success).count(), ts.len()),
                });
            }
        }
    }
    rows
}

impl Measured {
    /// Name in tables and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Measured::GroundTruth => "ground_truth",
            Measured::Odometry => "odometry",
        }
    }
}

/// The table as Markdown.
pub fn markdown(robot: &str, trials_per_target: usize, seed: u64, rows: &[Row]) -> String {
    let mut s = format!(
        "### {robot}: {trials_per_target} trials per target, seed {seed}\n\n\
         | controller | category | reference | translation (mm) | rotation (°) | succeeded |\n\
         |---|---|---|---|---|---|\n"
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {} | {:.1} ± {:.1} | {:.2} ± {:.2} | {}/{} |\n",
            r.controller.name(),
            r.category.name(),
            r.reference.name(),
            r.translation_mm[0],
            r.translation_mm[1],
            r.rotation_deg[0],
            r.rotation_deg[1],
            r.successes.0,
            r.successes.1
        );
    }
    s
}

/// A row of the table as in the command line's `--json`: the fields of [`Row`] with names
/// for the enums, in alphabetical order (the order the command line has always printed).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RowJson {
    /// [`Category::name`].
    pub category: &'static str,
    /// [`BaseController::name`].
    pub controller: &'static str,
    /// [`Measured::name`].
    pub reference: &'static str,
    /// Mean and sample standard deviation of the rotation error, degrees.
    pub rotation_deg: [f64; 2],
    /// Trials that reported success, and all trials.
    pub successes: [usize; 2],
    /// Mean and sample standard deviation of the translation error, mm.
    pub translation_mm: [f64; 2],
}

impl Row {
    /// The row as in the command line's `--json`.
    pub fn json(&self) -> RowJson {
        RowJson {
            category: self.category.name(),
            controller: self.controller.name(),
            reference: self.reference.name(),
            rotation_deg: self.rotation_deg,
            successes: [self.successes.0, self.successes.1],
            translation_mm: self.translation_mm,
        }
    }
}
