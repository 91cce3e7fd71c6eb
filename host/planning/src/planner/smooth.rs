//! Smoothing after shortcutting, as VAMP simplifies its paths (Thomason, Kingston and
//! Kavraki, ICRA 2024, `simplify.hh`): rounds of corner cutting (each edge split at its
//! middle, then each corner moved to the middle of the two points halfway to its neighbours,
//! where it moves by more than [`MIN_CHANGE`] and both new edges are free) and of the greedy
//! pass that joins each waypoint to the farthest later one it sees.

use std::time::{Duration, Instant};

use super::{path_length, LOOK_AHEAD};
use crate::checker::Checker;
use crate::joint_space::dist;

/// The least a corner moves to be cut, rad (VAMP's `min_change`).
pub const MIN_CHANGE: f64 = 0.1;

/// `rounds` of corner cutting, each followed by the greedy pass, while the path shortens and
/// within `limit` of `t0`. Every edge of the result is free (each was checked, or is part of
/// an edge that was).
pub(super) fn smooth(
    checker: &Checker,
    mut path: Vec<Vec<f64>>,
    rounds: usize,
    t0: Instant,
    limit: Duration,
) -> Vec<Vec<f64>> {
    for _ in 0..rounds {
        if path.len() < 3 || t0.elapsed() > limit {
            break;
        }
        let before = path_length(&path);
        let cut = cut_corners(checker, &path);
        let next = greedy(checker, cut, t0, limit);
        if path_length(&next) >= before - 1e-9 {
            break;
        }
        path = next;
    }
    path
}

/// The path with every edge split at its middle and each original corner moved to the middle
/// of the points halfway to its neighbours where that moves it by more than [`MIN_CHANGE`]
/// and the two edges to its neighbours are free.
fn cut_corners(checker: &Checker, path: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(2 * path.len());
    for w in path.windows(2) {
        out.push(w[0].clone());
        out.push(lerp(&w[0], &w[1], 0.5));
    }
    out.extend(path.last().cloned());
    // The original corners are at the even indices between the ends.
    let mut i = 2;
    while i + 1 < out.len() {
        let a = lerp(&out[i], &out[i - 1], 0.5);
        let b = lerp(&out[i], &out[i + 1], 0.5);
        let m = lerp(&a, &b, 0.5);
        if dist(&out[i], &m) > MIN_CHANGE
            && checker.motion_free(&out[i - 1], &m)
            && checker.motion_free(&m, &out[i + 1])
        {
            out[i] = m;
        }
        i += 2;
    }
    out
}

/// From each waypoint kept, the farthest later one it sees (within [`LOOK_AHEAD`]).
pub(super) fn greedy(
    checker: &Checker,
    path: Vec<Vec<f64>>,
    t0: Instant,
    limit: Duration,
) -> Vec<Vec<f64>> {
    let Some(first) = path.first() else {
        return path;
    };
    let mut out = Vec::with_capacity(path.len());
    out.push(first.clone());
    let mut i = 0;
    while i + 1 < path.len() {
        let mut j = (path.len() - 1).min(i + LOOK_AHEAD);
        while j > i + 1 && !(t0.elapsed() <= limit && checker.motion_free(&path[i], &path[j])) {
            j -= 1;
        }
        out.push(path[j].clone());
        i = j;
    }
    out
}

/// `a + (b − a) s`.
fn lerp(a: &[f64], b: &[f64], s: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + (y - x) * s).collect()
}
