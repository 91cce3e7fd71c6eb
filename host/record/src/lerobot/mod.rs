//! Recordings exported as a [LeRobot](https://github.com/huggingface/lerobot) dataset, format
//! v3.0, which LeRobot's `LeRobotDataset` loads: each recording one episode with its task
//! string, sampled at `fps` ([`episode`] says what each feature holds).
//!
//! ```text
//! OUT/meta/info.json                                 features, fps, counts, path templates
//! OUT/meta/stats.json                                per-feature statistics
//! OUT/meta/tasks.parquet                             task strings and their indices
//! OUT/meta/episodes/chunk-000/file-000.parquet       per episode: length, tasks, rows, stats
//! OUT/data/chunk-000/file-000.parquet                one row per frame
//! ```
//!
//! Colour frames go into the data file as PNG images (LeRobot's `image` features), not video:
//! no encoder to bundle, and exact pixels. Depth is not exported (LeRobot's loaders take no
//! 32-bit depth in images). One data file and one chunk hold every episode, row groups of at
//! most [`GROUP_ROWS`] rows.

pub mod columns;
pub mod episode;
mod meta;
pub mod stats;

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::error::{check as in_range, RecordError};
use columns::{ByteArray, Table, Values};
use episode::{Row, Streams};
use meta::{dataset_stats, info, write_episodes, write_tasks};
use stats::{Histograms, Stat};

/// The format version written (`codebase_version`).
pub const CODEBASE_VERSION: &str = "v3.0";
/// Rows per row group of the data file (bounds the PNGs held in memory).
pub const GROUP_ROWS: usize = 256;
/// The name of the colour camera's feature.
pub const IMAGE_KEY: &str = "observation.images.camera";

/// One demonstration: a recording and what it shows.
#[derive(Debug, Clone)]
pub struct Demonstration {
    /// The MCAP recording.
    pub path: PathBuf,
    /// Its task, in words ("pick up the red cube").
    pub task: String,
}

/// The tasks of a set of recordings.
#[derive(Debug, Clone)]
pub enum Tasks {
    /// One task for every recording.
    All(String),
    /// One task per recording, in order.
    Each(Vec<String>),
}

impl Demonstration {
    /// The demonstrations of `recordings` with their `tasks`; refused when [`Tasks::Each`]
    /// does not name one per recording.
    pub fn of(recordings: Vec<PathBuf>, tasks: Tasks) -> Result<Vec<Demonstration>, RecordError> {
        let n = recordings.len();
        let tasks = match tasks {
            Tasks::All(t) => vec![t; n],
            Tasks::Each(t) if t.len() == n => t,
            Tasks::Each(t) => {
                return Err(invalid(format!(
                    "{} tasks for {n} recordings: give one task for all, or one per recording",
                    t.len()
                )))
            }
        };
        Ok(recordings
            .into_iter()
            .zip(tasks)
            .map(|(path, task)| Demonstration { path, task })
            .collect())
    }
}

/// How to export.
#[derive(Debug, Clone)]
pub struct ExportOptions {
    /// Frames per second of the dataset, 1 to 1000.
    pub fps: u32,
    /// Whether to export the colour camera's frames (when every recording has them).
    pub camera: bool,
    /// The robot's name, `robot_type` in `info.json`.
    pub robot_type: Option<String>,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            fps: 30,
            camera: true,
            robot_type: None,
        }
    }
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportStats {
    /// Episodes (one per recording).
    pub episodes: usize,
    /// Frames in all.
    pub frames: usize,
    /// Distinct tasks.
    pub tasks: usize,
    /// Whether the data holds camera frames.
    pub images: bool,
    /// Recordings that were cut short (exported up to their last whole chunk).
    pub truncated: usize,
}

fn invalid(msg: String) -> RecordError {
    RecordError::Dataset(msg)
}

