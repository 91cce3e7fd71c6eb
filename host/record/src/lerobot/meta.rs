//! The dataset's metadata: `info.json`, `stats.json`, the tasks and the episodes, as LeRobot
//! v3.0 writes them.

use std::path::Path;

use serde_json::{json, Value};

use super::columns::{Table, Values};
use super::stats::Stat;
use super::{
    feature, feature_stats, invalid, Demonstration, Episode, ExportOptions, Layout,
    CODEBASE_VERSION, IMAGE_KEY, NUMERIC,
};
use crate::error::RecordError;

/// `meta/tasks.parquet`: pandas' layout of LeRobot's task table, the task strings as the
/// index (named `task`) and a `task_index` column; pandas' schema in the file's metadata
/// says which is the index.
pub(super) fn write_tasks(out: &Path, tasks: &[String]) -> Result<(), RecordError> {
    let pandas = json!({
        "index_columns": ["task"],
        "column_indexes": [{
            "name": null, "field_name": null, "pandas_type": "unicode",
            "numpy_type": "object", "metadata": {"encoding": "UTF-8"}
        }],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
             "numpy_type": "int64", "metadata": null},
            {"name": "task", "field_name": "task", "pandas_type": "unicode",
             "numpy_type": "object", "metadata": null}
        ],
        "creator": {"library": "ferrobot-record", "version": env!("CARGO_PKG_VERSION")},
        "pandas_version": "2.2.0"
    });
    let mut t = Table::new(
        &out.join("meta/tasks.parquet"),
        vec![("pandas".into(), pandas.to_string())],
    );
    t.write_group(&[
        ("task_index", Values::I64((0..tasks.len() as i64).collect())),
        ("task", Values::Str(tasks.to_vec())),
    ])?;
    t.finish()
}

/// `meta/episodes/chunk-000/file-000.parquet`: per episode its index, tasks, length, where
/// its rows are, and its statistics (`stats/FEATURE/STAT`, the numeric features').
pub(super) fn write_episodes(
    out: &Path,
    episodes: &[Episode],
    demos: &[Demonstration],
) -> Result<(), RecordError> {
    let n = episodes.len();
    let ints =
        |f: &dyn Fn(&Episode) -> usize| Values::I64(episodes.iter().map(|e| f(e) as i64).collect());
    let mut cols: Vec<(String, Values)> = vec![
        ("episode_index".into(), ints(&|e| e.index)),
        (
            "tasks".into(),
            Values::StrList(demos.iter().map(|d| vec![d.task.clone()]).collect()),
        ),
        ("length".into(), ints(&|e| e.rows.len())),
        ("data/chunk_index".into(), Values::I64(vec![0; n])),
        ("data/file_index".into(), Values::I64(vec![0; n])),
        ("dataset_from_index".into(), ints(&|e| e.from)),
        ("dataset_to_index".into(), ints(&|e| e.from + e.rows.len())),
        ("meta/episodes/chunk_index".into(), Values::I64(vec![0; n])),
        ("meta/episodes/file_index".into(), Values::I64(vec![0; n])),
    ];
    for key in NUMERIC {
        let per: Vec<(Vec<Stat>, usize)> = episodes
            .iter()
            .map(|e| feature_stats(&[e], key).ok_or_else(|| invalid(format!("no {key}"))))
            .collect::<Result<_, _>>()?;
        let stat = |f: fn(&Stat) -> f64| {
            Values::F64List(per.iter().map(|(s, _)| s.iter().map(f).collect()).collect())
        };
        cols.push((format!("stats/{key}/min"), stat(|s| s.min)));
        cols.push((format!("stats/{key}/max"), stat(|s| s.max)));
        cols.push((format!("stats/{key}/mean"), stat(|s| s.mean)));
        cols.push((format!("stats/{key}/std"), stat(|s| s.std)));
        cols.push((
            format!("stats/{key}/count"),
            Values::I64(per.iter().map(|(_, c)| *c as i64).collect()),
        ));
    }
    let mut t = Table::new(
        &out.join("meta/episodes/chunk-000/file-000.parquet"),
        vec![],
    );
    t.write_group(&cols)?;
    t.finish()
}

/// `meta/stats.json`: every feature's statistics over the whole dataset.
pub(super) fn dataset_stats(episodes: &[Episode], layout: &Layout) -> Value {
    let all: Vec<&Episode> = episodes.iter().collect();
    let mut m = serde_json::Map::new();
    let keys = NUMERIC
        .iter()
        .copied()
        .chain(layout.image.map(|_| IMAGE_KEY));
    for key in keys {
        if let Some((s, count)) = feature_stats(&all, key) {
            m.insert(
                key.into(),
                super::stats::to_json(&s, count, key == IMAGE_KEY),
            );
        }
    }
    Value::Object(m)
}

/// `meta/info.json`.
pub(super) fn info(
    layout: &Layout,
    frames: usize,
    episodes: &[Episode],
    tasks: usize,
    opts: &ExportOptions,
) -> Value {
    let mut features = serde_json::Map::new();
    features.insert(
        "observation.state".into(),
        feature("float32", &[layout.state.len()], json!(layout.state)),
    );
    features.insert(
        "action".into(),
        feature("float32", &[layout.action.len()], json!(layout.action)),
    );
    if let Some((w, h)) = layout.image {
        features.insert(
            IMAGE_KEY.into(),
            feature(
                "image",
                &[h as usize, w as usize, 3],
                json!(["height", "width", "channels"]),
            ),
        );
    }
    features.insert("timestamp".into(), feature("float32", &[1], Value::Null));
    for k in ["frame_index", "episode_index", "index", "task_index"] {
        features.insert(k.into(), feature("int64", &[1], Value::Null));
    }
    json!({
        "codebase_version": CODEBASE_VERSION,
        "robot_type": opts.robot_type,
        "total_episodes": episodes.len(),
        "total_frames": frames,
        "total_tasks": tasks,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 200,
        "fps": layout.fps,
        "splits": {"train": format!("0:{}", episodes.len())},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": null,
        "features": features,
    })
}
