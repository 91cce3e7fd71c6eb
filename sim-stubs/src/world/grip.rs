//! The gripper's grip: a grasp constraint made when both fingers touch one movable object
//! from either side, released when the gripper servo has opened [`RELEASE`] beyond the contact
//! angle; the servo's obstacle set and cleared with it.

use rapier3d::parry::bounding_volume::BoundingVolume;
use rapier3d::prelude::*;

use super::{Grasp, Robot, World, RELEASE, TOUCH};
use crate::body::Hand;
use crate::chain::ServoChain;

/// An object both fingers touch from either side, ready to be held.
struct Hold {
    /// Scene index of the object.
    object: usize,
    /// The palm's link body.
    palm: RigidBodyHandle,
    /// The object's body.
    body: RigidBodyHandle,
    /// The object's pose in the palm's frame.
    frame1: Pose,
}

impl World {
    /// Robot `i`'s gripper: grasp when both fingers touch one movable object; release when
    /// the servo has opened.
    pub(super) fn grip(&mut self, i: usize, theta: &[f64], chain: &mut ServoChain) {
        let Some(r) = self.robot(i) else { return };
        let Some(hand) = r.body.hand().cloned() else {
            return;
        };
        let Some(&angle) = theta.get(hand.servo) else {
            return;
        };
        // Closing moves the servo angle towards the closed stop.
        let closing_down = hand.closed < hand.open;
        if let Some(g) = r.grasp {
            let opened = if closing_down {
                angle - g.at
            } else {
                g.at - angle
            };
            if opened > RELEASE {
                self.release(i, g, &hand, chain);
            }
            return;
        }
        let Some(hold) = self.held_between_fingers(r, &hand) else {
            return;
        };
        self.grasp(i, hold, &hand, (angle, closing_down), chain);
    }

    /// Robot `i` lets go of `g`: remove its joint, clear the servo's obstacle if still ours,
    /// wake the object.
    fn release(&mut self, i: usize, g: Grasp, hand: &Hand, chain: &mut ServoChain) {
        self.pw.remove_impulse_joint(g.joint);
        if let Some(s) = chain.servos.get_mut(hand.servo) {
            if s.obstacle == Some(g.obstacle) {
                s.obstacle = None;
            }
        }
        if let Some(rb) = self
            .bodies
            .get(g.object)
            .and_then(|h| self.pw.bodies.get_mut(*h))
        {
            rb.wake_up(true);
        }
        if let Some(Some(r)) = self.robots.get_mut(i) {
            r.grasp = None;
        }
    }

    /// The colliders of each finger's link (empty for a finger without a body).
    fn finger_colliders(&self, r: &Robot, hand: &Hand) -> Vec<Vec<ColliderHandle>> {
        hand.fingers
            .iter()
            .map(|&f| {
                r.links
                    .get(f)
                    .copied()
                    .flatten()
                    .and_then(|h| self.pw.bodies.get(h))
                    .map(|b| b.colliders().to_vec())
                    .unwrap_or_default()
            })
            .collect()
    }

    /// The first movable object that every finger touches (within [`TOUCH`]) and whose centre
    /// lies between the first two fingers, with the palm's and its bodies.
    fn held_between_fingers(&self, r: &Robot, hand: &Hand) -> Option<Hold> {
        let finger_colliders = self.finger_colliders(r, hand);
        if finger_colliders.len() < 2 || finger_colliders.iter().any(Vec::is_empty) {
            return None;
        }
        // Movable objects near the first finger (by the broad phase's boxes, with a margin for
        // their motion in the last step), then whether every finger touches one.
        let first = finger_colliders
            .first()
            .and_then(|c| c.first())
            .and_then(|h| self.pw.colliders.get(*h))?;
        let near = first.compute_aabb().loosened(0.01);
        let candidates: Vec<ColliderHandle> = self
            .pw
            .intersect_aabb_conservative(near, QueryFilter::only_dynamic())
            .map(|(h, _)| h)
            .collect();
        // An object is grasped only from both sides: its centre lies between the first two
        // fingers along the line joining them (not beside a closed pair that pushes it).
        let centre = |f: &Vec<ColliderHandle>| {
            f.first()
                .and_then(|h| self.pw.colliders.get(*h))
                .map(|c| c.position().translation)
        };
        let (Some(a), Some(b)) = (
            finger_colliders.first().and_then(centre),
            finger_colliders.get(1).and_then(centre),
        ) else {
            return None;
        };
        let between = |o: Vector| {
            let ab = b - a;
            let t = (o - a).dot(ab);
            t > 0.0 && t < ab.length_squared()
        };
        for ch in candidates {
            let Some(c) = self.pw.colliders.get(ch) else {
                continue;
            };
            let object = c.user_data as usize;
            if object >= self.bodies.len() {
                continue;
            }
            if !finger_colliders.iter().all(|fc| self.touches(fc, c))
                || !between(c.position().translation)
            {
                continue;
            }
            let (Some(palm), Some(oh)) = (
                r.links.get(hand.palm).copied().flatten(),
                self.bodies.get(object).copied(),
            ) else {
                continue;
            };
            let (Some(pb), Some(ob)) = (self.pw.bodies.get(palm), self.pw.bodies.get(oh)) else {
                continue;
            };
            return Some(Hold {
                object,
                palm,
                body: oh,
                frame1: pb.position().inv_mul(ob.position()),
            });
        }
        None
    }

    /// Whether any of a finger's colliders `fc` is within [`TOUCH`] of collider `c`.
    fn touches(&self, fc: &[ColliderHandle], c: &Collider) -> bool {
        fc.iter().any(|h| {
            self.pw.colliders.get(*h).is_some_and(|f| {
                rapier3d::parry::query::distance(f.position(), f.shape(), c.position(), c.shape())
                    .is_ok_and(|d| f64::from(d.distance) <= TOUCH)
            })
        })
    }

    /// Robot `i` holds `hold`: a fixed joint from the palm, the object woken, the servo blocked at the
    /// `obstacle` (angle at contact, rad; whether closing lowers the angle).
    fn grasp(
        &mut self,
        i: usize,
        hold: Hold,
        hand: &Hand,
        obstacle: (f64, bool),
        chain: &mut ServoChain,
    ) {
        let joint = FixedJointBuilder::new()
            .local_frame1(hold.frame1)
            .local_frame2(Pose::IDENTITY)
            .contacts_enabled(false);
        let joint = self.pw.insert_impulse_joint(hold.palm, hold.body, joint);
        if let Some(ob) = self.pw.bodies.get_mut(hold.body) {
            ob.wake_up(true);
        }
        if let Some(s) = chain.servos.get_mut(hand.servo) {
            s.obstacle = Some(obstacle);
        }
        if let Some(Some(r)) = self.robots.get_mut(i) {
            r.grasp = Some(Grasp {
                object: hold.object,
                joint,
                at: obstacle.0,
                obstacle,
            });
        }
    }
}
