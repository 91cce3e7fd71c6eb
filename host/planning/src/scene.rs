//! The planning scene: objects in the world, objects attached to a link (carried by the
//! gripper), and an occupancy of small cubes from a point cloud. Everything is checked when
//! it is added, so a scene the planner sees is always valid.

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Point3};

use crate::shape::{Shape, MAX_DISTANCE};
use crate::{Error, Result};

/// Longest object id, bytes.
pub const MAX_ID_LEN: usize = 128;
/// Most objects in a scene (world and attached together).
pub const MAX_OBJECTS: usize = 10_000;
/// Most occupied voxels.
pub const MAX_VOXELS: usize = 1_000_000;
/// Smallest and largest voxel edge, m.
pub const VOXEL_RANGE: (f64, f64) = (0.005, 1.0);

/// An object in the world.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldObject {
    /// Unique id.
    pub id: String,
    /// Shape in the object's frame.
    pub shape: Shape,
    /// Pose of the object's frame in the robot's root frame.
    pub pose: Isometry3<f64>,
}

/// An object attached to a link: it moves with the link, is checked against the world and the
/// robot's other links, and may touch its link and `touch_links`.
#[derive(Debug, Clone, PartialEq)]
pub struct AttachedObject {
    /// Unique id.
    pub id: String,
    /// The link it is attached to.
    pub link: String,
    /// Shape in the object's frame.
    pub shape: Shape,
    /// Pose of the object's frame in the link's frame.
    pub pose: Isometry3<f64>,
    /// Links allowed to touch it besides its own (the gripper's fingers).
    pub touch_links: Vec<String>,
}

/// Occupied cubes of edge `size` (m), given by their integer cell `[i, j, k]`: the cube spans
/// `[i·size, (i+1)·size]` along x in the root frame, and so on.
#[derive(Debug, Clone, PartialEq)]
pub struct Voxels {
    /// Edge of a cube, m.
    pub size: f64,
    /// Occupied cells, sorted, without repeats.
    pub cells: Vec<[i32; 3]>,
}

impl Voxels {
    /// The cubes occupied by `points` (root frame, m) with edge `size` (m); non-finite or far
    /// points and a size outside [`VOXEL_RANGE`] are errors.
    pub fn from_points(points: &[Point3<f64>], size: f64) -> Result<Self> {
        check_size(size)?;
        let mut cells = Vec::with_capacity(points.len().min(MAX_VOXELS));
        for (i, p) in points.iter().enumerate() {
            if p.coords
                .iter()
                .any(|v| !v.is_finite() || v.abs() > MAX_DISTANCE)
            {
                return Err(Error::Invalid {
                    what: format!("point {i} of the cloud"),
                    why: format!("{p} is not finite or beyond {MAX_DISTANCE} m"),
                });
            }
            cells.push(p.coords.map(|v| (v / size).floor() as i32).into());
        }
        cells.sort_unstable();
        cells.dedup();
        let v = Voxels { size, cells };
        v.validate()?;
        Ok(v)
    }

    /// Checks what [`Voxels::from_points`] guarantees, for voxels built by hand: a size within
    /// [`VOXEL_RANGE`], at most [`MAX_VOXELS`] cells, sorted without repeats, each cube within
    /// [`MAX_DISTANCE`] of the root frame's origin.
    pub fn validate(&self) -> Result<()> {
        let size = self.size;
        check_size(size)?;
        if self.cells.len() > MAX_VOXELS {
            return Err(Error::Invalid {
                what: "point cloud".into(),
                why: format!("{} voxels, more than {MAX_VOXELS}", self.cells.len()),
            });
        }
        // A point within MAX_DISTANCE lies in a cell within this (rounded down or up).
        let far = (MAX_DISTANCE / size).ceil() as i64 + 1;
        if let Some(c) = self
            .cells
            .iter()
            .find(|c| c.iter().any(|&v| i64::from(v).abs() > far))
        {
            return Err(Error::Invalid {
                what: "voxels".into(),
                why: format!("cell {c:?} of {size} m lies beyond {MAX_DISTANCE} m"),
            });
        }
        if self.cells.windows(2).any(|w| w[0] >= w[1]) {
            return Err(Error::Invalid {
                what: "voxels".into(),
                why: "cells are not sorted without repeats".into(),
            });
        }
        Ok(())
    }
}