/// Exports `demos` to a new LeRobot dataset in `out` (which must not exist).
pub fn export(
    demos: &[Demonstration],
    out: &Path,
    opts: &ExportOptions,
) -> Result<ExportStats, RecordError> {
    check(demos, opts)?;
    if out.exists() {
        // A dataset is written whole into a new directory, never into one that exists.
        return Err(RecordError::Io {
            what: "creating",
            path: out.to_path_buf(),
            source: std::io::ErrorKind::AlreadyExists.into(),
        });
    }
    let streams = demos
        .iter()
        .map(|d| Streams::read(&d.path))
        .collect::<Result<Vec<_>, _>>()?;
    let layout = Layout::of(&streams, opts)?;
    create_dirs(out)?;
    let tasks = unique_tasks(demos);
    let mut data = Table::new(&out.join("data/chunk-000/file-000.parquet"), vec![]);
    let mut episodes = Vec::new();
    let mut index = 0usize;
    for (e, (s, d)) in streams.iter().zip(demos).enumerate() {
        let task = tasks.iter().position(|t| *t == d.task).unwrap_or(0);
        let ep = write_episode(&mut data, s, (e, task, index), &layout)?;
        index += ep.rows.len();
        episodes.push(ep);
    }
    data.finish()?;
    write_tasks(out, &tasks)?;
    write_episodes(out, &episodes, demos)?;
    write_json(out, "meta/stats.json", &dataset_stats(&episodes, &layout))?;
    write_json(
        out,
        "meta/info.json",
        &info(&layout, index, &episodes, tasks.len(), opts),
    )?;
    Ok(ExportStats {
        episodes: episodes.len(),
        frames: index,
        tasks: tasks.len(),
        images: layout.image.is_some(),
        truncated: streams.iter().filter(|s| s.truncated).count(),
    })
}

/// The arguments' checks, before anything is read or written.
fn check(demos: &[Demonstration], opts: &ExportOptions) -> Result<(), RecordError> {
    in_range("fps", opts.fps as usize, 1000)?;
    if demos.is_empty() {
        return Err(invalid("no recording to export".into()));
    }
    if let Some(d) = demos.iter().find(|d| d.task.trim().is_empty()) {
        return Err(invalid(format!(
            "{}: a demonstration needs a task, in words",
            d.path.display()
        )));
    }
    Ok(())
}

/// What every episode shares: the features' names and the image's size.
#[derive(Debug, Clone)]
struct Layout {
    state: Vec<String>,
    action: Vec<String>,
    /// Width, height (px), when images are exported.
    image: Option<(u32, u32)>,
    fps: u32,
}

impl Layout {
    fn of(streams: &[Streams], opts: &ExportOptions) -> Result<Layout, RecordError> {
        let first = &streams[0];
        let image = match opts.camera {
            true => first.image_size,
            false => None,
        };
        for s in streams {
            if s.state_names() != first.state_names() {
                return Err(invalid(format!(
                    "{} and {} are of different robots (joints {:?} and {:?}): one dataset \
                     holds one robot",
                    first.path.display(),
                    s.path.display(),
                    first.state_names(),
                    s.state_names()
                )));
            }
            if image.is_some() && s.image_size != image {
                return Err(invalid(format!(
                    "{} has camera frames of {:?}, {} of {:?}: export without the camera, or \
                     one camera size",
                    first.path.display(),
                    image,
                    s.path.display(),
                    s.image_size
                )));
            }
        }
        Ok(Layout {
            state: first.state_names(),
            action: first.action_names(),
            image,
            fps: opts.fps,
        })
    }
}

/// One episode as written: its place in the data, its rows (their images dropped once
/// written) and its pixels' counts.
struct Episode {
    index: usize,
    task: usize,
    from: usize,
    rows: Vec<Row>,
    pixels: Option<Histograms>,
}

/// Writes episode `e` (task `task`, first row `from`) of `s` into `data`.
fn write_episode(
    data: &mut Table,
    s: &Streams,
    (e, task, from): (usize, usize, usize),
    layout: &Layout,
) -> Result<Episode, RecordError> {
    let fps = layout.fps;
    let grid = s.grid(fps, layout.image.is_some());
    let mut ep = Episode {
        index: e,
        task,
        from,
        rows: (0..grid.len()).map(|k| s.row(&grid, k, fps)).collect(),
        pixels: None,
    };
    let place = (ep.index, ep.task, ep.from);
    if layout.image.is_none() {
        for (g, chunk) in ep.rows.chunks(GROUP_ROWS).enumerate() {
            data.write_group(&group(chunk, place, g * GROUP_ROWS, layout))?;
        }
        return Ok(ep);
    }
    // The frames the grid picks, encoded in one streaming pass; rows go out a group at a time.
    let frame_of = s.frame_of(&grid);
    let mut wanted = frame_of.clone();
    wanted.dedup();
    let (rows, mut hist) = (&mut ep.rows, Histograms::default());
    let (mut next, mut written) = (0usize, 0usize);
    episode::encode_frames(s, &wanted, |i, img, png| {
        let png = ByteArray::from(png);
        let mut h = Histograms::default();
        h.add_rgb(&img.data);
        while next < rows.len() && frame_of[next] == i {
            hist.merge(&h);
            rows[next].image = Some(png.clone());
            next += 1;
        }
        while next - written >= GROUP_ROWS || (next == rows.len() && written < next) {
            let end = (written + GROUP_ROWS).min(next);
            data.write_group(&group(&rows[written..end], place, written, layout))?;
            rows[written..end].iter_mut().for_each(|r| r.image = None);
            written = end;
        }
        Ok(())
    })?;
    ep.pixels = Some(hist);
    Ok(ep)
}

