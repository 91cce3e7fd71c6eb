//! Finding a square fiducial in a colour image: a dark square on a light plate (the LoCoBot's
//! calibration tag, as the robot's description places it), its four corners to a fraction of
//! a pixel.
//!
//! Why our own detector and not an AprilTag or ArUco crate: the calibration has one marker
//! whose rough place in the image is known from the robot's kinematics (a prediction within
//! tens of pixels), so it needs no identity bits, only the four corners, as exactly as
//! possible. The detector takes the dark connected region near the prediction that a light
//! ring encloses, fits a straight line to each side from sub-pixel edge crossings of the
//! intensity profile (tens of samples per side), and intersects the lines; the corners come
//! out in the prediction's order. The Rust AprilTag crates (`apriltag` binds the C library,
//! `kornia-apriltag` is young) would add a tag family to render and a larger dependency for
//! no better corners.
//!
//! Image coordinates: pixel (row r, column c) has its centre at (u, v) = (c, r).

use crate::error::{PerceptionError, Result};
use crate::image::RgbImage;

/// A square found in an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SquareDetection {
    /// The corners (u, v) in px, in the order of the prediction they were matched to.
    pub corners: [[f64; 2]; 4],
    /// Root-mean-square distance of the edge samples from their fitted sides, px.
    pub edge_rms: f64,
    /// Pixels of the dark square.
    pub area: usize,
}

/// Luminance of an image, 0-255, row-major.
struct Grey {
    w: usize,
    h: usize,
    v: Vec<f32>,
}

impl Grey {
    fn new(img: &RgbImage) -> Self {
        let v = img
            .data
            .chunks_exact(3)
            .map(|p| 0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2]))
            .collect();
        Grey {
            w: img.width as usize,
            h: img.height as usize,
            v,
        }
    }

    fn at(&self, r: usize, c: usize) -> f32 {
        self.v[r * self.w + c]
    }

    /// Bilinear interpolation at (u, v) px; `None` off the image.
    fn sample(&self, u: f64, v: f64) -> Option<f64> {
        if !(u >= 0.0 && v >= 0.0 && u <= (self.w - 1) as f64 && v <= (self.h - 1) as f64) {
            return None;
        }
        let (c0, r0) = (u.floor() as usize, v.floor() as usize);
        let (c1, r1) = ((c0 + 1).min(self.w - 1), (r0 + 1).min(self.h - 1));
        let (fu, fv) = (u - c0 as f64, v - r0 as f64);
        let g = |r, c| f64::from(self.at(r, c));
        let top = g(r0, c0) * (1.0 - fu) + g(r0, c1) * fu;
        let bottom = g(r1, c0) * (1.0 - fu) + g(r1, c1) * fu;
        Some(top * (1.0 - fv) + bottom * fv)
    }
}