/// A voxel edge (m) within [`VOXEL_RANGE`].
fn check_size(size: f64) -> Result<()> {
    if !size.is_finite() || !(VOXEL_RANGE.0..=VOXEL_RANGE.1).contains(&size) {
        return Err(Error::Invalid {
            what: "voxel size".into(),
            why: format!(
                "{size} m is not within [{}, {}] m",
                VOXEL_RANGE.0, VOXEL_RANGE.1
            ),
        });
    }
    Ok(())
}

/// What the planner plans around.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlanningScene {
    objects: BTreeMap<String, WorldObject>,
    attached: BTreeMap<String, AttachedObject>,
    voxels: Option<Voxels>,
}

fn check_id(id: &str) -> Result<()> {
    if id.is_empty() || id.len() > MAX_ID_LEN || id.chars().any(char::is_control) {
        return Err(Error::Invalid {
            what: "object id".into(),
            why: format!(
                "{id:?} is empty, longer than {MAX_ID_LEN} bytes or has control characters"
            ),
        });
    }
    Ok(())
}

fn check_pose(what: &str, pose: &Isometry3<f64>) -> Result<()> {
    let t = pose.translation.vector;
    let q = pose.rotation.quaternion();
    if t.iter().any(|v| !v.is_finite() || v.abs() > MAX_DISTANCE)
        || q.coords.iter().any(|v| !v.is_finite())
        || (q.norm() - 1.0).abs() > 1e-6
    {
        return Err(Error::Invalid {
            what: what.to_string(),
            why: format!(
                "pose {t:?} {:?} is not finite, not within {MAX_DISTANCE} m or not a unit quaternion",
                q.coords
            ),
        });
    }
    Ok(())
}

impl PlanningScene {
    /// An empty scene.
    pub fn new() -> Self {
        Self::default()
    }

    fn room(&self, id: &str) -> Result<()> {
        if self.objects.len() + self.attached.len() >= MAX_OBJECTS
            && !self.objects.contains_key(id)
            && !self.attached.contains_key(id)
        {
            return Err(Error::Invalid {
                what: "scene".into(),
                why: format!("more than {MAX_OBJECTS} objects"),
            });
        }
        Ok(())
    }

    /// Adds (or replaces) a world object `id` of `shape` at `pose` (root frame). An object
    /// attached under the same id is detached first.
    pub fn add_object(&mut self, id: &str, shape: Shape, pose: Isometry3<f64>) -> Result<()> {
        check_id(id)?;
        shape.validate(&format!("object {id:?}"))?;
        check_pose(&format!("object {id:?}"), &pose)?;
        self.room(id)?;
        self.attached.remove(id);
        self.objects.insert(
            id.to_string(),
            WorldObject {
                id: id.to_string(),
                shape,
                pose,
            },
        );
        Ok(())
    }

    /// Removes world or attached object `id`; an unknown id is an error.
    pub fn remove_object(&mut self, id: &str) -> Result<()> {
        if self.objects.remove(id).is_none() && self.attached.remove(id).is_none() {
            return Err(Error::Invalid {
                what: "object id".into(),
                why: format!("no object {id:?} in the scene"),
            });
        }
        Ok(())
    }

