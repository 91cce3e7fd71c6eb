//! `ferrobot record`: a robot's streams into an MCAP file ([`ferrobot_record`]).

use std::path::PathBuf;

use ferrobot_record::{RecordOptions, RecordStats, Recorder};
use serde::Serialize;

use super::common::BackendArgs;

/// `ferrobot record`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// The MCAP file to write (it must not exist).
    #[arg(long, short)]
    pub out: PathBuf,
    /// How long to record, s of the robot's time.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Leave the camera out.
    #[arg(long)]
    pub no_camera: bool,
    /// Teach mode while recording: a hand moves the arm and it stays where it is left (see
    /// `Arm::set_teach_mode`); the arm holds where it is once the recording ends.
    #[arg(long)]
    pub teach: bool,
    /// The simulator paced at real time (as a robot is), rather than as fast as it runs.
    #[arg(long)]
    pub realtime: bool,
    /// Print the robot's time (s) on a line of its own every --progress s of it (0: never).
    #[arg(long, default_value_t = 0.0)]
    pub progress: f64,
    /// Where it runs (the in-process simulator by default).
    #[command(flatten)]
    pub backend: BackendArgs,
    /// The summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// What `ferrobot record` prints.
#[derive(Serialize)]
struct Summary {
    file: String,
    seconds: f64,
    messages: u64,
    frames: u64,
    telemetry: u64,
    events: u64,
    frames_dropped: u64,
    telemetry_dropped: u64,
    bytes: u64,
}

/// Record the robot for `--seconds` of its time.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let seconds = ferrobot::validate::seconds("recording time", a.seconds)?.as_secs_f64();
    let progress = ferrobot::validate::seconds("progress period", a.progress)?.as_secs_f64();
    let mut backend = a.backend.backend()?;
    if let ferrobot::Backend::Sim { realtime, .. } = &mut backend {
        *realtime = a.realtime;
    }
    let robot = super::common::robot_builder(&a.robot)
        .backend(backend)
        .build()?;
    let opts = RecordOptions {
        camera: !a.no_camera,
        ..RecordOptions::default()
    };
    let recorder = Recorder::start(&robot, &a.out, opts)?;
    if a.teach {
        robot.arm()?.set_teach_mode(true)?;
    }
    let step = if progress > 0.0 { progress } else { 0.1 };
    let end = robot.time() + seconds;
    while robot.time() < end {
        robot.wait(step.min(end - robot.time()).max(1e-6))?;
        if progress > 0.0 {
            println!("{:.3}", robot.time());
        }
    }
    if a.teach {
        robot.arm()?.set_teach_mode(false)?;
    }
    let stats = recorder.finish()?;
    print_summary(a, seconds, &stats)
}

fn print_summary(a: &Args, seconds: f64, s: &RecordStats) -> ferrobot::Result<()> {
    let bytes = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    let summary = Summary {
        file: a.out.display().to_string(),
        seconds,
        messages: s.written.messages,
        frames: s.written.frames,
        telemetry: s.written.telemetry,
        events: s.written.events,
        frames_dropped: s.frames_dropped,
        telemetry_dropped: s.telemetry_dropped,
        bytes,
    };
    if a.json {
        super::common::print_json(&summary);
    } else {
        say!(
            "recorded {:.1} s into {}: {} messages ({} frames, {} telemetry reports, {} events), {:.1} MB; dropped {} frames, {} reports",
            seconds,
            summary.file,
            summary.messages,
            summary.frames,
            summary.telemetry,
            summary.events,
            bytes as f64 / 1e6,
            summary.frames_dropped,
            summary.telemetry_dropped
        );
    }
    Ok(())
}