/// The data file's columns for `rows`, the rows from `first` of the episode `(index, task,
/// from)` (its index, its task's, and its first row's in the dataset).
fn group(
    rows: &[Row],
    (index, task, from): (usize, usize, usize),
    first: usize,
    layout: &Layout,
) -> Vec<(&'static str, Values)> {
    let n = rows.len();
    let mut cols = vec![
        (
            "observation.state",
            Values::F32List(rows.iter().map(|r| r.state.clone()).collect()),
        ),
        (
            "action",
            Values::F32List(rows.iter().map(|r| r.action.clone()).collect()),
        ),
    ];
    if layout.image.is_some() {
        let images = rows
            .iter()
            .map(|r| {
                r.image
                    .clone()
                    .unwrap_or_else(|| ByteArray::from(Vec::new()))
            })
            .collect();
        cols.push((IMAGE_KEY, Values::Image(images)));
    }
    let frame = |k: usize| (first + k) as i64;
    cols.extend([
        (
            "timestamp",
            Values::F32(rows.iter().map(|r| r.timestamp).collect()),
        ),
        ("frame_index", Values::I64((0..n).map(frame).collect())),
        ("episode_index", Values::I64(vec![index as i64; n])),
        (
            "index",
            Values::I64((0..n).map(|k| (from + first + k) as i64).collect()),
        ),
        ("task_index", Values::I64(vec![task as i64; n])),
    ]);
    cols
}

/// The tasks in the order they first appear.
fn unique_tasks(demos: &[Demonstration]) -> Vec<String> {
    let mut tasks: Vec<String> = Vec::new();
    for d in demos {
        if !tasks.contains(&d.task) {
            tasks.push(d.task.clone());
        }
    }
    tasks
}

fn create_dirs(out: &Path) -> Result<(), RecordError> {
    let io = |path: &Path, source| RecordError::Io {
        what: "creating",
        path: path.to_path_buf(),
        source,
    };
    // Never into an existing directory: a dataset is written whole or not at all.
    std::fs::create_dir(out).map_err(|e| io(out, e))?;
    for d in ["meta/episodes/chunk-000", "data/chunk-000"] {
        let p = out.join(d);
        std::fs::create_dir_all(&p).map_err(|e| io(&p, e))?;
    }
    Ok(())
}

fn write_json(out: &Path, rel: &str, v: &Value) -> Result<(), RecordError> {
    let path = out.join(rel);
    let text = serde_json::to_string_pretty(v).map_err(|e| invalid(e.to_string()))?;
    std::fs::write(&path, text + "\n").map_err(|source| RecordError::Io {
        what: "writing",
        path,
        source,
    })
}

/// The statistics of one feature of `ep`, by its name in the data.
fn feature_stats(ep: &[&Episode], key: &str) -> Option<(Vec<Stat>, usize)> {
    let count = ep.iter().map(|e| e.rows.len()).sum();
    let rows = |f: fn(&Row) -> &[f32]| {
        let all: Vec<&[f32]> = ep.iter().flat_map(|e| e.rows.iter().map(f)).collect();
        stats::of_rows(all.into_iter())
    };
    let scalars = |f: &dyn Fn(&Episode, usize) -> f64| {
        let mut v: Vec<f64> = ep
            .iter()
            .flat_map(|e| (0..e.rows.len()).map(move |k| (e, k)))
            .map(|(e, k)| f(e, k))
            .collect();
        vec![Stat::of(&mut v)]
    };
    let s = match key {
        "observation.state" => rows(|r| &r.state),
        "action" => rows(|r| &r.action),
        "timestamp" => scalars(&|e, k| f64::from(e.rows[k].timestamp)),
        "frame_index" => scalars(&|_, k| k as f64),
        "episode_index" => scalars(&|e, _| e.index as f64),
        "index" => scalars(&|e, k| (e.from + k) as f64),
        "task_index" => scalars(&|e, _| e.task as f64),
        IMAGE_KEY => {
            let mut h = Histograms::default();
            for e in ep {
                h.merge(e.pixels.as_ref()?);
            }
            h.stats()
        }
        _ => return None,
    };
    Some((s, count))
}

/// The numeric features of the data, in the data's order.
const NUMERIC: [&str; 7] = [
    "observation.state",
    "action",
    "timestamp",
    "frame_index",
    "episode_index",
    "index",
    "task_index",
];

/// `json!` of a feature's entry in `info.json`.
fn feature(dtype: &str, shape: &[usize], names: Value) -> Value {
    json!({ "dtype": dtype, "shape": shape, "names": names })
}