/// Find the dark square whose corners are predicted at `predicted` ((u, v) px, in the order
/// wanted back), searching `radius` px around the prediction.
///
/// An error ([`PerceptionError::MarkerNotSeen`]) when no dark region of roughly the
/// predicted size, enclosed by a light ring, lies there (out of view, occluded, too small);
/// [`PerceptionError::Parameter`] for a non-finite prediction or radius.
pub fn detect_square(
    img: &RgbImage,
    predicted: &[[f64; 2]; 4],
    radius: f64,
) -> Result<SquareDetection> {
    if !predicted.iter().flatten().all(|v| v.is_finite()) {
        return Err(PerceptionError::Parameter {
            name: "predicted corner",
            value: f64::NAN,
            range: "finite image coordinates",
        });
    }
    if !(radius.is_finite() && (1.0..=10_000.0).contains(&radius)) {
        return Err(PerceptionError::Parameter {
            name: "search radius",
            value: radius,
            range: "[1, 10000] px",
        });
    }
    img.check()?;
    if img.width < 2 || img.height < 2 {
        return Err(PerceptionError::Size(format!(
            "a {}x{} image is too small to find a marker in",
            img.width, img.height
        )));
    }
    let grey = Grey::new(img);
    let (w, h) = (grey.w as f64, grey.h as f64);
    let not_seen = |why: String| Err(PerceptionError::MarkerNotSeen(why));
    // The search window: the prediction's bounds on axis k (0: u, 1: v), widened by radius.
    let lo = |k: usize| predicted.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min) - radius;
    let hi = |k: usize| {
        predicted
            .iter()
            .map(|p| p[k])
            .fold(f64::NEG_INFINITY, f64::max)
            + radius
    };
    let (lo_u, hi_u, lo_v, hi_v) = (lo(0), hi(0), lo(1), hi(1));
    let (c0, c1) = (lo_u.max(0.0), hi_u.min(w - 1.0));
    let (r0, r1) = (lo_v.max(0.0), hi_v.min(h - 1.0));
    if c0 > c1 || r0 > r1 {
        return not_seen("the predicted marker lies outside the image".into());
    }
    let (c0, c1, r0, r1) = (c0 as usize, c1 as usize, r0 as usize, r1 as usize);
    let (ww, wh) = (c1 - c0 + 1, r1 - r0 + 1);
    // The threshold: half way between the window's darkest and lightest (5th and 95th
    // percentiles).
    let mut vals: Vec<f32> = (r0..=r1)
        .flat_map(|r| (c0..=c1).map(move |c| (r, c)))
        .map(|(r, c)| grey.at(r, c))
        .collect();
    vals.sort_by(f32::total_cmp);
    let pct = |p: f64| vals[((vals.len() - 1) as f64 * p) as usize];
    let (dark, light) = (pct(0.05), pct(0.95));
    if light - dark < 40.0 {
        return not_seen(format!(
            "no contrast near the prediction (grey levels {dark:.0}-{light:.0})"
        ));
    }
    let threshold = (dark + light) / 2.0;
    // Dark connected regions (4-connected) of the window.
    let predicted_area = shoelace(predicted).abs();
    let centre = mean(predicted);
    let mut region = vec![u32::MAX; ww * wh];
    let is_dark = |i: usize| grey.at(r0 + i / ww, c0 + i % ww) < threshold;
    let mut best: Option<(f64, Vec<usize>)> = None;
    let mut stack = Vec::new();
    let mut id = 0u32;
    for start in 0..ww * wh {
        if region[start] != u32::MAX || !is_dark(start) {
            continue;
        }
        let mut pixels = Vec::new();
        region[start] = id;
        stack.push(start);
        let mut touches_edge = false;
        while let Some(i) = stack.pop() {
            pixels.push(i);
            let (r, c) = (i / ww, i % ww);
            touches_edge |= r == 0 || c == 0 || r + 1 == wh || c + 1 == ww;
            let mut visit = |j: usize| {
                if region[j] == u32::MAX && is_dark(j) {
                    region[j] = id;
                    stack.push(j);
                }
            };
            if r > 0 {
                visit(i - ww);
            }
            if r + 1 < wh {
                visit(i + ww);
            }
            if c > 0 {
                visit(i - 1);
            }
            if c + 1 < ww {
                visit(i + 1);
            }
        }
        let this = id;
        id += 1;
        let area = pixels.len() as f64;
        if touches_edge || area < 0.3 * predicted_area || area > 3.0 * predicted_area {
            continue;
        }
        // Enclosed by light: the pixels 4-adjacent to the region and outside it.
        let (mut ring, mut lit) = (0usize, 0usize);
        for &i in &pixels {
            // Not touching the window's edge: every 4-neighbour is in it.
            for j in [i - ww, i + ww, i - 1, i + 1] {
                if region[j] != this {
                    ring += 1;
                    lit += usize::from(!is_dark(j));
                }
            }
        }
        if ring == 0 || (lit as f64) < 0.95 * ring as f64 {
            continue;
        }
        let (su, sv) = pixels.iter().fold((0.0, 0.0), |(u, v), &i| {
            (u + (c0 + i % ww) as f64, v + (r0 + i / ww) as f64)
        });
        let d = ((su / area - centre[0]).powi(2) + (sv / area - centre[1]).powi(2)).sqrt();
        if best.as_ref().is_none_or(|(bd, _)| d < *bd) {
            best = Some((d, pixels));
        }
    }
    let Some((_, pixels)) = best else {
        return not_seen(format!(
            "no dark square of about {predicted_area:.0} px enclosed by a light ring within \
             {radius} px of the prediction"
        ));
    };
    let points: Vec<[f64; 2]> = pixels
        .iter()
        .map(|&i| [(c0 + i % ww) as f64, (r0 + i / ww) as f64])
        .collect();
    let rough = rough_corners(&points);
    // Levels inside and outside, for the edge crossings.
    let inside = pixels
        .iter()
        .map(|&i| f64::from(grey.at(r0 + i / ww, c0 + i % ww)))
        .sum::<f64>()
        / pixels.len() as f64;
    let level = (inside + f64::from(light)) / 2.0;
    let mid = mean(&rough);
    let mut lines = [([0.0; 2], [0.0; 2]); 4];
    let mut sq = 0.0;
    let mut samples = 0usize;
    for k in 0..4 {
        let (a, b) = (rough[k], rough[(k + 1) % 4]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = (dx * dx + dy * dy).sqrt();
        if len < 4.0 {
            return not_seen(format!("a side of {len:.1} px is too short to measure"));
        }
        let (tx, ty) = (dx / len, dy / len);
        // The normal pointing away from the square's middle.
        let (mut nx, mut ny) = (-ty, tx);
        let (ex, ey) = ((a[0] + b[0]) / 2.0 - mid[0], (a[1] + b[1]) / 2.0 - mid[1]);
        if nx * ex + ny * ey < 0.0 {
            (nx, ny) = (-nx, -ny);
        }
        let mut pts = Vec::new();
        let n = (len * 2.0) as usize;
        for s in 0..=n {
            let t = 0.15 + 0.7 * s as f64 / n as f64;
            let (pu, pv) = (a[0] + dx * t, a[1] + dy * t);
            if let Some(off) = crossing(&grey, [pu, pv], [nx, ny], level) {
                pts.push([pu + nx * off, pv + ny * off]);
            }
        }
        if pts.len() < 5 {
            return not_seen(format!("a side gave {} edge samples", pts.len()));
        }
        let (c, d, rss) = fit_line(&pts);
        lines[k] = (c, d);
        sq += rss;
        samples += pts.len();
    }
    let mut corners = [[0.0; 2]; 4];
    for k in 0..4 {
        // Corner k+1 joins side k and side k+1.
        let p = intersect(lines[k], lines[(k + 1) % 4]).ok_or_else(|| {
            PerceptionError::MarkerNotSeen("two sides of the square are parallel".into())
        })?;
        corners[(k + 1) % 4] = p;
    }
    Ok(SquareDetection {
        corners: match_order(&corners, predicted),
        edge_rms: (sq / samples as f64).sqrt(),
        area: pixels.len(),
    })
}

