//! RGB-D sequences on disk in the TUM RGB-D benchmark's layout: `rgb.txt` and `depth.txt`
//! (lines `timestamp path`, `#` comments), PNG images (8-bit colour; 16-bit depth of
//! `depth_factor` units per metre, 5000 in TUM's sequences), `groundtruth.txt` when present
//! (TUM trajectory of the camera), and the intrinsics in `camera.yaml` beside them (keys `fx`,
//! `fy`, `cx`, `cy`, `width`, `height`, `depth_factor`). Colour and depth images pair up as
//! TUM's `associate.py` pairs them: nearest in time, within 0.02 s, each used once.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use ferrobot_perception::{io, DepthImage, Intrinsics, RgbImage};
use yaml_rust2::{Yaml, YamlLoader};

use crate::error::{read_file, write_file, Error, Result};
use crate::trajectory::{data_lines, parse_tum, to_tum, Stamped};

/// Largest list or YAML file read, bytes.
const MAX_TEXT: u64 = 64 << 20;
/// Colour and depth images pair up within this, s.
pub const MAX_PAIR_DT: f64 = 0.02;

/// A sequence's description: its frames (paired), intrinsics and ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The folder.
    pub dir: PathBuf,
    /// The camera.
    pub intrinsics: Intrinsics,
    /// Depth units per metre.
    pub depth_factor: f64,
    /// Frames: time (s), colour file, depth file, in time order.
    pub frames: Vec<(f64, PathBuf, PathBuf)>,
    /// The camera's true trajectory, when the sequence has one.
    pub ground_truth: Option<Vec<Stamped>>,
}

fn read_text(path: &Path) -> Result<String> {
    String::from_utf8(read_file(path, MAX_TEXT)?).map_err(|_| Error::File {
        path: path.to_path_buf(),
        why: "not UTF-8 text".into(),
    })
}

/// Lines `timestamp path` of a TUM list, in file order.
fn parse_list(path: &Path, dir: &Path) -> Result<Vec<(f64, PathBuf)>> {
    let text = read_text(path)?;
    let mut out = Vec::new();
    for (n, line) in data_lines(&text) {
        let bad = |why: String| Error::File {
            path: path.to_path_buf(),
            why: format!("line {n}: {why}"),
        };
        let mut it = line.split_whitespace();
        let t: f64 = it
            .next()
            .and_then(|t| t.parse().ok())
            .filter(|t: &f64| t.is_finite())
            .ok_or_else(|| bad("not `timestamp path`".into()))?;
        let file = it.next().ok_or_else(|| bad("no file name".into()))?;
        let rel = Path::new(file);
        if rel.is_absolute()
            || rel
                .components()
                .any(|c| c == std::path::Component::ParentDir)
        {
            return Err(bad(format!("{file:?} leaves the dataset's folder")));
        }
        out.push((t, dir.join(rel)));
    }
    Ok(out)
}

impl Dataset {
    /// Reads the sequence in `dir` (lists, camera, ground truth; not the images). Errors name
    /// the file and line.
    pub fn open(dir: &Path) -> Result<Self> {
        let cam_path = dir.join("camera.yaml");
        let text = read_text(&cam_path)?;
        let bad = |why: String| Error::File {
            path: cam_path.clone(),
            why,
        };
        let docs = YamlLoader::load_from_str(&text).map_err(|e| bad(format!("not YAML: {e}")))?;
        let doc = docs.first().ok_or_else(|| bad("empty".into()))?;
        let num = |k: &str| -> Result<f64> {
            match &doc[k] {
                Yaml::Real(_) | Yaml::Integer(_) => doc[k]
                    .as_f64()
                    .or_else(|| doc[k].as_i64().map(|v| v as f64))
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| bad(format!("{k} is not a finite number"))),
                Yaml::BadValue => Err(bad(format!("no key {k}"))),
                _ => Err(bad(format!("{k} is not a number"))),
            }
        };
        let size = |k: &str| -> Result<u32> {
            let v = num(k)?;
            if v.fract() == 0.0 && (1.0..=16384.0).contains(&v) {
                Ok(v as u32)
            } else {
                Err(bad(format!(
                    "{k} = {v} is not a whole number of pixels in 1..=16384"
                )))
            }
        };
        let intrinsics = Intrinsics::new(
            size("width")?,
            size("height")?,
            num("fx")?,
            num("fy")?,
            num("cx")?,
            num("cy")?,
        )
        .map_err(|e| bad(e.to_string()))?;
        let depth_factor = num("depth_factor")?;
        if !(1.0..=1e6).contains(&depth_factor) {
            return Err(bad(format!(
                "depth_factor {depth_factor} is not in [1, 1e6] units per metre"
            )));
        }
        let rgb = parse_list(&dir.join("rgb.txt"), dir)?;
        let mut depth = parse_list(&dir.join("depth.txt"), dir)?;
        depth.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut used = vec![false; depth.len()];
        let mut frames = Vec::new();
        for (t, c) in rgb {
            let i = depth.partition_point(|d| d.0 < t);
            let best = [i.checked_sub(1), Some(i)]
                .into_iter()
                .flatten()
                .filter(|&k| k < depth.len() && !used[k] && (depth[k].0 - t).abs() <= MAX_PAIR_DT)
                .min_by(|&a, &b| (depth[a].0 - t).abs().total_cmp(&(depth[b].0 - t).abs()));
            if let Some(k) = best {
                used[k] = true;
                frames.push((t, c, depth[k].1.clone()));
            }
        }
        frames.sort_by(|a, b| a.0.total_cmp(&b.0));
        let gt_path = dir.join("groundtruth.txt");
        let ground_truth = if gt_path.exists() {
            Some(parse_tum(&read_text(&gt_path)?, &gt_path)?)
        } else {
            None
        };
        Ok(Dataset {
            dir: dir.to_path_buf(),
            intrinsics,
            depth_factor,
            frames,
            ground_truth,
        })
    }

    /// Frame `i`'s images, checked against the camera's size.
    pub fn load(&self, i: usize) -> Result<(f64, RgbImage, DepthImage)> {
        let (t, c, d) = self.frames.get(i).ok_or_else(|| Error::File {
            path: self.dir.clone(),
            why: format!("no frame {i}"),
        })?;
        let file = |p: &Path, e: ferrobot_perception::PerceptionError| Error::File {
            path: p.to_path_buf(),
            why: e.to_string(),
        };
        let rgb = io::read_rgb_png(c).map_err(|e| file(c, e))?;
        let depth = io::read_depth_png_scaled(d, self.depth_factor).map_err(|e| file(d, e))?;
        let k = &self.intrinsics;
        for (p, w, h) in [(c, rgb.width, rgb.height), (d, depth.width, depth.height)] {
            if (w, h) != (k.width, k.height) {
                return Err(Error::File {
                    path: p.clone(),
                    why: format!("{w}x{h} px, camera.yaml says {}x{}", k.width, k.height),
                });
            }
        }
        Ok((*t, rgb, depth))
    }
}

