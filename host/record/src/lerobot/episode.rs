//! One recording as one episode of a dataset: its streams sampled on a grid of `fps` frames a
//! second of the robot's time. A first pass reads every small stream (joint states, odometry,
//! velocity commands, the colour frames' instants); a second streams the colour frames and
//! encodes the ones the grid picks as PNG, so an episode of any length holds only its small
//! streams in memory.
//!
//! - `observation.state`: every joint's position at the frame's instant (rad; m for a
//!   prismatic joint), the last report at or before it; with a base, its odometry (x, y in m,
//!   yaw in rad) after them.
//! - `action`: the joint positions the demonstration reached one frame later (what a position
//!   policy commands; the last frame's is its own), and with a base the velocity command in
//!   force (m/s, rad/s; 0 before the first).
//! - `observation.images.camera`: the colour frame nearest the instant.

use std::path::{Path, PathBuf};

use ferrobot::perception::RgbImage;

use super::columns::ByteArray;
use crate::decode;
use crate::error::RecordError;
use crate::reader::Reading;
use crate::topics;

/// The small streams of one recording, read in a first pass.
#[derive(Debug, Clone, Default)]
pub struct Streams {
    /// The recording.
    pub path: PathBuf,
    /// The joint table's names, from the first joint state.
    pub joints: Vec<String>,
    /// Joint positions: (ns, one per joint).
    pub states: Vec<(u64, Vec<f64>)>,
    /// The base's odometry: (ns, [x m, y m, yaw rad]).
    pub odom: Vec<(u64, [f64; 3])>,
    /// Velocity commands: (ns, [m/s, rad/s]).
    pub cmd_vel: Vec<(u64, [f64; 2])>,
    /// The colour frames' instants, ns.
    pub frames: Vec<u64>,
    /// The colour frames' size (width, height), px.
    pub image_size: Option<(u32, u32)>,
    /// Whether the recording was cut short.
    pub truncated: bool,
}

/// One row of an episode, before the dataset's indices.
#[derive(Debug, Clone)]
pub struct Row {
    /// Seconds since the episode's first frame (`frame / fps`).
    pub timestamp: f32,
    /// `observation.state`.
    pub state: Vec<f32>,
    /// `action`.
    pub action: Vec<f32>,
    /// The colour frame as PNG, when the dataset has images (shared by the rows that show
    /// the same frame, not copied).
    pub image: Option<ByteArray>,
}

impl Streams {
    /// Reads the small streams of the recording at `path`.
    pub fn read(path: &Path) -> Result<Streams, RecordError> {
        let mut s = Streams {
            path: path.to_path_buf(),
            ..Streams::default()
        };
        let mut reading = Reading::open(path)?;
        for m in reading.by_ref() {
            let m = m?;
            let t = m.time_ns;
            match &*m.topic {
                n if n == topics::JOINT_STATES.name => {
                    let (_, names, q, _, _) = decode::joint_state(&m.data)?;
                    if s.joints.is_empty() {
                        s.joints = names.clone();
                    }
                    if names != s.joints {
                        return Err(RecordError::Dataset(format!(
                            "{}: the joint states change their names at {:.3} s",
                            path.display(),
                            t as f64 * 1e-9
                        )));
                    }
                    s.states.push((t, q));
                }
                n if n == topics::ODOM.name => s.odom.push((t, decode::odometry_pose(&m.data)?)),
                n if n == topics::CMD_VEL.name => s.cmd_vel.push((t, decode::twist(&m.data)?)),
                n if n == topics::COLOR.name => {
                    let (w, h, _) = decode::image_size(&m.data)?;
                    s.image_size.get_or_insert((w, h));
                    s.frames.push(t);
                }
                _ => {}
            }
        }
        s.truncated = reading.truncated;
        // Within a topic the file is in time order; make sure of it.
        s.states.sort_by_key(|e| e.0);
        s.odom.sort_by_key(|e| e.0);
        s.cmd_vel.sort_by_key(|e| e.0);
        // The frames stay in the file's order: the second pass (`encode_frames`) counts them
        // in it. One writer thread writes them in time order; a file that does not is refused.
        if !s.frames.is_sorted() {
            return Err(RecordError::Dataset(format!(
                "{}: colour frames out of time order",
                path.display()
            )));
        }
        if s.states.is_empty() {
            return Err(RecordError::Dataset(format!(
                "{}: no joint states: nothing to make an episode of",
                path.display()
            )));
        }
        Ok(s)
    }

    /// The names of `observation.state`'s entries.
    pub fn state_names(&self) -> Vec<String> {
        let mut n = self.joints.clone();
        if !self.odom.is_empty() {
            n.extend(["odom_x", "odom_y", "odom_yaw"].map(String::from));
        }
        n
    }

    /// The names of `action`'s entries.
    pub fn action_names(&self) -> Vec<String> {
        let mut n = self.joints.clone();
        if !self.odom.is_empty() {
            n.extend(["cmd_vel_linear", "cmd_vel_angular"].map(String::from));
        }
        n
    }

    /// The grid's instants (ns) at `fps`: from the first colour frame to the last (`camera`),
    /// or from the first joint state to the last.
    pub fn grid(&self, fps: u32, camera: bool) -> Vec<u64> {
        let (first, last) = match (camera, self.frames.first(), self.frames.last()) {
            (true, Some(&a), Some(&b)) => (a, b),
            _ => (self.states[0].0, self.states[self.states.len() - 1].0),
        };
        let period = 1e9 / f64::from(fps);
        // A thousandth of a period of slack: frame clocks tick in whole microseconds.
        let n = ((last - first) as f64 / period + 1e-3).floor() as u64 + 1;
        (0..n)
            .map(|k| first + (k as f64 * period).round() as u64)
            .collect()
    }