/// Where, along the normal from `p` (in px, −3 to +3), the profile first rises through
/// `level` (dark inside to light outside); `None` if it does not.
fn crossing(grey: &Grey, p: [f64; 2], n: [f64; 2], level: f64) -> Option<f64> {
    const STEP: f64 = 0.1;
    let at = |s: f64| grey.sample(p[0] + n[0] * s, p[1] + n[1] * s);
    let mut prev = at(-3.0)?;
    if prev >= level {
        return None;
    }
    let mut s = -3.0;
    while s < 3.0 {
        let next = at(s + STEP)?;
        if next >= level {
            return Some(s + STEP * (level - prev) / (next - prev));
        }
        prev = next;
        s += STEP;
    }
    None
}

/// Total least-squares line through `pts`: a point on it, its unit direction, and the sum of
/// squared distances.
fn fit_line(pts: &[[f64; 2]]) -> ([f64; 2], [f64; 2], f64) {
    let c = mean(pts);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let (x, y) = (p[0] - c[0], p[1] - c[1]);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    // The direction of largest spread: eigenvector of [[sxx, sxy], [sxy, syy]].
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let d = [theta.cos(), theta.sin()];
    let rss = pts
        .iter()
        .map(|p| ((p[0] - c[0]) * -d[1] + (p[1] - c[1]) * d[0]).powi(2))
        .sum();
    (c, d, rss)
}

