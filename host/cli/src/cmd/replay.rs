//! `ferrobot replay`: a recording fed back as commands to a robot, or as sensor input to SLAM
//! offline ([`ferrobot_record::replay`]).

use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use ferrobot::slam::{optimise, RgbdInput, Slam, SlamSettings, SELF_RADIUS};
use ferrobot_record::reader::Reading;
use ferrobot_record::replay::{replay_commands, SensorFrames};
use serde::Serialize;

use super::common::{load, print_json, BackendArgs};

/// `ferrobot replay`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The recording (an MCAP file from `ferrobot record` or the recorder).
    pub file: PathBuf,
    /// The robot recorded (name or configuration path).
    #[arg(long, default_value = "locobot")]
    pub robot: String,
    /// Send the recorded commands to the robot, each at its recorded instant (on the
    /// simulator by default: with the recording's seed, the same states).
    #[arg(long, conflicts_with = "slam")]
    pub commands: bool,
    /// Feed the recorded frames and odometry to SLAM offline; writes estimate.tum (the body's
    /// poses, TUM format) to --out if given.
    #[arg(long)]
    pub slam: bool,
    /// Where --slam writes estimate.tum.
    #[arg(long, requires = "slam")]
    pub out: Option<PathBuf>,
    /// --slam's pace: this many seconds of the recording per wall second (0: as fast as it
    /// runs).
    #[arg(long, default_value_t = 0.0)]
    pub speed: f64,
    /// SLAM's start pose `x,y,θ` (m, rad), as the live run had it.
    #[arg(long, value_delimiter = ',', num_args = 3, default_values_t = [0.0, 0.0, 0.0])]
    pub start: Vec<f64>,
    /// Send commands to a robot that is not simulated without asking.
    #[arg(long)]
    pub yes: bool,
    /// Where the commands go (the in-process simulator by default).
    #[command(flatten)]
    pub backend: BackendArgs,
    /// The summary as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Summary {
    commands_sent: u64,
    commands_refused: u64,
    frames: u64,
    slam_final_pose: Option<[f64; 3]>,
    truncated: bool,
}

/// Replay the recording.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    ferrobot::validate::finite("replay speed", &[a.speed])?;
    let speed = a.speed;
    if !(0.0..=1e6).contains(&speed) {
        return Err(ferrobot::Error::OutOfRange {
            what: "replay speed".into(),
            value: speed,
            min: 0.0,
            max: 1e6,
        });
    }
    ferrobot::validate::finite("SLAM start pose", &a.start)?;
    let start = &a.start;
    let summary = match (a.commands, a.slam) {
        (true, _) => commands(a)?,
        (_, true) => slam(a, speed, [start[0], start[1], start[2]])?,
        _ => {
            return Err(ferrobot::Error::Usage(
                "say what to replay: --commands or --slam".into(),
            ))
        }
    };
    if a.json {
        print_json(&summary);
    } else {
        say!(
            "replayed {}: {} commands sent, {} refused, {} frames{}{}",
            a.file.display(),
            summary.commands_sent,
            summary.commands_refused,
            summary.frames,
            summary
                .slam_final_pose
                .map(|p| format!(", SLAM's last pose [{:.3}, {:.3}, {:.3}]", p[0], p[1], p[2]))
                .unwrap_or_default(),
            if summary.truncated {
                " (the recording was cut short)"
            } else {
                ""
            }
        );
    }
    Ok(())
}

fn confirm(a: &Args) -> ferrobot::Result<()> {
    if a.yes {
        return Ok(());
    }
    eprint!(
        "send the recorded commands to a real robot ({})? type yes: ",
        a.robot
    );
    let _ = std::io::stderr().flush();
    let mut line = String::new();
    std::io::stdin().read_line(&mut line)?;
    if line.trim() != "yes" {
        return Err(ferrobot::Error::Usage("replay not confirmed".into()));
    }
    Ok(())
}

fn commands(a: &Args) -> ferrobot::Result<Summary> {
    let backend = a.backend.backend()?;
    // The file is a recording (its magic read) before anyone is asked to confirm.
    drop(Reading::open(&a.file)?);
    if !matches!(backend, ferrobot::Backend::Sim { .. }) {
        confirm(a)?;
    }
    let robot = super::common::robot_builder(&a.robot)
        .backend(backend)
        .build()?;
    let s = replay_commands(&robot, &a.file)?;
    Ok(Summary {
        commands_sent: s.sent,
        commands_refused: s.refused,
        frames: 0,
        slam_final_pose: None,
        truncated: s.truncated,
    })
}

fn slam(a: &Args, speed: f64, start: [f64; 3]) -> ferrobot::Result<Summary> {
    let cfg = load(&a.robot)?;
    let radius = cfg
        .base
        .as_ref()
        .map_or(SELF_RADIUS, |b| b.footprint_radius);
    let mut frames = SensorFrames::open(&a.file)?;
    let (mut slam, mut tum, mut last) = (None::<Slam>, String::new(), None);
    let (wall, mut first) = (Instant::now(), None);
    let mut n = 0;
    for f in frames.by_ref() {
        let f = f?;
        let t = f.time.as_secs_f64();
        let t0 = *first.get_or_insert(t);
        if speed > 0.0 {
            let due = Duration::from_secs_f64((t - t0) / speed);
            std::thread::sleep(due.saturating_sub(wall.elapsed()));
        }
        let s = match slam.as_mut() {
            Some(s) => s,
            None => slam.insert(Slam::new(
                SlamSettings::ground_robot(radius.max(SELF_RADIUS)),
                f.intrinsics,
                optimise::planar(start),
            )?),
        };
        let r = s.track(&RgbdInput {
            time: t,
            rgb: &f.rgb,
            depth: &f.depth,
            camera: f.camera_pose,
            odometry: Some(f.odometry),
        })?;
        let (p, q) = (r.pose.translation.vector, r.pose.rotation.coords);
        tum.push_str(&format!(
            "{t:.6} {} {} {} {} {} {} {}\n",
            p.x, p.y, p.z, q.x, q.y, q.z, q.w
        ));
        last = Some(optimise::to_planar(&r.pose));
        n += 1;
    }
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir)?;
        std::fs::write(dir.join("estimate.tum"), tum)?;
    }
    Ok(Summary {
        commands_sent: 0,
        commands_refused: 0,
        frames: n,
        slam_final_pose: last,
        truncated: frames.truncated(),
    })
}
