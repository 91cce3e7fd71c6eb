//! Trajectories in the TUM RGB-D benchmark's format (`timestamp tx ty tz qx qy qz qw`, one
//! pose per line, `#` comments) and the absolute trajectory error as the benchmark's
//! `evaluate_ate.py` computes it: poses associated by time, the estimate aligned to the truth by
//! the best rigid transform (Horn), the RMSE of the translations' differences.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion};

use crate::error::{Error, Result};
use crate::optimise::align;

/// A timed pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stamped {
    /// Time, s.
    pub time: f64,
    /// Pose.
    pub pose: Isometry3<f64>,
}

/// A trajectory as TUM text.
pub fn to_tum(poses: &[Stamped]) -> String {
    let mut s = String::from("# timestamp tx ty tz qx qy qz qw\n");
    for p in poses {
        let t = p.pose.translation;
        let q = p.pose.rotation;
        let _ = writeln!(
            s,
            "{:.6} {:.6} {:.6} {:.6} {:.7} {:.7} {:.7} {:.7}",
            p.time, t.x, t.y, t.z, q.i, q.j, q.k, q.w
        );
    }
    s
}

/// Writes a TUM trajectory file.
pub fn write_tum(path: &Path, poses: &[Stamped]) -> Result<()> {
    crate::error::write_file(path, to_tum(poses))
}

/// The lines of a TUM text file that hold data, trimmed, with their 1-based numbers: blank
/// lines and `#` comments skipped.
pub(crate) fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(n, l)| (n + 1, l.trim()))
        .filter(|(_, l)| !(l.is_empty() || l.starts_with('#')))
}

/// Reads a TUM trajectory (lines of eight numbers; blank lines and `#` comments skipped;
/// quaternions normalised). Errors name the line.
pub fn parse_tum(text: &str, path: &Path) -> Result<Vec<Stamped>> {
    let mut out = Vec::new();
    for (n, line) in data_lines(text) {
        let bad = |why: String| Error::File {
            path: path.to_path_buf(),
            why: format!("line {n}: {why}"),
        };
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|t| {
                t.parse::<f64>()
                    .map_err(|_| bad(format!("{t:?} is not a number")))
            })
            .collect::<Result<_>>()?;
        if v.len() != 8 {
            return Err(bad(format!("{} numbers, not 8", v.len())));
        }
        if !v.iter().all(|x| x.is_finite()) {
            return Err(bad("a number is not finite".into()));
        }
        let q = Quaternion::new(v[7], v[4], v[5], v[6]);
        if q.norm() < 1e-6 {
            return Err(bad("zero quaternion".into()));
        }
        out.push(Stamped {
            time: v[0],
            pose: Isometry3::from_parts(
                Translation3::new(v[1], v[2], v[3]),
                UnitQuaternion::from_quaternion(q),
            ),
        });
    }
    Ok(out)
}

/// The absolute trajectory error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ate {
    /// Pose pairs compared.
    pub pairs: usize,
    /// Root mean square of the translation differences after alignment, m.
    pub rmse: f64,
    /// Their mean, m.
    pub mean: f64,
    /// Their largest, m.
    pub max: f64,
    /// The alignment applied to the estimate (truth ≈ alignment · estimate).
    pub alignment: Isometry3<f64>,
}

/// The ATE of `estimate` against `truth`: each estimated pose paired with the truth's nearest
/// in time within `max_dt` s (each truth pose used once at most), the estimate aligned rigidly.
pub fn ate(estimate: &[Stamped], truth: &[Stamped], max_dt: f64) -> Result<Ate> {
    let mut t: Vec<&Stamped> = truth.iter().collect();
    t.sort_by(|a, b| a.time.total_cmp(&b.time));
    let mut used = vec![false; t.len()];
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for e in estimate {
        let i = t.partition_point(|s| s.time < e.time);
        let best = [i.checked_sub(1), Some(i)]
            .into_iter()
            .flatten()
            .filter(|&k| k < t.len() && !used[k] && (t[k].time - e.time).abs() <= max_dt)
            .min_by(|&x, &y| {
                (t[x].time - e.time)
                    .abs()
                    .total_cmp(&(t[y].time - e.time).abs())
            });
        if let Some(k) = best {
            used[k] = true;
            a.push(Point3::from(e.pose.translation.vector));
            b.push(Point3::from(t[k].pose.translation.vector));
        }
    }
    if a.len() < 3 {
        return Err(Error::Trajectory {
            why: format!("{} poses pair up in time (at least 3 needed)", a.len()),
        });
    }
    // A trajectory along a line (or a point) has no unique alignment: align translation only.
    let alignment = align(&a, &b).unwrap_or_else(|| {
        let n = a.len() as f64;
        let ca = a.iter().map(|p| p.coords).sum::<nalgebra::Vector3<f64>>() / n;
        let cb = b.iter().map(|p| p.coords).sum::<nalgebra::Vector3<f64>>() / n;
        Isometry3::translation(cb.x - ca.x, cb.y - ca.y, cb.z - ca.z)
    });
    let d: Vec<f64> = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (alignment * p - q).norm())
        .collect();
    let n = d.len() as f64;
    Ok(Ate {
        pairs: d.len(),
        rmse: (d.iter().map(|x| x * x).sum::<f64>() / n).sqrt(),
        mean: d.iter().sum::<f64>() / n,
        max: d.iter().fold(0.0, |m, &x| m.max(x)),
        alignment,
    })
}
