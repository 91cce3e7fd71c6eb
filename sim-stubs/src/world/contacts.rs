//! Contacts of the robot's links with the scene, observed by exact shape queries (now, and
//! recorded over a motion while watched), and the bases' bumper ring against the scene
//! ([`Surroundings`]). The queries change nothing in the world.

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::parry::bounding_volume::BoundingVolume;
use rapier3d::prelude::*;

use super::{convert, World, BUMPER_BAND, CONTACT};
use crate::diff_drive::{Surroundings, Touch};

/// A robot link touching or penetrating a scene body now ([`World::robot_contacts`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotContact {
    /// The link's name (URDF).
    pub link: String,
    /// The scene body's id.
    pub body: String,
    /// Penetration depth, m, ≥ 0: the deepest over the link's and the body's shapes; 0 when
    /// they are within [`CONTACT`] of each other without penetrating.
    pub depth: f64,
}

/// A robot link and a scene body that touched while watched
/// ([`World::watch_robot_contacts`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotContactRecord {
    /// The link's name (URDF).
    pub link: String,
    /// The scene body's id.
    pub body: String,
    /// World time of the first check in which they touched, µs.
    pub first_us: u64,
    /// World time of the last check in which they touched, µs.
    pub last_us: u64,
    /// Checks (world steps, and the one when watching starts) in which they touched.
    pub steps: u64,
    /// Deepest penetration seen, m, ≥ 0 (see [`RobotContact::depth`]).
    pub max_depth: f64,
}

/// A contact watch that cannot be set up.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ContactError {
    /// The robot has no link of that name.
    #[error("the robot has no link {link:?} (its links: {known})")]
    UnknownLink {
        /// The name asked for.
        link: String,
        /// The robot's links, comma-separated (empty without a robot body).
        known: String,
    },
}

/// What a watch has seen of one (link, body) pair.
#[derive(Debug, Clone, Copy)]
struct Seen {
    first_us: u64,
    last_us: u64,
    steps: u64,
    max_depth: f64,
}

/// The links watched for contacts and what they touched, by (link index, scene index).
#[derive(Debug, Clone, Default)]
pub(super) struct Watch {
    links: Vec<usize>,
    seen: BTreeMap<(usize, usize), Seen>,
}

impl World {
    /// Names (URDF) of the robot's links that have collision shapes, in
    /// [`ferrobot_kinematics::LinkTree::links`] order; empty without a robot body.
    pub fn robot_links(&self) -> Vec<String> {
        let Some(r) = self.robot(0) else {
            return Vec::new();
        };
        r.body
            .tree
            .links()
            .zip(&r.links)
            .filter(|(_, h)| h.is_some())
            .map(|(n, _)| n.to_string())
            .collect()
    }

    /// Every (robot link, scene body) pair in contact now (within [`CONTACT`], penetrating
    /// included), for every link with shapes against every scene body, fixed or movable, the
    /// floor and walls included; in link order ([`ferrobot_kinematics::LinkTree::links`]),
    /// then scene order. Exact shapes (a movable mesh's convex hull, as the engine has it; a
    /// link entirely inside a static mesh, which has no inside, is not seen). The object the
    /// gripper holds is in contact with its fingers. Empty without a robot body.
    pub fn robot_contacts(&self) -> Vec<RobotContact> {
        let Some(r) = self.robot(0) else {
            return Vec::new();
        };
        let links: Vec<usize> = (0..r.links.len()).collect();
        self.contacts_of(&links)
            .into_iter()
            .map(|(l, b, depth)| RobotContact {
                link: self.link_name(l),
                body: self.ids.get(b).cloned().unwrap_or_default(),
                depth,
            })
            .collect()
    }

