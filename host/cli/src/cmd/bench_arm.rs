//! `ferrobot bench arm ROBOT [--cycles N] [--json] [--out DIR] [--backend ...]`: the arm
//! measured in the manner of ISO 9283: pose accuracy AP and repeatability RP (mm) over five
//! poses in a cube, attained positions by ground truth in the arm's base frame, and the joint
//! tracking (rad) of a planned trajectory through them, commanded against measured every
//! 10 ms, with one plot per joint. The method: `docs/design/cli.md`.

use std::path::Path;

use ferrobot::kinematics::LinkTree;
use ferrobot::Robot;
use nalgebra::{Point3, Vector3};
use serde::Serialize;

use super::common::{print_json, robot_builder, BackendArgs};
use ferrobot_cli::plot::{Canvas, COLOURS};

/// Side of the cube of the five poses, m (centred in the LoCoBot's reach pointing down).
const CUBE_SIDE: f64 = 0.1;
/// The cube's centre in the arm's base frame, m.
const CUBE_CENTRE: [f64; 3] = [0.3, 0.0, 0.25];
/// Sampling period of the tracking record, s.
const TRACK_DT: f64 = 0.01;

/// `ferrobot bench arm`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Cycles through the five poses (ISO 9283: 30).
    #[arg(long, default_value_t = 30)]
    pub cycles: usize,
    /// Where the robot runs.
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Write one PNG per joint (commanded and measured angle over time) here.
    #[arg(long)]
    pub out: Option<std::path::PathBuf>,
    /// Print one JSON object: `{"accuracy_mm_max", "cycles", "poses": [{"accuracy_mm",
    /// "commanded_m", "repeatability_mm"}], "repeatability_mm_max", "tracking": [{"max_rad",
    /// "name", "rms_rad"}], "tracking_duration_s"}`.
    #[arg(long)]
    pub json: bool,
}

/// One pose's figures, fields in alphabetical order.
#[derive(Serialize)]
struct PoseJson {
    /// Accuracy AP, mm.
    accuracy_mm: f64,
    /// The commanded position, m (base frame).
    commanded_m: [f64; 3],
    /// Repeatability RP, mm.
    repeatability_mm: f64,
}

/// Tracking error of one joint, rad.
#[derive(Serialize)]
struct JointJson {
    max_rad: f64,
    name: String,
    rms_rad: f64,
}

/// `bench arm --json`.
#[derive(Serialize)]
struct ArmJson {
    cycles: usize,
    poses: Vec<PoseJson>,
    /// The largest accuracy AP of the five poses, mm.
    accuracy_mm_max: f64,
    /// The largest repeatability RP of the five poses, mm.
    repeatability_mm_max: f64,
    tracking: Vec<JointJson>,
    /// Duration of the streamed trajectory, s.
    tracking_duration_s: f64,
}

/// The five ISO 9283 poses of a cube of side `side` centred on `c`: P1 the centre, P2-P5 on
/// the diagonal plane through the cube's edges (x = -, z = -)...(x = +, z = +), 10 % of the
/// diagonal in from the corners.
pub fn iso_poses(c: [f64; 3], side: f64) -> [[f64; 3]; 5] {
    let h = side / 2.0;
    // The plane's corners (x, y, z) = (±h, ±h, ±h) with z following x: a diagonal plane.
    let corners = [[-h, -h, -h], [h, -h, h], [h, h, h], [-h, h, -h]];
    let mut out = [c; 5];
    for (k, k3) in corners.iter().enumerate() {
        // 10 % of the plane's diagonal (from the centre to the corner: half of it) in.
        for i in 0..3 {
            out[k + 1][i] = c[i] + k3[i] * 0.8;
        }
    }
    out
}

/// Commanded (the trajectory) and measured joint angles over time: (s, rad, rad).
type TrackRecord = Vec<(f64, Vec<f64>, Vec<f64>)>;

