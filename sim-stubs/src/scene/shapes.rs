//! An object's shape and orientation as the scene gives them: primitives by their sizes, meshes
//! read from their files and scaled, rotations from roll-pitch-yaw or a quaternion.

use nalgebra::UnitQuaternion;

use super::file::ObjectFile;
use super::{Ctx, Result, Shape, MAX_EXTENT, MAX_MESH_BYTES};
use crate::mesh;

impl Ctx<'_> {
    pub(super) fn rotation(&self, key: &str, o: &ObjectFile) -> Result<UnitQuaternion<f64>> {
        match (o.rpy, o.quaternion) {
            (Some(_), Some(_)) => Err(self.err(key, "give `rpy` or `quaternion`, not both")),
            (Some(r), None) => {
                for v in r {
                    self.finite(&format!("{key}.rpy"), v, -100.0, 100.0)?;
                }
                Ok(UnitQuaternion::from_euler_angles(r[0], r[1], r[2]))
            }
            (None, Some(q)) => {
                for v in q {
                    self.finite(&format!("{key}.quaternion"), v, -1.0, 1.0)?;
                }
                let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                if (n - 1.0).abs() > 1e-3 {
                    return Err(self.err(
                        format!("{key}.quaternion"),
                        format!("norm {n} is not 1 (within 0.001)"),
                    ));
                }
                Ok(UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                    q[3], q[0], q[1], q[2],
                )))
            }
            (None, None) => Ok(UnitQuaternion::identity()),
        }
    }

    pub(super) fn shape(&self, key: &str, o: &ObjectFile) -> Result<Shape> {
        let size = |n: usize, what: &str| -> Result<Vec<f64>> {
            let s = o.size.as_ref().ok_or_else(|| {
                self.err(
                    format!("{key}.size"),
                    format!("a {} needs `size` ({what})", o.shape),
                )
            })?;
            if s.len() != n {
                return Err(self.err(
                    format!("{key}.size"),
                    format!("a {} takes {n} numbers ({what}), not {}", o.shape, s.len()),
                ));
            }
            s.iter()
                .map(|&v| self.positive(&format!("{key}.size"), v))
                .collect()
        };
        if o.shape != "mesh" && o.mesh.is_some() {
            return Err(self.err(
                format!("{key}.mesh"),
                "only a `mesh` shape takes a mesh file",
            ));
        }
        if o.shape != "mesh" && o.scale != 1.0 {
            return Err(self.err(format!("{key}.scale"), "only a `mesh` shape takes a scale"));
        }
        Ok(match o.shape.as_str() {
            "box" => {
                let s = size(3, "full extents x, y, z")?;
                Shape::Box([s[0], s[1], s[2]])
            }
            "cylinder" => {
                let s = size(2, "radius, length")?;
                Shape::Cylinder {
                    radius: s[0],
                    length: s[1],
                }
            }
            "capsule" => {
                let s = size(2, "radius, length")?;
                Shape::Capsule {
                    radius: s[0],
                    length: s[1],
                }
            }
            "sphere" => Shape::Sphere(size(1, "radius")?[0]),
            "mesh" => self.mesh_shape(key, o)?,
            other => {
                return Err(self.err(
                    format!("{key}.shape"),
                    format!("unknown shape {other:?} (box, cylinder, sphere, capsule, mesh)"),
                ))
            }
        })
    }

    /// A `mesh` object's shape: its file read, parsed and scaled, its extent checked.
    fn mesh_shape(&self, key: &str, o: &ObjectFile) -> Result<Shape> {
        if o.size.is_some() {
            return Err(self.err(
                format!("{key}.size"),
                "a mesh takes its size from its file (use `scale`)",
            ));
        }
        let path = o.mesh.as_ref().ok_or_else(|| {
            self.err(
                format!("{key}.mesh"),
                "a mesh needs `mesh` (an OBJ or STL file)",
            )
        })?;
        let scale = self.positive(&format!("{key}.scale"), o.scale)?;
        let bytes =
            (self.read)(path, MAX_MESH_BYTES).map_err(|e| self.err(format!("{key}.mesh"), e))?;
        let mut m = mesh::parse(path, &bytes)
            .map_err(|e| self.err(format!("{key}.mesh"), format!("{path}: {e}")))?;
        m.scale(scale);
        let (lo, hi) = m.bounds();
        let ext = (hi - lo).amax();
        if !(ext > 1e-4 && ext <= MAX_EXTENT) {
            return Err(self.err(
                format!("{key}.mesh"),
                format!("{path}: extent {ext} m is not in (0.0001, {MAX_EXTENT}]"),
            ));
        }
        Ok(Shape::Mesh {
            path: path.clone(),
            mesh: m,
        })
    }
}