/// Writes a sequence in the layout [`Dataset::open`] reads: images under `rgb/` and
/// `depth/`, named by their time.
#[derive(Debug)]
pub struct DatasetWriter {
    dir: PathBuf,
    depth_factor: f64,
    rgb: String,
    depth: String,
    truth: Vec<Stamped>,
}

impl DatasetWriter {
    /// Starts a sequence in `dir` (created, with `rgb/` and `depth/`).
    pub fn create(dir: &Path, depth_factor: f64) -> Result<Self> {
        let bad = |p: &Path, e: std::io::Error| Error::File {
            path: p.to_path_buf(),
            why: e.to_string(),
        };
        for sub in ["rgb", "depth"] {
            let p = dir.join(sub);
            std::fs::create_dir_all(&p).map_err(|e| bad(&p, e))?;
        }
        Ok(DatasetWriter {
            dir: dir.to_path_buf(),
            depth_factor,
            rgb: String::from("# colour images\n# timestamp filename\n"),
            depth: String::from("# depth images\n# timestamp filename\n"),
            truth: Vec::new(),
        })
    }

    /// Adds a frame taken at `time` (s), with the camera's true pose when known.
    pub fn add(
        &mut self,
        time: f64,
        rgb: &RgbImage,
        depth: &DepthImage,
        truth: Option<nalgebra::Isometry3<f64>>,
    ) -> Result<()> {
        let name = format!("{time:.6}.png");
        let file = |p: PathBuf, e: ferrobot_perception::PerceptionError| Error::File {
            path: p,
            why: e.to_string(),
        };
        let c = self.dir.join("rgb").join(&name);
        io::write_rgb_png(&c, rgb).map_err(|e| file(c.clone(), e))?;
        let d = self.dir.join("depth").join(&name);
        io::write_depth_png_scaled(&d, depth, self.depth_factor).map_err(|e| file(d.clone(), e))?;
        let _ = writeln!(self.rgb, "{time:.6} rgb/{name}");
        let _ = writeln!(self.depth, "{time:.6} depth/{name}");
        if let Some(pose) = truth {
            self.truth.push(Stamped { time, pose });
        }
        Ok(())
    }

    /// Writes the lists, the camera and the ground truth.
    pub fn finish(self, k: &Intrinsics) -> Result<()> {
        let camera = format!(
            "# Pinhole intrinsics (px) and the depth images' units per metre.\nfx: {}\nfy: {}\ncx: {}\ncy: {}\nwidth: {}\nheight: {}\ndepth_factor: {}\n",
            k.fx, k.fy, k.cx, k.cy, k.width, k.height, self.depth_factor
        );
        let mut files = vec![
            ("rgb.txt", self.rgb),
            ("depth.txt", self.depth),
            ("camera.yaml", camera),
        ];
        if !self.truth.is_empty() {
            files.push(("groundtruth.txt", to_tum(&self.truth)));
        }
        for (name, text) in files {
            write_file(&self.dir.join(name), text)?;
        }
        Ok(())
    }
}