/// Run the benchmark and print it.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    ferrobot::validate::count("cycles", a.cycles, 1..=1000)?;
    let bot = robot_builder(&a.robot)
        .backend(a.backend.backend()?)
        .build()?;
    let arm = bot.arm()?;
    let (ie, ib) = arm_links(&bot)?;
    let poses = iso_poses(CUBE_CENTRE, CUBE_SIDE);
    let pitch = std::f64::consts::FRAC_PI_2;
    // Joint targets of the five poses (IK, from the previous one).
    let mut targets = Vec::new();
    let mut seed = arm.get_joint_angles()?;
    for p in &poses {
        let q = arm.compute_ik_pitch_roll(*p, pitch, Some(0.0), Some(&seed))?;
        seed = q.clone();
        targets.push(q);
    }
    // Repeatability and accuracy by ground truth.
    let mut attained: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); 5];
    for _ in 0..a.cycles {
        for (k, q) in targets.iter().enumerate() {
            arm.set_joint_positions(q)?;
            let t = bot.truth()?;
            let p = t.links[ib].inverse() * Point3::from(t.links[ie].translation.vector);
            attained[k].push(p.coords);
        }
    }
    let pose_json = pose_figures(&attained, &poses);
    // Tracking: a planned trajectory through the five poses and back to the first.
    let names = arm.joint_names();
    let (record, duration) = track(&bot, &arm, &targets)?;
    let tracking = tracking_errors(&names, &record);
    if let Some(dir) = a.out.as_deref() {
        plot_tracking(dir, &names, &record, duration)?;
    }
    let out = ArmJson {
        cycles: a.cycles,
        accuracy_mm_max: pose_json.iter().map(|p| p.accuracy_mm).fold(0.0, f64::max),
        repeatability_mm_max: pose_json
            .iter()
            .map(|p| p.repeatability_mm)
            .fold(0.0, f64::max),
        poses: pose_json,
        tracking,
        tracking_duration_s: duration,
    };
    if a.json {
        print_json(&out);
    } else {
        print_text(bot.name(), &out);
    }
    Ok(())
}

/// The indices of the arm's end-effector and base links in the URDF's link tree.
fn arm_links(bot: &Robot) -> ferrobot::Result<(usize, usize)> {
    let cfg = bot.config();
    let ee = cfg
        .arm
        .as_ref()
        .map(|s| s.ee_frame.clone())
        .ok_or_else(|| missing_arm(bot))?;
    let base = cfg
        .arm
        .as_ref()
        .map(|s| s.base_frame.clone())
        .unwrap_or_default();
    let tree = LinkTree::from_urdf(&cfg.urdf)?;
    match (tree.link_index(&ee), tree.link_index(&base)) {
        (Some(e), Some(b)) => Ok((e, b)),
        _ => Err(missing_arm(bot)),
    }
}

/// Accuracy AP and repeatability RP of each pose from its `attained` positions (m, base
/// frame) against the commanded `poses`.
fn pose_figures(attained: &[Vec<Vector3<f64>>], poses: &[[f64; 3]; 5]) -> Vec<PoseJson> {
    let mut pose_json = Vec::new();
    for (k, pts) in attained.iter().enumerate() {
        let n = pts.len() as f64;
        let bary = pts.iter().sum::<Vector3<f64>>() / n;
        let l: Vec<f64> = pts.iter().map(|p| (p - bary).norm()).collect();
        let mean = l.iter().sum::<f64>() / n;
        let s = if pts.len() > 1 {
            (l.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        pose_json.push(PoseJson {
            accuracy_mm: 1e3 * (bary - Vector3::from(poses[k])).norm(),
            commanded_m: poses[k],
            repeatability_mm: 1e3 * (mean + 3.0 * s),
        });
    }
    pose_json
}

/// Planned motions through `targets` and back to the first, the commanded and measured
/// angles recorded every [`TRACK_DT`]; the record and its duration (s).
fn track(
    bot: &Robot,
    arm: &ferrobot::arm::Arm,
    targets: &[Vec<f64>],
) -> ferrobot::Result<(TrackRecord, f64)> {
    let mut record: TrackRecord = Vec::new();
    let mut duration = 0.0;
    for q in targets.iter().skip(1).chain(std::iter::once(&targets[0])) {
        let plan = arm.make_plan_joint_positions(q)?;
        let motion = arm.execute(&plan)?;
        let t0 = bot.time();
        while !motion.is_finished() {
            bot.wait(TRACK_DT)?;
            let t = bot.time() - t0;
            let cmd = plan.trajectory.sample(t.min(plan.duration())).position;
            record.push((duration + t, cmd, arm.get_joint_angles()?));
        }
        motion.wait()?;
        duration += bot.time() - t0;
    }
    Ok((record, duration))
}

/// Max and RMS error of each joint (`names`) over the record, rad.
fn tracking_errors(names: &[String], record: &TrackRecord) -> Vec<JointJson> {
    names
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let e: Vec<f64> = record.iter().map(|(_, c, m)| (c[j] - m[j]).abs()).collect();
            JointJson {
                max_rad: e.iter().copied().fold(0.0, f64::max),
                name: name.clone(),
                rms_rad: (e.iter().map(|v| v * v).sum::<f64>() / e.len().max(1) as f64).sqrt(),
            }
        })
        .collect()
}