/// Where two lines (point, direction) meet; `None` if nearly parallel.
fn intersect(a: ([f64; 2], [f64; 2]), b: ([f64; 2], [f64; 2])) -> Option<[f64; 2]> {
    let ((p, d), (q, e)) = (a, b);
    let den = d[0] * e[1] - d[1] * e[0];
    if den.abs() < 1e-6 {
        return None;
    }
    let t = ((q[0] - p[0]) * e[1] - (q[1] - p[1]) * e[0]) / den;
    Some([p[0] + d[0] * t, p[1] + d[1] * t])
}

/// Four rough corners of a convex quadrilateral's pixels, in order round it: the farthest
/// pixel from the middle, the farthest from that, and the farthest on each side of the
/// diagonal they make.
fn rough_corners(points: &[[f64; 2]]) -> [[f64; 2]; 4] {
    let m = mean(points);
    let far = |from: [f64; 2]| {
        points
            .iter()
            .copied()
            .max_by(|a, b| dist2(*a, from).total_cmp(&dist2(*b, from)))
            .unwrap_or(from)
    };
    let a = far(m);
    let c = far(a);
    let side = |p: [f64; 2]| (c[0] - a[0]) * (p[1] - a[1]) - (c[1] - a[1]) * (p[0] - a[0]);
    let extreme = |sign: f64| {
        points
            .iter()
            .copied()
            .max_by(|p, q| (sign * side(*p)).total_cmp(&(sign * side(*q))))
            .unwrap_or(a)
    };
    [a, extreme(1.0), c, extreme(-1.0)]
}

/// `found` reordered to match `predicted` best: the cyclic shift and direction with the least
/// squared distance once both are centred (the marker's in-image rotation is close to the
/// prediction's, its position may not be).
fn match_order(found: &[[f64; 2]; 4], predicted: &[[f64; 2]; 4]) -> [[f64; 2]; 4] {
    let (mf, mp) = (mean(found), mean(predicted));
    let mut best = (f64::INFINITY, *found);
    for reverse in [false, true] {
        for shift in 0..4 {
            let order: [[f64; 2]; 4] = std::array::from_fn(|j| {
                let k = if reverse { 4 - j } else { j };
                found[(k + shift) % 4]
            });
            let cost: f64 = order
                .iter()
                .zip(predicted)
                .map(|(f, p)| dist2([f[0] - mf[0], f[1] - mf[1]], [p[0] - mp[0], p[1] - mp[1]]))
                .sum();
            if cost < best.0 {
                best = (cost, order);
            }
        }
    }
    best.1
}

fn mean(pts: &[[f64; 2]]) -> [f64; 2] {
    let n = pts.len().max(1) as f64;
    let (u, v) = pts
        .iter()
        .fold((0.0, 0.0), |(u, v), p| (u + p[0], v + p[1]));
    [u / n, v / n]
}

