//! How far the model's points move for a joint step: each planned joint's reach over a
//! link's spheres (m per rad, or per m of a prismatic joint), from the joint's origin and from
//! its axis.

use ferrobot_kinematics::JointType;
use nalgebra::{Isometry3, Point3};

use super::CollisionModel;
use crate::spheres::Sphere;

impl CollisionModel {
    /// For each planned joint, the largest of [`CollisionModel::link_reach`] over the links it
    /// carries and `extra` spheres (link index, spheres in that link's frame): a step Δq moves
    /// no point more than Σ |Δqᵢ|·reachᵢ.
    pub fn reach(&self, extra: &[(usize, Vec<Sphere>)]) -> Vec<f64> {
        self.largest(extra, |l, s| self.link_reach(l, s))
    }

    /// The arm's size (m): the largest bound on a moving point's distance from a planned
    /// joint's origin (`origin_reach`), with `extra` spheres as
    /// [`CollisionModel::reach`] takes them.
    pub fn span(&self, extra: &[(usize, Vec<Sphere>)]) -> f64 {
        self.largest(extra, |l, s| self.origin_reach(l, s))
            .into_iter()
            .fold(0.0, f64::max)
    }

    /// For each planned joint, the largest of `bound(link, spheres)` over the links and their
    /// `extra` spheres.
    fn largest(
        &self,
        extra: &[(usize, Vec<Sphere>)],
        bound: impl Fn(usize, &[Sphere]) -> Vec<f64>,
    ) -> Vec<f64> {
        let mut out = vec![0.0f64; self.planned.len()];
        for l in 0..self.links.len() {
            let spheres: Vec<Sphere> = self.links[l]
                .spheres
                .iter()
                .copied()
                .chain(
                    extra
                        .iter()
                        .filter(|(el, _)| *el == l)
                        .flat_map(|(_, s)| s.iter().copied()),
                )
                .collect();
            for (o, r) in out.iter_mut().zip(bound(l, &spheres)) {
                *o = o.max(r);
            }
        }
        out
    }

    /// For each planned joint, a bound (m) on how far a unit step of it moves any point of
    /// `spheres` (in link `link`'s frame) when the joint carries the link, else 0: for a
    /// revolute joint the points' distance from its axis, for a prismatic one 1. A step Δq
    /// moves no point of them more than Σ |Δqᵢ|·reachᵢ, in the world and in the frame of any
    /// link above the joints.
    ///
    /// The smaller of two bounds: the distance from the joint's origin along the chain
    /// (`origin_reach`) and the distance from its axis
    /// (`axis_reach`), which is much smaller where the link lies along the
    /// axis (a wrist's roll: the LoCoBot's gripper 0.103 → 0.055 m, its fingers 0.109 →
    /// 0.018 m) or beside it (Sawyer's `right_l1` about its own joint 0.300 → 0.117 m).
    pub fn link_reach(&self, link: usize, spheres: &[Sphere]) -> Vec<f64> {
        let origin = self.origin_reach(link, spheres);
        self.planned
            .iter()
            .zip(&origin)
            .map(|(&j, &r)| {
                self.axis_reach(link, spheres, j, &origin)
                    .map_or(r, |a| a.min(r))
            })
            .collect()
    }

    /// A bound (m) on the distance from revolute joint `j`'s axis of any point of `spheres`
    /// (in link `link`'s frame) when `j` carries the link; `None` when it does not apply
    /// (`j` prismatic or not above the link, or a prismatic planned joint between them).
    ///
    /// The chain from the link up to `j` is rigid except at planned joints. Where none lies
    /// between, the spheres' distance from the axis is fixed: the bound is exact. Where some
    /// do, let `k` be the one nearest `j`: `k`'s origin is fixed relative to `j`'s axis, and
    /// every point below `k` is within `origin[k]` of that origin (the origin bound), so the
    /// bound is the origin's distance from the axis plus `origin[k]` (the triangle
    /// inequality).
    fn axis_reach(&self, link: usize, spheres: &[Sphere], j: usize, origin: &[f64]) -> Option<f64> {
        let joint = &self.tree.joints()[j];
        if joint.kind != JointType::Revolute {
            return None;
        }
        // Points with radii, in the frame of link `at`: the spheres, or the origin of the
        // nearest planned joint passed, with its bound.
        let mut points: Vec<(Point3<f64>, f64)> =
            spheres.iter().map(|s| (s.centre, s.radius)).collect();
        let mut at = link;
        loop {
            let lj = self.tree.link_joint(at);
            if lj == Some(j) {
                let a = joint.axis;
                let far = points.iter().fold(0.0f64, |m, (p, r)| {
                    let v = p.coords;
                    m.max((v - a * v.dot(&a)).norm() + r)
                });
                // Rounding of the chain's products: a nanometre and a part in 10⁹.
                return Some(far * (1.0 + 1e-9) + 1e-9);
            }
            if let Some(k) = lj {
                if let Some(pk) = self.planned.iter().position(|&p| p == k) {
                    if self.tree.joints()[k].kind != JointType::Revolute {
                        return None;
                    }
                    // Everything below is within `origin[pk]` of k's origin.
                    points = vec![(Point3::origin(), origin[pk])];
                } else {
                    // A joint not planned: rigid at its value.
                    let v = self.values[k];
                    let m = match self.tree.joints()[k].kind {
                        JointType::Revolute => Isometry3::rotation(self.tree.joints()[k].axis * v),
                        JointType::Prismatic => {
                            let a = self.tree.joints()[k].axis * v;
                            Isometry3::translation(a.x, a.y, a.z)
                        }
                    };
                    for (p, _) in &mut points {
                        *p = m * *p;
                    }
                }
            }
            let o = self
                .tree
                .link_origin(at)
                .unwrap_or_else(Isometry3::identity);
            for (p, _) in &mut points {
                *p = o * *p;
            }
            at = self.tree.parent(at)?;
        }
    }