    /// Record, from now on and at every step, which of the robot's `links` (URDF names)
    /// touch which scene bodies (as [`World::robot_contacts`] sees them), with the first and
    /// last time, the number of steps and the deepest penetration of each pair; read with
    /// [`World::take_robot_contacts`]. Checks once now, too. Replaces an earlier watch and
    /// drops what it recorded. Checked once per step ([`STEP_US`](super::STEP_US): a link
    /// moving at 1 m/s advances 1 mm between checks). Costs nothing while nothing is watched; a watch costs
    /// one bounding-box test per scene body and link shape per step, and an exact query per
    /// pair whose boxes meet (all 18 of the LoCoBot's links in the tabletop: about 4 µs a
    /// step). Changes nothing in the physics. Links without shapes are accepted and never
    /// touch anything.
    ///
    /// # Errors
    ///
    /// [`ContactError::UnknownLink`] when the robot has no link of a given name (nothing is
    /// watched then).
    pub fn watch_robot_contacts<S: AsRef<str>>(&mut self, links: &[S]) -> Result<(), ContactError> {
        let (names, indices) = match self.robot(0) {
            Some(r) => (
                r.body.tree.links().collect::<Vec<_>>().join(", "),
                links
                    .iter()
                    .map(|l| r.body.tree.link_index(l.as_ref()).ok_or(l.as_ref()))
                    .collect::<Result<Vec<usize>, &str>>(),
            ),
            None => (
                String::new(),
                links.first().map_or(Ok(Vec::new()), |l| Err(l.as_ref())),
            ),
        };
        let mut indices = indices.map_err(|l| ContactError::UnknownLink {
            link: l.to_string(),
            known: names,
        })?;
        indices.sort_unstable();
        indices.dedup();
        self.watch = Some(Watch {
            links: indices,
            seen: BTreeMap::new(),
        });
        self.record_contacts();
        Ok(())
    }

    /// What the watch has recorded since it started or was last taken, and forget it (the
    /// watch goes on): one record per (link, body) pair that touched, ordered by the time
    /// they first touched, then link and scene order. Empty when nothing is watched.
    pub fn take_robot_contacts(&mut self) -> Vec<RobotContactRecord> {
        let Some(w) = self.watch.as_mut() else {
            return Vec::new();
        };
        let seen = std::mem::take(&mut w.seen);
        let mut out: Vec<(u64, RobotContactRecord)> = seen
            .into_iter()
            .map(|((l, b), s)| {
                (
                    s.first_us,
                    RobotContactRecord {
                        link: self.link_name(l),
                        body: self.ids.get(b).cloned().unwrap_or_default(),
                        first_us: s.first_us,
                        last_us: s.last_us,
                        steps: s.steps,
                        max_depth: s.max_depth,
                    },
                )
            })
            .collect();
        // Stable: pairs that first touched together stay in link, then scene order.
        out.sort_by_key(|(t, _)| *t);
        out.into_iter().map(|(_, r)| r).collect()
    }

    /// Stop watching; what was recorded and not yet taken (as
    /// [`World::take_robot_contacts`]).
    pub fn unwatch_robot_contacts(&mut self) -> Vec<RobotContactRecord> {
        let out = self.take_robot_contacts();
        self.watch = None;
        out
    }

    /// Name (URDF) of link `i` ([`ferrobot_kinematics::LinkTree::links`] index).
    fn link_name(&self, i: usize) -> String {
        self.robot(0)
            .and_then(|r| r.body.tree.links().nth(i))
            .unwrap_or("?")
            .to_string()
    }

    /// Add the watched links' contacts now to the watch's record.
    pub(super) fn record_contacts(&mut self) {
        let Some(mut w) = self.watch.take() else {
            return;
        };
        let now = self.time_us;
        for (l, b, depth) in self.contacts_of(&w.links) {
            w.seen
                .entry((l, b))
                .and_modify(|s| {
                    s.last_us = now;
                    s.steps += 1;
                    s.max_depth = s.max_depth.max(depth);
                })
                .or_insert(Seen {
                    first_us: now,
                    last_us: now,
                    steps: 1,
                    max_depth: depth,
                });
        }
        self.watch = Some(w);
    }