    /// Row `k` of `grid` (its colour frame to be filled in): the state at its instant and the
    /// action one frame later.
    pub fn row(&self, grid: &[u64], k: usize, fps: u32) -> Row {
        let t = grid[k];
        let next = grid[(k + 1).min(grid.len() - 1)];
        let joints =
            |at| -> Vec<f32> { latest(&self.states, at).iter().map(|&q| q as f32).collect() };
        let (mut state, mut action) = (joints(t), joints(next));
        if !self.odom.is_empty() {
            state.extend(latest(&self.odom, t).map(|v| v as f32));
            let cmd = at_or_before(&self.cmd_vel, t).map_or([0.0; 2], |c| c.1);
            action.extend(cmd.map(|v| v as f32));
        }
        Row {
            timestamp: (k as f64 / f64::from(fps)) as f32,
            state,
            action,
            image: None,
        }
    }

    /// For each instant of `grid`, the index of its colour frame in [`Streams::frames`]: the
    /// nearest one (the earlier of two as near).
    pub fn frame_of(&self, grid: &[u64]) -> Vec<usize> {
        let f = &self.frames;
        grid.iter()
            .map(|&t| {
                let after = f.partition_point(|&x| x < t);
                match (after.checked_sub(1), f.get(after)) {
                    (Some(b), Some(&a)) if a - t < t - f[b] => after,
                    (Some(b), _) => b,
                    (None, _) => 0,
                }
            })
            .collect()
    }
}

/// The entry of `series` (sorted by time) at or before `t`.
fn at_or_before<T>(series: &[(u64, T)], t: u64) -> Option<&(u64, T)> {
    let i = series.partition_point(|e| e.0 <= t);
    i.checked_sub(1).and_then(|i| series.get(i))
}

/// The value of `series` (sorted, not empty) in force at `t`: the last at or before it, or
/// the first.
fn latest<T: Clone>(series: &[(u64, T)], t: u64) -> T {
    at_or_before(series, t).unwrap_or(&series[0]).1.clone()
}

/// Streams the colour frames of `streams`' recording, calling `each(index, image, png)` for
/// the frames `wanted` names (sorted indices into [`Streams::frames`], each once), in order.
pub fn encode_frames(
    streams: &Streams,
    wanted: &[usize],
    mut each: impl FnMut(usize, &RgbImage, Vec<u8>) -> Result<(), RecordError>,
) -> Result<(), RecordError> {
    let mut reading = Reading::open(&streams.path)?;
    let (mut i, mut next) = (0usize, 0usize);
    for m in reading.by_ref() {
        let m = m?;
        if &*m.topic != topics::COLOR.name {
            continue;
        }
        if wanted.get(next) == Some(&i) {
            let img = decode::rgb(&m.data)?;
            each(i, &img, png_of(&img, &streams.path)?)?;
            next += 1;
            if next == wanted.len() {
                return Ok(());
            }
        }
        i += 1;
    }
    Err(RecordError::Decode(format!(
        "{}: fewer colour frames on the second reading",
        streams.path.display()
    )))
}

/// `img` as a PNG file's bytes (fast compression: camera noise compresses little anyway).
fn png_of(img: &RgbImage, path: &Path) -> Result<Vec<u8>, RecordError> {
    let mut out = Vec::with_capacity(img.data.len() / 2);
    let err = |e: png::EncodingError| RecordError::Io {
        what: "encoding a frame of",
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    };
    let mut enc = png::Encoder::new(&mut out, img.width, img.height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Fast);
    let mut w = enc.write_header().map_err(err)?;
    w.write_image_data(&img.data).map_err(err)?;
    w.finish().map_err(err)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn streams() -> Streams {
        Streams {
            joints: vec!["a".into()],
            states: (0..=100)
                .map(|k| (k * 10_000_000, vec![k as f64]))
                .collect(),
            frames: (0..=30).map(|k| k * 33_333_000).collect(),
            image_size: Some((4, 2)),
            ..Streams::default()
        }
    }

    #[test]
    fn the_grid_spans_the_frames_at_fps_and_picks_the_nearest_frame() {
        let s = streams();
        let g = s.grid(30, true);
        // 31 frames over 0.99999 s (a clock of whole microseconds): 31 rows at 30 fps, the
        // last 10 µs after the last frame, within the grid's slack.
        assert_eq!(g.len(), 31, "{:?}", &g[g.len() - 2..]);
        assert_eq!(s.frame_of(&g), (0..31).collect::<Vec<_>>());
        // At 10 fps every third frame.
        let g10 = s.grid(10, true);
        assert_eq!(s.frame_of(&g10), (0..11).map(|k| 3 * k).collect::<Vec<_>>());
        // Without the camera, the joint states' span: 1 s at 10 fps is 11 rows.
        assert_eq!(s.grid(10, false).len(), 11);
    }

    #[test]
    fn a_row_holds_the_state_at_its_instant_and_the_next_frame_s_as_action() {
        let s = streams();
        let g = s.grid(10, false);
        let r = s.row(&g, 3, 10);
        assert_eq!(r.state, vec![30.0]);
        assert_eq!(r.action, vec![40.0]);
        assert!((r.timestamp - 0.3).abs() < 1e-7);
        let last = s.row(&g, g.len() - 1, 10);
        assert_eq!(last.action, last.state);
    }
}