    /// [`CollisionModel::link_reach`]'s bound from each joint's origin: the norms of the
    /// joint offsets from the link up to the joint (and prismatic travel) plus the spheres'
    /// extent in the link's frame.
    fn origin_reach(&self, link: usize, spheres: &[Sphere]) -> Vec<f64> {
        let extent = spheres
            .iter()
            .map(|s| s.centre.coords.norm() + s.radius)
            .fold(0.0, f64::max);
        self.planned
            .iter()
            .map(|&j| {
                // The path from `link` up to the joint's link: its joint offsets (and
                // prismatic travel) bound how far `link`'s frame is from the joint's origin.
                let mut at = link;
                let mut offset = 0.0;
                loop {
                    if self.tree.link_joint(at) == Some(j) {
                        return if self.tree.joints()[j].kind == JointType::Prismatic {
                            1.0
                        } else {
                            offset + extent
                        };
                    }
                    offset += self
                        .tree
                        .link_origin(at)
                        .map_or(0.0, |o| o.translation.vector.norm());
                    if let Some(jj) = self.tree.link_joint(at) {
                        if self.tree.joints()[jj].kind == JointType::Prismatic {
                            offset += match self.planned.iter().position(|&p| p == jj) {
                                Some(k) => self.limits[k].0.abs().max(self.limits[k].1.abs()),
                                None => self.values[jj].abs(),
                            };
                        }
                    }
                    match self.tree.parent(at) {
                        Some(p) => at = p,
                        None => return 0.0,
                    }
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrobot_description::RobotConfig;

    /// At random states of both bundled arms, no sphere of a moving link reaches farther from
    /// a revolute planned joint's axis than the link's reach for that joint; and the axis
    /// bound is attained (within 1 mm, so it is exact where no planned joint lies between)
    /// for the LoCoBot's gripper about its wrist's roll, where it is half the origin bound.
    #[test]
    fn reach_bounds_every_sphere_from_each_axis() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for robot in ["locobot", "sawyer"] {
            let cfg = RobotConfig::bundled(robot).expect("robot");
            let model = CollisionModel::from_config(&cfg).expect("model");
            let reach: Vec<Vec<f64>> = (0..model.links().len())
                .map(|l| model.link_reach(l, &model.links()[l].spheres))
                .collect();
            let mut seen = vec![vec![0.0f64; model.dof()]; model.links().len()];
            for _ in 0..400 {
                let q: Vec<f64> = model
                    .limits()
                    .iter()
                    .map(|&(lo, hi)| rng.random_range(lo..=hi))
                    .collect();
                let poses = model.link_poses(&q);
                for (k, &j) in model.planned.iter().enumerate() {
                    let lj = (0..poses.len())
                        .find(|&l| model.tree().link_joint(l) == Some(j))
                        .expect("joint's link");
                    let axis = poses[lj].rotation * model.tree().joints()[j].axis;
                    let o = poses[lj].translation.vector;
                    for (l, link) in model.links().iter().enumerate() {
                        for s in &link.spheres {
                            let v = (poses[l] * s.centre).coords - o;
                            let d = (v - axis * v.dot(&axis)).norm() + s.radius;
                            if reach[l][k] == 0.0 {
                                continue;
                            }
                            assert!(
                                d <= reach[l][k] + 1e-9,
                                "{robot} {}: {d} m from joint {k}'s axis, reach {}",
                                link.name,
                                reach[l][k]
                            );
                            seen[l][k] = seen[l][k].max(d);
                        }
                    }
                }
            }
            if robot == "locobot" {
                let g = model.link_index("gripper_link").expect("gripper");
                let roll = model.dof() - 1;
                assert!((seen[g][roll] - reach[g][roll]).abs() < 1e-3);
                let origin = model.origin_reach(g, &model.links()[g].spheres);
                assert!(reach[g][roll] < 0.6 * origin[roll], "{reach:?}");
            }
        }
    }
}
