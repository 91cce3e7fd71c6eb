//! The planners' trees of configurations (rad), the one-step extension toward a target, and
//! the dynamic domains that keep a trapped node's samples near it.

use super::diagonal;
use crate::checker::Checker;
use crate::joint_space::dist;

/// A tree of configurations, stored one after another (a nearest-node search reads them in
/// order, from one allocation).
pub(super) struct Tree {
    /// The configurations, [`Tree::dof`] values each, rad.
    flat: Vec<f64>,
    dof: usize,
    pub(super) parent: Vec<usize>,
    /// Each node's dynamic domain, rad: infinite until an extension from it is trapped.
    pub(super) domain: Vec<f64>,
}

impl Tree {
    pub(super) fn new(root: &[f64]) -> Self {
        Tree {
            flat: root.to_vec(),
            dof: root.len(),
            parent: vec![usize::MAX],
            domain: vec![f64::INFINITY],
        }
    }

    /// Nodes.
    pub(super) fn len(&self) -> usize {
        self.parent.len()
    }

    /// Node `i`'s configuration.
    pub(super) fn node(&self, i: usize) -> &[f64] {
        &self.flat[i * self.dof..(i + 1) * self.dof]
    }

    pub(super) fn nearest(&self, q: &[f64]) -> usize {
        let mut best = (f64::INFINITY, 0);
        for (i, n) in self.flat.chunks_exact(self.dof.max(1)).enumerate() {
            let d: f64 = n.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum();
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }

    pub(super) fn add(&mut self, q: &[f64], parent: usize) -> usize {
        self.flat.extend_from_slice(q);
        self.parent.push(parent);
        self.domain.push(f64::INFINITY);
        self.len() - 1
    }

    /// Configurations from the root to node `i`.
    pub(super) fn branch(&self, mut i: usize) -> Vec<Vec<f64>> {
        let mut out = Vec::new();
        while i != usize::MAX {
            out.push(self.node(i).to_vec());
            i = self.parent[i];
        }
        out.reverse();
        out
    }
}

/// Outcome of growing a tree toward a configuration.
#[derive(Debug, PartialEq)]
pub(super) enum Grow {
    Reached(usize),
    Advanced(usize),
    Trapped,
    /// The target lies outside its nearest node's [`Domain`]: nothing was checked.
    Outside,
}

/// Dynamic domains (Yershova, Jaillet, Siméon & LaValle, "Dynamic-Domain RRTs", ICRA 2005),
/// with VAMP's rules: the first trapped extension from a node gives it a domain of `radius`;
/// each later one shrinks it by the factor `1 − alpha`, down to `min`; each extension from it
/// that succeeds grows it by `1 + alpha`. Samples outside their nearest node's domain are
/// drawn again: nodes on an obstacle's boundary stop drawing the far samples whose
/// extensions would be trapped there again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Domain {
    /// A node's first domain, rad.
    pub(super) radius: f64,
    /// The smallest domain, rad.
    pub(super) min: f64,
    /// Growth and shrinkage per extension.
    pub(super) alpha: f64,
}

/// [`Domain::radius`] as a fraction of the joint box's diagonal (the LoCoBot's 1.76 rad,
/// Sawyer's 4.4 rad). On six problem sets (four of the LoCoBot's, Sawyer's shelf and clutter)
/// 0.25 took 12–33 % fewer instructions than no domains; 0.3 fewer on all six but less, 0.2
/// more on one set. A radius fixed in radians does not fit both arms: at VAMP's 4 rad the
/// LoCoBot gained nothing, at 1 rad Sawyer took 11–15× more (BENCHMARKS.md).
pub(super) const DOMAIN_PER_DIAGONAL: f64 = 0.25;

impl Domain {
    /// Domains for `checker`'s joint limits: [`DOMAIN_PER_DIAGONAL`] of their box's diagonal,
    /// at least a quarter of that, VAMP's `alpha` (10⁻⁴).
    pub(super) fn for_checker(checker: &Checker) -> Self {
        let radius = DOMAIN_PER_DIAGONAL * diagonal(checker);
        Domain {
            radius,
            min: radius / 4.0,
            alpha: 1e-4,
        }
    }