    /// Attaches an object to `link` at `pose` (link frame); a world object of the same id is
    /// taken out of the world. Link names are checked by the planner's model.
    pub fn attach(
        &mut self,
        id: &str,
        link: &str,
        shape: Shape,
        pose: Isometry3<f64>,
        touch_links: Vec<String>,
    ) -> Result<()> {
        check_id(id)?;
        shape.validate(&format!("attached object {id:?}"))?;
        check_pose(&format!("attached object {id:?}"), &pose)?;
        if pose.translation.vector.norm() > 2.0 {
            return Err(Error::Invalid {
                what: format!("attached object {id:?}"),
                why: "more than 2 m from its link".into(),
            });
        }
        self.room(id)?;
        self.objects.remove(id);
        self.attached.insert(
            id.to_string(),
            AttachedObject {
                id: id.to_string(),
                link: link.to_string(),
                shape,
                pose,
                touch_links,
            },
        );
        Ok(())
    }

    /// Detaches object `id`: it stays in the world where it is now, at `world_pose` (root
    /// frame) when given, or is dropped from the scene when `None`. An id not attached is an
    /// error.
    pub fn detach(&mut self, id: &str, world_pose: Option<Isometry3<f64>>) -> Result<()> {
        let a = self.attached.remove(id).ok_or_else(|| Error::Invalid {
            what: "object id".into(),
            why: format!("no object {id:?} is attached"),
        })?;
        if let Some(p) = world_pose {
            self.add_object(id, a.shape, p)?;
        }
        Ok(())
    }

    /// Replaces the occupancy from a point cloud; voxels that fail [`Voxels::validate`] are
    /// an error and leave the scene as it was.
    pub fn set_voxels(&mut self, voxels: Option<Voxels>) -> Result<()> {
        if let Some(v) = &voxels {
            v.validate()?;
        }
        self.voxels = voxels;
        Ok(())
    }

    /// Removes every object, attached or not, and the voxels.
    pub fn clear(&mut self) {
        self.objects.clear();
        self.attached.clear();
        self.voxels = None;
    }

    /// World objects, by id.
    pub fn objects(&self) -> impl Iterator<Item = &WorldObject> {
        self.objects.values()
    }

    /// A world object by id.
    pub fn object(&self, id: &str) -> Option<&WorldObject> {
        self.objects.get(id)
    }

    /// Attached objects, by id.
    pub fn attached(&self) -> impl Iterator<Item = &AttachedObject> {
        self.attached.values()
    }

    /// The occupancy, if any.
    pub fn voxels(&self) -> Option<&Voxels> {
        self.voxels.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Voxels built by hand are checked as those from a cloud are: a bad size, a cell beyond
    /// a kilometre (which once overflowed the checker's grid), unsorted or repeated cells are
    /// errors that leave the scene's voxels as they were.
    #[test]
    fn voxels_built_by_hand_are_checked() {
        let mut scene = PlanningScene::new();
        let good = Voxels::from_points(&[Point3::new(0.3, 0.0, 0.2)], 0.01).expect("voxels");
        scene.set_voxels(Some(good.clone())).expect("valid");
        let bad = [
            Voxels {
                size: 0.0,
                cells: vec![[0, 0, 0]],
            },
            Voxels {
                size: f64::NAN,
                cells: vec![[0, 0, 0]],
            },
            Voxels {
                size: 0.01,
                cells: vec![[i32::MIN; 3], [i32::MAX; 3]],
            },
            Voxels {
                size: 1.0,
                cells: vec![[0, 0, 1002]],
            },
            Voxels {
                size: 0.01,
                cells: vec![[1, 0, 0], [0, 0, 0]],
            },
            Voxels {
                size: 0.01,
                cells: vec![[0, 0, 0], [0, 0, 0]],
            },
        ];
        for v in bad {
            let err = scene.set_voxels(Some(v.clone())).expect_err("refused");
            assert!(!err.to_string().is_empty(), "{v:?}");
            assert_eq!(scene.voxels(), Some(&good), "{v:?}");
        }
        // A cloud's points a kilometre out are within reach of the check's rounding.
        let edge = Voxels::from_points(
            &[Point3::new(1000.0, -1000.0, 1000.0), Point3::origin()],
            0.005,
        )
        .expect("voxels at a kilometre");
        scene.set_voxels(Some(edge)).expect("valid");
        scene.set_voxels(None).expect("none");
        assert_eq!(scene.voxels(), None);
    }
}
