//! The statistics LeRobot normalises with (`meta/stats.json`, and each episode's in its
//! metadata): per entry of a feature, its minimum, maximum, mean, standard deviation
//! (population), count and the quantiles LeRobot keeps (1, 10, 50, 90 and 99 %, linear
//! between order statistics as numpy's default). Images: per colour channel, values scaled to
//! [0, 1], from an exact histogram of every pixel.

use serde_json::{json, Value};

/// The quantiles LeRobot keeps, and their keys.
pub const QUANTILES: [(f64, &str); 5] = [
    (0.01, "q01"),
    (0.10, "q10"),
    (0.50, "q50"),
    (0.90, "q90"),
    (0.99, "q99"),
];

/// The statistics of one scalar entry over `values` (not empty).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stat {
    /// Minimum.
    pub min: f64,
    /// Maximum.
    pub max: f64,
    /// Mean.
    pub mean: f64,
    /// Standard deviation (population).
    pub std: f64,
    /// The quantiles of [`QUANTILES`].
    pub q: [f64; 5],
}

impl Stat {
    /// The statistics of `values` (sorted in place; not empty).
    pub fn of(values: &mut [f64]) -> Stat {
        values.sort_by(f64::total_cmp);
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        Stat {
            min: values[0],
            max: values[values.len() - 1],
            mean,
            std: var.sqrt(),
            q: QUANTILES.map(|(p, _)| quantile(values.len(), p, |i| values[i])),
        }
    }

    /// The statistics of a histogram `counts` of the values `0..counts.len()`, each scaled by
    /// `scale` (not all zero).
    pub fn of_histogram(counts: &[u64], scale: f64) -> Stat {
        let n: u64 = counts.iter().sum();
        let value = |v: usize| v as f64 * scale;
        let mean = counts
            .iter()
            .enumerate()
            .map(|(v, &c)| c as f64 * value(v))
            .sum::<f64>()
            / n as f64;
        let var = counts
            .iter()
            .enumerate()
            .map(|(v, &c)| c as f64 * (value(v) - mean).powi(2))
            .sum::<f64>()
            / n as f64;
        // The i-th order statistic: the value whose cumulative count passes i.
        let nth = |i: usize| {
            let mut seen = 0u64;
            for (v, &c) in counts.iter().enumerate() {
                seen += c;
                if seen > i as u64 {
                    return value(v);
                }
            }
            value(counts.len() - 1)
        };
        Stat {
            min: nth(0),
            max: nth(n as usize - 1),
            mean,
            std: var.sqrt(),
            q: QUANTILES.map(|(p, _)| quantile(n as usize, p, nth)),
        }
    }
}

/// Quantile `p` of `n` sorted values given by `nth`: linear between the order statistics
/// around `(n - 1) p`, as numpy's default.
fn quantile(n: usize, p: f64, nth: impl Fn(usize) -> f64) -> f64 {
    let x = (n - 1) as f64 * p;
    let (lo, frac) = (x.floor() as usize, x - x.floor());
    let hi = (lo + 1).min(n - 1);
    nth(lo) + frac * (nth(hi) - nth(lo))
}

/// A feature's statistics as LeRobot writes them: each key an array of the feature's shape
/// (`shape` wraps each entry, e.g. `[[[v]]]` for an image channel), `count` the rows.
pub fn to_json(stats: &[Stat], count: usize, image: bool) -> Value {
    let wrap = |v: f64| if image { json!([[v]]) } else { json!(v) };
    let field = |f: &dyn Fn(&Stat) -> f64| Value::Array(stats.iter().map(|s| wrap(f(s))).collect());
    let mut m = serde_json::Map::new();
    m.insert("min".into(), field(&|s| s.min));
    m.insert("max".into(), field(&|s| s.max));
    m.insert("mean".into(), field(&|s| s.mean));
    m.insert("std".into(), field(&|s| s.std));
    m.insert("count".into(), json!([count]));
    for (k, (_, name)) in QUANTILES.iter().enumerate() {
        m.insert((*name).into(), field(&|s| s.q[k]));
    }
    Value::Object(m)
}

/// The statistics of each column of `rows` (rows of equal width, at least one).
pub fn of_rows<'a>(rows: impl Iterator<Item = &'a [f32]> + Clone) -> Vec<Stat> {
    let width = rows.clone().next().map_or(0, <[f32]>::len);
    (0..width)
        .map(|j| {
            let mut col: Vec<f64> = rows.clone().map(|r| f64::from(r[j])).collect();
            Stat::of(&mut col)
        })
        .collect()
}

/// Per-channel histograms of RGB pixels.
#[derive(Debug, Clone)]
pub struct Histograms(pub [[u64; 256]; 3]);

impl Default for Histograms {
    fn default() -> Self {
        Histograms([[0; 256]; 3])
    }
}

impl Histograms {
    /// Counts the pixels of `rgb`, packed RGB bytes.
    pub fn add_rgb(&mut self, rgb: &[u8]) {
        for px in rgb.chunks_exact(3) {
            for (h, &v) in self.0.iter_mut().zip(px) {
                h[v as usize] += 1;
            }
        }
    }

    /// Adds `other`'s counts.
    pub fn merge(&mut self, other: &Histograms) {
        for (mine, theirs) in self.0.iter_mut().zip(&other.0) {
            for (a, b) in mine.iter_mut().zip(theirs) {
                *a += b;
            }
        }
    }

    /// Each channel's statistics, values scaled to [0, 1].
    pub fn stats(&self) -> Vec<Stat> {
        self.0
            .iter()
            .map(|h| Stat::of_histogram(h, 1.0 / 255.0))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_match_numpy_s_definitions() {
        // numpy: np.quantile([1, 2, 3, 4, 10], [.01, .1, .5, .9, .99]) =
        // [1.04, 1.4, 3.0, 7.6, 9.76]; std (population) of it: 3.1622776601683795.
        let s = Stat::of(&mut [4.0, 1.0, 10.0, 3.0, 2.0]);
        assert_eq!((s.min, s.max, s.mean), (1.0, 10.0, 4.0));
        assert!((s.std - 3.1622776601683795).abs() < 1e-12);
        for (got, want) in s.q.iter().zip([1.04, 1.4, 3.0, 7.6, 9.76]) {
            assert!((got - want).abs() < 1e-12, "{got} {want}");
        }
        // The same values as a histogram.
        let mut h = [0u64; 11];
        for v in [1, 2, 3, 4, 10] {
            h[v] += 1;
        }
        let hs = Stat::of_histogram(&h, 1.0);
        assert_eq!((hs.min, hs.max, hs.mean), (1.0, 10.0, 4.0));
        for (a, b) in hs.q.iter().zip(s.q) {
            assert!((a - b).abs() < 1e-12);
        }
    }
}
