//! `ferrobot export-lerobot`: recordings exported as one LeRobot dataset (format v3.0), each
//! recording an episode ([`ferrobot_record::lerobot`]).

use std::path::PathBuf;

use ferrobot_record::lerobot::{export, Demonstration, ExportOptions, Tasks};
use serde::Serialize;

use super::common::{print_json, say};

/// `ferrobot export-lerobot`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The recordings (MCAP files from `ferrobot record`, the recorder or `teleop --record`),
    /// one episode each, in this order.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// The dataset's directory (it must not exist).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Each episode's task, in words: one for all, or one per recording in order.
    #[arg(long, required = true)]
    pub task: Vec<String>,
    /// Frames per second of the dataset (the camera's 30 by default).
    #[arg(long, default_value_t = 30)]
    pub fps: u32,
    /// Leave the camera's frames out.
    #[arg(long)]
    pub no_camera: bool,
    /// The robot's name in the dataset's metadata (`robot_type`).
    #[arg(long)]
    pub robot_type: Option<String>,
    /// The summary as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Summary {
    out: PathBuf,
    episodes: usize,
    frames: usize,
    tasks: usize,
    fps: u32,
    images: bool,
    truncated_recordings: usize,
}

/// Export the recordings.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let tasks = match a.task.as_slice() {
        [one] => Tasks::All(one.clone()),
        each => Tasks::Each(each.to_vec()),
    };
    let demos = Demonstration::of(a.files.clone(), tasks)?;
    let opts = ExportOptions {
        fps: a.fps,
        camera: !a.no_camera,
        robot_type: a.robot_type.clone(),
    };
    let s = export(&demos, &a.out, &opts)?;
    let summary = Summary {
        out: a.out.clone(),
        episodes: s.episodes,
        frames: s.frames,
        tasks: s.tasks,
        fps: a.fps,
        images: s.images,
        truncated_recordings: s.truncated,
    };
    if a.json {
        print_json(&summary);
    } else {
        say(format_args!(
            "{}: {} episodes, {} frames at {} fps, {} task(s){}{}",
            a.out.display(),
            s.episodes,
            s.frames,
            a.fps,
            s.tasks,
            if s.images {
                ", camera frames as PNG"
            } else {
                ""
            },
            match s.truncated {
                0 => String::new(),
                n => format!(" ({n} recordings cut short, exported to their last whole chunk)"),
            }
        ));
    }
    Ok(())
}
