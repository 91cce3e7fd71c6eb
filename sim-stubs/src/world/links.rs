//! The robot's body in the world: where the plants put its link bodies, moving them there
//! (waking what they touch), whether the world must step, and the overlap check at the start.

use rapier3d::parry::bounding_volume::BoundingVolume;
use rapier3d::prelude::*;

use super::{convert, World, NEAR, OVERLAP};
use crate::body::RobotBody;
use crate::diff_drive::Pose as BasePose;
use crate::scene::{Scene, SceneError};

impl World {
    /// Where robot `i`'s link bodies belong for its plants' state: each link body with its
    /// pose (the fingers held at the contact angle while the gripper holds an object).
    pub(super) fn link_targets(
        &self,
        i: usize,
        base: BasePose,
        theta: &[f64],
    ) -> Vec<(RigidBodyHandle, Pose)> {
        let Some(r) = self.robot(i) else {
            return Vec::new();
        };
        let mut theta = theta.to_vec();
        if let (Some(g), Some(hand)) = (&r.grasp, r.body.hand()) {
            if let Some(t) = theta.get_mut(hand.servo) {
                *t = if hand.closed < hand.open {
                    t.max(g.at)
                } else {
                    t.min(g.at)
                };
            }
        }
        let root = RobotBody::root_pose(base, r.height);
        let q = r.body.joint_values(&theta);
        let poses = r.body.link_poses(&root, &q);
        r.links
            .iter()
            .zip(&poses)
            .filter_map(|(h, p)| h.map(|h| (h, convert::pose(p))))
            .collect()
    }

    /// Put the link bodies at `targets` now, outside a step.
    pub(super) fn teleport(&mut self, targets: &[(RigidBodyHandle, Pose)]) {
        for (h, p) in targets {
            if let Some(rb) = self.pw.bodies.get_mut(*h) {
                rb.set_position(*p, false);
            }
        }
    }

    /// Send the link bodies to `targets` in the next step, waking what the moving ones touch
    /// (rapier does not wake a sleeping body that a kinematic one runs into).
    pub(super) fn drive(&mut self, targets: &[(RigidBodyHandle, Pose)]) {
        let mut moving = Vec::new();
        for (h, p) in targets {
            if let Some(rb) = self.pw.bodies.get_mut(*h) {
                if rb.position() != p {
                    moving.extend(rb.colliders().iter().copied());
                }
                rb.set_next_kinematic_position(*p);
            }
        }
        let mut wake = Vec::new();
        for &c in &moving {
            for pair in self.pw.narrow_phase.contact_pairs_with(c) {
                let other = if pair.collider1 == c {
                    pair.collider2
                } else {
                    pair.collider1
                };
                if let Some(b) = self.pw.colliders.get(other).and_then(|o| o.parent()) {
                    wake.push(b);
                }
            }
        }
        for b in wake {
            if let Some(rb) = self.pw.bodies.get_mut(b) {
                if rb.is_dynamic() && rb.is_sleeping() {
                    rb.wake_up(true);
                }
            }
        }
    }

    /// Whether a link moving to `targets` comes within [`NEAR`] of a movable body, or any
    /// movable body is awake: the engine has something to do.
    pub(super) fn busy(&self, targets: &[(RigidBodyHandle, Pose)]) -> bool {
        let bodies = &self.pw.bodies;
        let movable: Vec<&RigidBody> = self
            .bodies
            .iter()
            .filter_map(|h| bodies.get(*h))
            .filter(|b| b.is_dynamic())
            .collect();
        if movable.iter().any(|b| !b.is_sleeping()) {
            return true;
        }
        let mut swept = Vec::new();
        for (h, p) in targets {
            let Some(rb) = bodies.get(*h) else { continue };
            if rb.position() == p {
                continue;
            }
            for c in self.colliders_of(rb) {
                let local = c.position_wrt_parent().copied().unwrap_or(Pose::IDENTITY);
                let to = c.shape().compute_aabb(&(*p * local));
                swept.push(c.compute_aabb().merged(&to).loosened(NEAR as f32));
            }
        }
        if swept.is_empty() {
            return false;
        }
        movable.iter().any(|b| {
            self.colliders_of(b).any(|c| {
                let a = c.compute_aabb();
                swept.iter().any(|s| s.intersects(&a))
            })
        })
    }

    /// Robot `i`'s links against the scene's bodies and the other robots' links: the first
    /// pair reaching more than [`OVERLAP`] into each other, as an error naming both.
    pub(super) fn check_overlap(&self, i: usize, scene: &Scene) -> Result<(), SceneError> {
        let Some(r) = self.robot(i) else {
            return Ok(());
        };
        let names: Vec<&str> = r.body.tree.links().collect();
        let link_name = |li: usize| names.get(li).copied().unwrap_or("?").to_string();
        for (si, h) in self.bodies.iter().enumerate() {
            if let Some(li) = self.overlap(r, *h) {
                return Err(SceneError::Overlap {
                    object: scene
                        .bodies
                        .get(si)
                        .map(|b| b.id.clone())
                        .unwrap_or_default(),
                    link: link_name(li),
                });
            }
        }
        for (oi, other) in self.robots.iter().enumerate() {
            let Some(other) = other.as_ref().filter(|_| oi != i) else {
                continue;
            };
            let other_names: Vec<&str> = other.body.tree.links().collect();
            for (ol, oh) in other.links.iter().enumerate() {
                let Some(li) = oh.and_then(|oh| self.overlap(r, oh)) else {
                    continue;
                };
                return Err(SceneError::Overlap {
                    object: format!(
                        "robot {oi}'s link {}",
                        other_names.get(ol).copied().unwrap_or("?")
                    ),
                    link: link_name(li),
                });
            }
        }
        Ok(())
    }

    /// The first of `r`'s links that a collider of body `h` reaches more than [`OVERLAP`]
    /// into.
    fn overlap(&self, r: &super::Robot, h: RigidBodyHandle) -> Option<usize> {
        let rb = self.pw.bodies.get(h)?;
        for c in self.colliders_of(rb) {
            let aabb = c.compute_aabb();
            for (li, lh) in r.links.iter().enumerate() {
                let Some(lb) = lh.and_then(|h| self.pw.bodies.get(h)) else {
                    continue;
                };
                for lc in self.colliders_of(lb) {
                    if !aabb.intersects(&lc.compute_aabb()) {
                        continue;
                    }
                    let hit = rapier3d::parry::query::contact(
                        c.position(),
                        c.shape(),
                        lc.position(),
                        lc.shape(),
                        0.0,
                    );
                    if let Ok(Some(k)) = hit {
                        if f64::from(k.dist) < -OVERLAP {
                            return Some(li);
                        }
                    }
                }
            }
        }
        None
    }
}
