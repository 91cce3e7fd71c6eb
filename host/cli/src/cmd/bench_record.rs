//! `ferrobot bench record`: what recording costs. The simulated LoCoBot drives and moves its arm
//! for --seconds of its time with its camera at 30 Hz (640x480 RGB-D) and telemetry at 100 Hz,
//! twice in one run: with the frames and telemetry only taken (the baseline: the camera renders
//! either way) and with the recorder writing them to MCAP. The real-time factor of each, the
//! recorder thread's CPU time, the file's size and rate, what was dropped, and the firmware's
//! loop overruns.

use std::path::PathBuf;
use std::time::Instant;

use ferrobot::{Backend, Robot};
use ferrobot_record::{RecordOptions, Recorder};
use serde::Serialize;

use super::common::print_json;

/// `ferrobot bench record`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Seconds of the robot's time in each run.
    #[arg(long, default_value_t = 600.0)]
    pub seconds: f64,
    /// Where the recording goes (it must not exist; removed after the run unless --keep).
    #[arg(long, default_value = "target/bench-record.mcap")]
    pub out: PathBuf,
    /// Keep the recording.
    #[arg(long)]
    pub keep: bool,
    /// One JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// One run's figures.
#[derive(Serialize, Default, Clone, Copy)]
struct Run {
    /// Seconds of the robot's time the run took (its last motions end after --seconds).
    robot_s: f64,
    /// Real-time factor: the robot's seconds per wall second.
    rtf: f64,
    /// Wall time, s.
    wall_s: f64,
    /// The process's CPU time (user + system), s.
    cpu_s: f64,
    /// The recorder thread's CPU time, s (0 without it).
    recorder_cpu_s: f64,
    /// Camera frames taken.
    frames: u64,
    /// Telemetry reports taken.
    telemetry: u64,
    /// Frames and reports dropped.
    dropped: u64,
    /// The firmware's loop overruns during the run.
    overruns: u32,
}

/// The report, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct Report {
    /// The baseline: frames and telemetry taken, nothing written.
    baseline: Run,
    /// The file's size, MB.
    file_mb: f64,
    /// MB per second of the robot's time.
    mb_per_robot_s: f64,
    /// MB written per wall second.
    mb_per_wall_s: f64,
    /// With the recorder.
    recording: Run,
    /// Seconds of the robot's time per run.
    seconds: f64,
}

/// CPU time (user + system, s) of this process, or of its thread named `thread`.
fn cpu_seconds(thread: Option<&str>) -> f64 {
    let stat = |path: PathBuf| -> Option<f64> {
        let s = std::fs::read_to_string(path).ok()?;
        // Fields after the command's closing parenthesis: utime and stime are the 12th and
        // 13th, in clock ticks (100 per second on Linux).
        let rest = s.rsplit_once(')')?.1;
        let f: Vec<&str> = rest.split_whitespace().collect();
        Some((f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?) / 100.0)
    };
    let Some(name) = thread else {
        return stat("/proc/self/stat".into()).unwrap_or(0.0);
    };
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return 0.0;
    };
    tasks
        .flatten()
        .filter(|t| std::fs::read_to_string(t.path().join("comm")).is_ok_and(|c| c.trim() == name))
        .filter_map(|t| stat(t.path().join("stat")))
        .sum()
}

/// The robot's work: the base on a slow circle, the arm between two poses every 4 s.
fn work(
    robot: &Robot,
    seconds: f64,
    mut recorder_cpu: impl FnMut() -> f64,
) -> ferrobot::Result<f64> {
    let arm = robot.arm()?;
    let poses = [[0.3, 0.2, -0.3, 0.4, 0.1], [-0.3, 0.1, -0.1, 0.2, -0.1]];
    let end = robot.time() + seconds;
    let mut i = 0;
    let mut cpu = 0.0;
    while robot.time() < end {
        let base = robot.base()?.set_vel_async(0.1, 0.1, 4.0)?;
        let m = arm.move_joints(&poses[i % 2], Default::default())?;
        robot.wait(4.0_f64.min(end - robot.time()).max(1e-3))?;
        let _ = (m.wait(), base.wait());
        i += 1;
        cpu = recorder_cpu();
    }
    Ok(cpu)
}

fn run_once(seconds: f64, out: Option<&PathBuf>) -> ferrobot::Result<Run> {
    let robot = Robot::builder("locobot")
        .backend(Backend::Sim {
            seed: 1,
            realtime: false,
        })
        .build()?;
    let overruns0 = robot.telemetry()?.loop_stats.overruns;
    let t0 = robot.time();
    let (cpu0, wall) = (cpu_seconds(None), Instant::now());
    let mut run = Run::default();
    if let Some(path) = out {
        let recorder = Recorder::start(&robot, path, RecordOptions::default())?;
        run.recorder_cpu_s = work(&robot, seconds, || cpu_seconds(Some("ferrobot-record")))?;
        let stats = recorder.finish()?;
        run.frames = stats.written.frames;
        run.telemetry = stats.written.telemetry;
        run.dropped = stats.frames_dropped + stats.telemetry_dropped;
    } else {
        let tel = robot.subscribe_telemetry(100_000)?;
        let frames = robot.camera()?.subscribe(1000)?;
        work(&robot, seconds, || {
            let _ = (tel.drain(), frames.drain());
            0.0
        })?;
        run.frames = frames.delivered();
        run.telemetry = tel.delivered();
        run.dropped = frames.dropped() + tel.dropped();
    }
    run.wall_s = wall.elapsed().as_secs_f64();
    run.cpu_s = cpu_seconds(None) - cpu0;
    run.robot_s = robot.time() - t0;
    run.rtf = run.robot_s / run.wall_s;
    run.overruns = robot.telemetry()?.loop_stats.overruns - overruns0;
    Ok(run)
}

/// Run both and print the table (or JSON).
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let seconds = ferrobot::validate::seconds("benchmark time", a.seconds)?.as_secs_f64();
    if a.out.exists() {
        return Err(ferrobot::Error::PathExists {
            path: a.out.clone(),
        });
    }
    let baseline = run_once(seconds, None)?;
    let recording = run_once(seconds, Some(&a.out))?;
    let bytes = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0) as f64;
    if !a.keep {
        let _ = std::fs::remove_file(&a.out);
    }
    let r = Report {
        baseline,
        file_mb: bytes / 1e6,
        mb_per_robot_s: bytes / 1e6 / recording.robot_s,
        mb_per_wall_s: bytes / 1e6 / recording.wall_s,
        recording,
        seconds,
    };
    if a.json {
        print_json(&r);
        return Ok(());
    }
    say!("Recording the simulated LoCoBot: {seconds:.0} s of its time, RGB-D 640x480 at 30 Hz, telemetry at 100 Hz");
    say!("| run | robot s | real-time factor | wall s | CPU s | recorder CPU s | frames | telemetry | dropped | loop overruns |");
    say!("|---|---|---|---|---|---|---|---|---|---|");
    for (name, x) in [
        ("frames taken, nothing written", &r.baseline),
        ("recorded to MCAP (lz4 1)", &r.recording),
    ] {
        say!(
            "| {name} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} | {} | {} |",
            x.robot_s,
            x.rtf,
            x.wall_s,
            x.cpu_s,
            x.recorder_cpu_s,
            x.frames,
            x.telemetry,
            x.dropped,
            x.overruns
        );
    }
    say!(
        "file {:.0} MB: {:.1} MB per second of the robot's time, {:.1} MB/s written",
        r.file_mb,
        r.mb_per_robot_s,
        r.mb_per_wall_s
    );
    Ok(())
}