    /// The contacts of robot links `links` ([`ferrobot_kinematics::LinkTree::links`]
    /// indices, ascending) now: (link, scene index, penetration depth in m ≥ 0), in link then
    /// scene order. Poses from the bodies (a link put in place while the world rests has
    /// moved its body, not yet its colliders).
    fn contacts_of(&self, links: &[usize]) -> Vec<(usize, usize, f64)> {
        let Some(r) = self.robot(0) else {
            return Vec::new();
        };
        let placed = |rb: &RigidBody, c: &Collider| match c.position_wrt_parent() {
            Some(local) => *rb.position() * *local,
            None => *c.position(),
        };
        // The links' shapes where they are, and the box around them all.
        let mut shapes: Vec<(
            usize,
            Pose,
            &Collider,
            rapier3d::parry::bounding_volume::Aabb,
        )> = Vec::new();
        for &l in links {
            let Some(lb) = r
                .links
                .get(l)
                .copied()
                .flatten()
                .and_then(|h| self.pw.bodies.get(h))
            else {
                continue;
            };
            for c in self.colliders_of(lb) {
                let pose = placed(lb, c);
                let aabb = c.shape().compute_aabb(&pose).loosened(CONTACT as f32);
                shapes.push((l, pose, c, aabb));
            }
        }
        let Some(all) = shapes.iter().map(|s| s.3).reduce(|a, b| a.merged(&b)) else {
            return Vec::new();
        };
        let mut found: BTreeMap<(usize, usize), f64> = BTreeMap::new();
        for (i, h) in self.bodies.iter().enumerate() {
            let Some(rb) = self.pw.bodies.get(*h) else {
                continue;
            };
            for c in self.colliders_of(rb) {
                let pose = placed(rb, c);
                let aabb = c.shape().compute_aabb(&pose);
                if !aabb.intersects(&all) {
                    continue;
                }
                for (l, lpose, lc, laabb) in &shapes {
                    if !aabb.intersects(laabb) {
                        continue;
                    }
                    let hit = rapier3d::parry::query::contact(
                        lpose,
                        lc.shape(),
                        &pose,
                        c.shape(),
                        CONTACT as f32,
                    );
                    let Ok(Some(k)) = hit else { continue };
                    let dist = f64::from(k.dist);
                    if dist > CONTACT || !dist.is_finite() {
                        continue;
                    }
                    let depth = (-dist).max(0.0);
                    found
                        .entry((*l, i))
                        .and_modify(|d| *d = d.max(depth))
                        .or_insert(depth);
                }
            }
        }
        found.into_iter().map(|((l, b), d)| (l, b, d)).collect()
    }
}

/// The world around robot `robot`'s base, as its bumper ring meets it: every scene body and
/// every other robot's links (fixed to it: a bumper does not push a robot), not its own links
/// ([`World::around`]).
#[derive(Clone, Copy)]
pub struct Around<'a> {
    world: &'a World,
    robot: usize,
}

impl World {
    /// The world around robot `i`'s base ([`Around`]).
    pub fn around(&self, i: usize) -> Around<'_> {
        Around {
            world: self,
            robot: i,
        }
    }
}

impl Surroundings for World {
    /// The world around the first robot ([`World::around`]).
    fn touches(&self, x: f64, y: f64, radius: f64, gap: f64) -> Vec<Touch> {
        self.around(0).touches(x, y, radius, gap)
    }
}

impl Surroundings for Around<'_> {
    fn touches(&self, x: f64, y: f64, radius: f64, gap: f64) -> Vec<Touch> {
        let (lo, hi) = BUMPER_BAND;
        let ring = rapier3d::parry::shape::Cylinder::new(((hi - lo) / 2.0) as f32, radius as f32);
        let at = Isometry3::from_parts(
            Translation3::new(x, y, (lo + hi) / 2.0),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2),
        );
        let pose = convert::pose(&at);
        let aabb = rapier3d::parry::shape::Shape::compute_aabb(&ring, &pose).loosened(gap as f32);
        let own = super::link_tag(self.robot);
        let not_own = |_: ColliderHandle, c: &Collider| c.user_data != own;
        let filter = QueryFilter::default().predicate(&not_own);
        let pw = &self.world.pw;
        let mut out = Vec::new();
        for (h, c) in pw.intersect_aabb_conservative(aabb, filter) {
            let Ok(Some(k)) =
                rapier3d::parry::query::contact(&pose, &ring, c.position(), c.shape(), gap as f32)
            else {
                continue;
            };
            let n = convert::from_vector(k.normal1);
            // Only a scene's movable body gives way; the others' links are driven by their
            // plants, as fixed as a wall to this one.
            let fixed = c
                .parent()
                .and_then(|b| pw.bodies.get(b))
                .is_none_or(|b| !b.is_dynamic());
            let (i, g) = h.into_raw_parts();
            out.push(Touch {
                id: (u64::from(g) << 32) | u64::from(i),
                bearing: n.y.atan2(n.x),
                depth: -f64::from(k.dist),
                fixed,
            });
        }
        out
    }
}