    /// A node's domain after an extension from it was trapped (`trapped`) or succeeded.
    pub(super) fn after(&self, domain: f64, trapped: bool) -> f64 {
        match (trapped, domain.is_finite()) {
            (true, false) => self.radius,
            (true, true) => (domain * (1.0 - self.alpha)).max(self.min),
            (false, true) => domain * (1.0 + self.alpha),
            (false, false) => domain,
        }
    }
}

/// One step of at most `range` from the nearest node toward `target`; with `domain`, only
/// when `target` lies within that node's domain, which the outcome then updates.
pub(super) fn extend(
    checker: &Checker,
    tree: &mut Tree,
    target: &[f64],
    range: f64,
    domain: Option<&Domain>,
) -> Grow {
    let near = tree.nearest(target);
    let from = tree.node(near);
    let d = dist(from, target);
    if domain.is_some() && d > tree.domain[near] {
        return Grow::Outside;
    }
    let (q, reached) = if d <= range {
        (target.to_vec(), true)
    } else {
        let s = range / d;
        (
            from.iter()
                .zip(target)
                .map(|(a, b)| a + (b - a) * s)
                .collect(),
            false,
        )
    };
    let free = checker.motion_free(from, &q);
    if let Some(domain) = domain {
        tree.domain[near] = domain.after(tree.domain[near], !free);
    }
    if !free {
        return Grow::Trapped;
    }
    let i = tree.add(&q, near);
    if reached {
        Grow::Reached(i)
    } else {
        Grow::Advanced(i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trapped node gets its domain; a sample beyond it is refused without an edge check;
    /// one within it is extended, and the domain grows by `alpha`. Repeated traps shrink it
    /// down to `min`, never below.
    #[test]
    fn a_trapped_node_keeps_its_samples_near() {
        use std::sync::atomic::Ordering;

        let checker = crate::checker::alone("locobot");
        let domain = Domain::for_checker(&checker);
        // A quarter of the LoCoBot's 7 rad diagonal.
        assert!((1.6..1.9).contains(&domain.radius), "{domain:?}");
        let edges = || checker.counters().edges.load(Ordering::Relaxed);
        let home = [0.0; 5];
        let mut tree = Tree::new(&home);
        // Joint 1 far beyond its limit: the extension is trapped.
        let out_of_limits = [50.0, 0.0, 0.0, 0.0, 0.0];
        let grow = extend(&checker, &mut tree, &out_of_limits, 100.0, Some(&domain));
        assert_eq!(grow, Grow::Trapped);
        assert_eq!(tree.domain[0], domain.radius);
        // Beyond the domain: drawn again, nothing checked.
        let checked = edges();
        // Joints 1 and 5 turned (within their ±1.57 rad), 0.05 rad beyond the domain.
        let a = (domain.radius + 0.05) / 2f64.sqrt();
        let far = [a, 0.0, 0.0, 0.0, a];
        let grow = extend(&checker, &mut tree, &far, 100.0, Some(&domain));
        assert_eq!((grow, edges()), (Grow::Outside, checked));
        // Without domains the same sample is checked (and free).
        let mut plain = Tree::new(&home);
        assert_eq!(
            extend(&checker, &mut plain, &far, 100.0, None),
            Grow::Reached(1)
        );
        assert_eq!(edges(), checked + 1);
        // Within it: extended, and the domain grows.
        let near = [0.0, 0.0, 0.0, 0.0, 0.5];
        let grow = extend(&checker, &mut tree, &near, 100.0, Some(&domain));
        assert_eq!(grow, Grow::Reached(1));
        let grown = domain.radius * (1.0 + domain.alpha);
        assert!((tree.domain[0] - grown).abs() < 1e-12, "{}", tree.domain[0]);
        // Traps shrink it by alpha each, to `min` and no further.
        let mut r = tree.domain[0];
        r = domain.after(r, true);
        assert!((r - grown * (1.0 - domain.alpha)).abs() < 1e-12);
        for _ in 0..100_000 {
            r = domain.after(r, true);
        }
        assert_eq!(r, domain.min);
    }
}
