//! The self-collision matrix found by sampling ([`SelfCollisionMatrix::compute`]).

use std::collections::BTreeMap;

use nalgebra::Isometry3;
use parry3d::query;
use rand::{Rng, SeedableRng};

use super::{key, Reason, SelfCollisionMatrix, ALWAYS_FRACTION};
use crate::model::CollisionModel;

impl SelfCollisionMatrix {
    /// Computes the matrix of `model` from `samples` random configurations of every movable
    /// joint (seeded with `seed`).
    pub fn compute(model: &CollisionModel, samples: usize, seed: u64) -> Self {
        let tree = model.tree();
        let links = model.links();
        let n = links.len();
        let mut disabled = BTreeMap::new();
        // Adjacent: each link with geometry and its nearest ancestor with geometry.
        for l in 0..n {
            if links[l].is_empty() {
                continue;
            }
            let mut at = tree.parent(l);
            while let Some(p) = at {
                if !links[p].is_empty() {
                    disabled.insert(key(&links[l].name, &links[p].name), Reason::Adjacent);
                    break;
                }
                at = tree.parent(p);
            }
        }
        let pairs: Vec<(usize, usize)> = (0..n)
            .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
            .filter(|&(a, b)| {
                !links[a].is_empty()
                    && !links[b].is_empty()
                    && !disabled.contains_key(&key(&links[a].name, &links[b].name))
            })
            .collect();
        let ranges = model.all_limits();
        let default: Vec<f64> = ranges
            .iter()
            .map(|&(lo, hi)| 0.0f64.clamp(lo, hi))
            .collect();
        let poses = tree.poses(&default);
        for &(a, b) in &pairs {
            if links_touch(model, a, &poses[a], b, &poses[b]) {
                disabled.insert(key(&links[a].name, &links[b].name), Reason::Default);
            }
        }
        let pairs: Vec<(usize, usize)> = pairs
            .into_iter()
            .filter(|&(a, b)| !disabled.contains_key(&key(&links[a].name, &links[b].name)))
            .collect();
        let mut hits = vec![0usize; pairs.len()];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut q = vec![0.0; ranges.len()];
        let mut poses = Vec::new();
        for _ in 0..samples {
            for (v, &(lo, hi)) in q.iter_mut().zip(&ranges) {
                *v = if hi > lo {
                    rng.random_range(lo..=hi)
                } else {
                    lo
                };
            }
            tree.poses_into(&q, &mut poses);
            for (h, &(a, b)) in hits.iter_mut().zip(&pairs) {
                if links_touch(model, a, &poses[a], b, &poses[b]) {
                    *h += 1;
                }
            }
        }
        for (&h, &(a, b)) in hits.iter().zip(&pairs) {
            let reason = if h == 0 {
                Reason::Never
            } else if h as f64 >= ALWAYS_FRACTION * samples as f64 {
                Reason::Always
            } else {
                continue;
            };
            disabled.insert(key(&links[a].name, &links[b].name), reason);
        }
        SelfCollisionMatrix { disabled }
    }
}

/// Whether links `a` and `b` of `model` at `pa`, `pb` (root frame) touch (exact shapes).
fn links_touch(
    model: &CollisionModel,
    a: usize,
    pa: &Isometry3<f64>,
    b: usize,
    pb: &Isometry3<f64>,
) -> bool {
    let la = &model.links()[a];
    let lb = &model.links()[b];
    let ca = pa * la.bound.centre;
    let cb = pb * lb.bound.centre;
    if (ca - cb).norm() > la.bound.radius + lb.bound.radius {
        return false;
    }
    model.exact_at(a, pa).any(|(posa, ea)| {
        model.exact_at(b, pb).any(|(posb, eb)| {
            query::intersection_test(&posa, ea.shape.as_ref(), &posb, eb.shape.as_ref())
                .map_or(true, |i| i.intersecting)
        })
    })
}