/// The figures as text.
fn print_text(robot: &str, out: &ArmJson) {
    say!(
        "ISO 9283 on {} ({} cycles of 5 poses, ground truth):",
        robot,
        out.cycles
    );
    for (k, p) in out.poses.iter().enumerate() {
        say!(
            "  P{}  at {:?} m: accuracy AP {:.2} mm, repeatability RP {:.3} mm",
            k + 1,
            p.commanded_m,
            p.accuracy_mm,
            p.repeatability_mm
        );
    }
    say!(
        "tracking a {:.1} s planned trajectory (commanded vs measured):",
        out.tracking_duration_s
    );
    for j in &out.tracking {
        say!(
            "  {:<8} max {:.4} rad, RMS {:.4} rad",
            j.name,
            j.max_rad,
            j.rms_rad
        );
    }
}

/// One PNG per joint in `dir`: commanded (black) and measured (red) angle over time, the time
/// axis scaled to the canvas' width and the angle to its height (the caption gives both).
fn plot_tracking(
    dir: &Path,
    names: &[String],
    record: &[(f64, Vec<f64>, Vec<f64>)],
    duration: f64,
) -> ferrobot::Result<()> {
    std::fs::create_dir_all(dir)?;
    for (j, name) in names.iter().enumerate() {
        let (lo, hi) = record
            .iter()
            .flat_map(|(_, c, m)| [c[j], m[j]])
            .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
        let range = (hi - lo).max(1e-3) * 1.1;
        let mid = (hi + lo) / 2.0;
        let scale = |t: f64, v: f64| [t / duration.max(1e-9), (v - mid) / range + 0.5];
        let mut c = Canvas::new(800, [0.5, 0.5], 1.0, 0.1)?;
        let cmd: Vec<[f64; 2]> = record.iter().map(|(t, c, _)| scale(*t, c[j])).collect();
        let meas: Vec<[f64; 2]> = record.iter().map(|(t, _, m)| scale(*t, m[j])).collect();
        c.polyline(&cmd, COLOURS[0].1, 3);
        c.polyline(&meas, COLOURS[1].1, 1);
        c.legend(&[
            (COLOURS[0].1, "commanded".into()),
            (COLOURS[1].1, "measured".into()),
        ]);
        c.caption(&format!(
            "{name}: {:.2} to {:.2} rad over {:.1} s (grid: 1/10 of each)",
            mid - range / 2.0,
            mid + range / 2.0,
            duration
        ));
        c.save(&dir.join(format!("tracking_{name}.png")))?;
    }
    Ok(())
}

/// The error for a robot without an arm (or whose arm frames the URDF lacks).
fn missing_arm(bot: &Robot) -> ferrobot::Error {
    ferrobot::Error::NoComponent {
        robot: bot.name().to_string(),
        component: "arm",
    }
}