fn dist2(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// The signed area of a quadrilateral, px².
fn shoelace(p: &[[f64; 2]; 4]) -> f64 {
    (0..4)
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % 4]);
            a[0] * b[1] - a[1] * b[0]
        })
        .sum::<f64>()
        / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An empty or one-pixel image, or one whose buffer does not hold its size (built without
    /// `new`), is a size error (the bilinear sample's `w - 1` underflowed on an empty one).
    #[test]
    fn images_too_small_or_lying_are_size_errors() {
        let q = [[1.0, 1.0], [3.0, 1.0], [3.0, 3.0], [1.0, 3.0]];
        for (w, h, n) in [(0, 0, 0), (1, 1, 3), (8, 8, 3), (8, 8, 0)] {
            let img = RgbImage {
                width: w,
                height: h,
                data: vec![200; n],
            };
            let r = detect_square(&img, &q, 5.0);
            assert!(
                matches!(r, Err(PerceptionError::Size(_))),
                "{w}x{h} ({n}): {r:?}"
            );
        }
    }

    /// A light image with a dark quadrilateral of corners `q`, each pixel the mean of 8 x 8
    /// samples over its area (as the simulator's camera renders its marker).
    fn image_with(q: &[[f64; 2]; 4], w: u32, h: u32) -> RgbImage {
        let inside = |u: f64, v: f64| {
            (0..4).all(|i| {
                let (a, b) = (q[i], q[(i + 1) % 4]);
                (b[0] - a[0]) * (v - a[1]) - (b[1] - a[1]) * (u - a[0]) >= 0.0
            })
        };
        let mut data = Vec::with_capacity((w * h * 3) as usize);
        for r in 0..h {
            for c in 0..w {
                let mut sum = 0.0f64;
                for k in 0..64 {
                    let (du, dv) = ((k % 8) as f64, (k / 8) as f64);
                    let (u, v) = (
                        c as f64 - 0.5 + (du + 0.5) / 8.0,
                        r as f64 - 0.5 + (dv + 0.5) / 8.0,
                    );
                    sum += if inside(u, v) { 8.0 } else { 200.0 };
                }
                let g = (sum / 64.0).round() as u8;
                data.extend_from_slice(&[g, g, g]);
            }
        }
        RgbImage::new(w, h, data).unwrap()
    }

    #[test]
    fn corners_of_a_rotated_square_within_a_twentieth_of_a_pixel() {
        // A 40 px square turned by 0.3 rad, corners counter-clockwise in image coordinates
        // (v down): the order of the prediction comes back.
        let (cu, cv, s, a) = (100.3, 80.7, 20.0, 0.3f64);
        let q: [[f64; 2]; 4] = std::array::from_fn(|i| {
            let t = a + std::f64::consts::FRAC_PI_2 * i as f64;
            let (x, y) = (s * (t.cos() - t.sin()), s * (t.sin() + t.cos()));
            [cu + x, cv + y]
        });
        let img = image_with(&q, 200, 160);
        // The prediction: 12 px off and turned by 0.05 rad, starting at the same corner.
        let predicted: [[f64; 2]; 4] = std::array::from_fn(|i| {
            let t = a + 0.05 + std::f64::consts::FRAC_PI_2 * i as f64;
            let (x, y) = (s * (t.cos() - t.sin()), s * (t.sin() + t.cos()));
            [cu + 12.0 + x, cv - 5.0 + y]
        });
        let d = detect_square(&img, &predicted, 40.0).unwrap();
        for (f, t) in d.corners.iter().zip(&q) {
            let e = dist2(*f, *t).sqrt();
            assert!(e < 0.05, "corner {f:?} is {e} px from {t:?}");
        }
        assert!(d.edge_rms < 0.5, "{}", d.edge_rms);
    }

    #[test]
    fn no_square_near_the_prediction_is_a_typed_error() {
        let img = image_with(
            &[[10.0, 10.0], [30.0, 10.0], [30.0, 30.0], [10.0, 30.0]],
            200,
            160,
        );
        let far = [
            [150.0, 100.0],
            [150.0, 120.0],
            [170.0, 120.0],
            [170.0, 100.0],
        ];
        assert!(matches!(
            detect_square(&img, &far, 20.0),
            Err(PerceptionError::MarkerNotSeen(_))
        ));
        let off = far.map(|[u, v]| [u + 1000.0, v]);
        assert!(matches!(
            detect_square(&img, &off, 20.0),
            Err(PerceptionError::MarkerNotSeen(_))
        ));
        let nan = [[f64::NAN, 0.0]; 4];
        assert!(matches!(
            detect_square(&img, &nan, 20.0),
            Err(PerceptionError::Parameter { .. })
        ));
        assert!(matches!(
            detect_square(&img, &far, f64::INFINITY),
            Err(PerceptionError::Parameter { .. })
        ));
    }
}
