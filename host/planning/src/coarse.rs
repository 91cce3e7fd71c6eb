//! The checker's coarse stage for many obstacles at once: one sphere (a body's bound) against
//! the bounding boxes of a list of obstacles, each box in its own frame, as a structure of
//! arrays padded to [`LANES`], so that the loop runs in vector lanes rather than one obstacle
//! after another. [`crate::checker`] uses it where every obstacle of every body is measured:
//! at the start of each edge, to find what may come near along it.

use crate::shape::box_distance;

/// Lanes of the checker's loops: lists of boxes, and each body's spheres, are padded to a
/// multiple of it, so that the loops run whole chunks the compiler turns into vector
/// instructions.
pub(crate) const LANES: usize = 8;

/// Rows of a box: world-to-box rotation (9, row-major), translation (3), centre (3) and
/// half-extents (3) in the box's frame.
const ROWS: usize = 18;

/// Coordinate of padding (a box's centre seen from anywhere, a sphere's centre), m: far from
/// everything, small enough that squares of sums of three stay finite in `f32`.
pub(crate) const FAR: f32 = 1.0e15;

/// Bounding boxes of a list of obstacles, in the list's order.
#[derive(Debug, Clone, Default)]
pub(crate) struct BoxSet {
    /// Boxes, padding included: a multiple of [`LANES`].
    n: usize,
    /// [`ROWS`] rows of `n`.
    rows: Vec<f32>,
}

impl BoxSet {
    /// The boxes `(inv, (centre, half))` (world to box frame: rotation rows and translation;
    /// centre and half-extents in that frame, m).
    pub(crate) fn new<'a>(
        boxes: impl ExactSizeIterator<Item = (&'a [f32; 12], &'a ([f32; 3], [f32; 3]))>,
    ) -> Self {
        let len = boxes.len();
        let n = len.div_ceil(LANES) * LANES;
        let mut rows = vec![0.0; ROWS * n];
        for (i, (inv, (centre, half))) in boxes.enumerate() {
            for (k, v) in inv.iter().chain(centre).chain(half).enumerate() {
                rows[k * n + i] = *v;
            }
        }
        // Padding: a point box seen at (FAR, FAR, FAR) from everything.
        for i in len..n {
            for k in 9..12 {
                rows[k * n + i] = FAR;
            }
        }
        BoxSet { n, rows }
    }

    /// The lower bounds (m) of the gap between the sphere at `c` (world) of radius `r` and
    /// each box, written to `out` (resized to the padded length): the boxes' signed distances
    /// of `c`, less `r`.
    pub(crate) fn gaps(&self, c: [f32; 3], r: f32, out: &mut Vec<f32>) {
        let n = self.n;
        out.clear();
        out.resize(n, 0.0);
        let row = |k: usize| &self.rows[k * n..(k + 1) * n];
        let (m0, m1, m2, m3, m4, m5, m6, m7, m8) = (
            row(0),
            row(1),
            row(2),
            row(3),
            row(4),
            row(5),
            row(6),
            row(7),
            row(8),
        );
        let (tx, ty, tz) = (row(9), row(10), row(11));
        let (cx, cy, cz) = (row(12), row(13), row(14));
        let (hx, hy, hz) = (row(15), row(16), row(17));
        let [x, y, z] = c;
        for i in 0..n {
            let lx = m0[i] * x + m1[i] * y + m2[i] * z + tx[i];
            let ly = m3[i] * x + m4[i] * y + m5[i] * z + ty[i];
            let lz = m6[i] * x + m7[i] * y + m8[i] * z + tz[i];
            out[i] = box_distance([cx[i], cy[i], cz[i]], [hx[i], hy[i], hz[i]], lx, ly, lz) - r;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::to_local;

    /// Every lane gives the scalar signed distance of its box, whatever the list's length,
    /// and padding lanes are far.
    #[test]
    fn lanes_agree_with_one_box_at_a_time() {
        let mut out = Vec::new();
        for len in [0usize, 1, 7, 8, 9, 20] {
            type Box = ([f32; 12], ([f32; 3], [f32; 3]));
            let boxes: Vec<Box> = (0..len)
                .map(|i| {
                    let a = i as f32 * 0.7;
                    let (s, c) = a.sin_cos();
                    (
                        [c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0, 0.1 * a, -0.2, 0.3],
                        ([0.01 * a, 0.0, -0.02], [0.1, 0.2 + 0.01 * a, 0.05]),
                    )
                })
                .collect();
            let set = BoxSet::new(boxes.iter().map(|(inv, b)| (inv, b)));
            for p in [[0.0f32, 0.0, 0.0], [0.5, -0.3, 0.2], [-1.0, 2.0, 0.1]] {
                set.gaps(p, 0.04, &mut out);
                assert_eq!(out.len(), len.div_ceil(LANES) * LANES);
                for (i, (inv, (centre, half))) in boxes.iter().enumerate() {
                    let (lx, ly, lz) = to_local(inv, p[0], p[1], p[2]);
                    let want = box_distance(*centre, *half, lx, ly, lz) - 0.04;
                    assert!((out[i] - want).abs() < 1e-6, "{len} {i}: {} {want}", out[i]);
                }
                assert!(out[len..].iter().all(|&g| g > 1e14));
            }
        }
    }
}
