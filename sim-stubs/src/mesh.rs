//! Triangle meshes: loaded from OBJ (tobj) and STL (stl_io) files, and tessellated from the
//! scene's and the URDF's primitives for the renderer. Units m; triangles wind
//! counter-clockwise seen from outside.

use nalgebra::{Point3, Vector3};

/// Most triangles in one mesh file.
pub const MAX_TRIANGLES: usize = 1 << 20;

/// An indexed triangle mesh.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriMesh {
    /// Vertices, m.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles as vertex indices, counter-clockwise from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Axis-aligned bounds (zero for an empty mesh).
    pub fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let mut lo = Point3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
        let mut hi = -lo;
        for v in &self.vertices {
            lo = lo.inf(v);
            hi = hi.sup(v);
        }
        if self.vertices.is_empty() {
            (Point3::origin(), Point3::origin())
        } else {
            (lo, hi)
        }
    }

    /// Scale every vertex by `s` about the origin.
    pub fn scale(&mut self, s: f64) {
        for v in &mut self.vertices {
            *v *= s;
        }
    }

    /// Signed volume enclosed (positive for a closed, outward-wound surface), m³.
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize].coords);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    fn push(&mut self, p: Point3<f64>) -> u32 {
        self.vertices.push(p);
        (self.vertices.len() - 1) as u32
    }

    /// A box of full extents `s`, centred.
    pub fn cuboid(s: [f64; 3]) -> TriMesh {
        let h = Vector3::new(s[0], s[1], s[2]) / 2.0;
        let mut m = TriMesh::default();
        // Each face with its own four vertices, so faces stay flat-shaded.
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let n = Vector3::ith(axis, sign);
                let u = Vector3::ith((axis + 1) % 3, 1.0);
                let v = n.cross(&u);
                let c = n.component_mul(&h);
                let (hu, hv) = (u.component_mul(&h).norm(), v.component_mul(&h).norm());
                let base = m.vertices.len() as u32;
                for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    m.push(Point3::from(c + u * (su * hu) + v * (sv * hv)));
                }
                m.triangles.push([base, base + 1, base + 2]);
                m.triangles.push([base, base + 2, base + 3]);
            }
        }
        m
    }

    /// A cylinder of `radius` and `length` along z, centred, with `n` sides.
    pub fn cylinder(radius: f64, length: f64, n: usize) -> TriMesh {
        let n = n.max(3);
        let mut m = TriMesh::default();
        let h = length / 2.0;
        let ring = |m: &mut TriMesh, z: f64| -> u32 {
            let base = m.vertices.len() as u32;
            for k in 0..n {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                m.push(Point3::new(radius * a.cos(), radius * a.sin(), z));
            }
            base
        };
        // Sides (own vertices), then caps (own vertices) for flat caps.
        let (b0, b1) = (ring(&mut m, -h), ring(&mut m, h));
        for k in 0..n as u32 {
            let k1 = (k + 1) % n as u32;
            m.triangles.push([b0 + k, b0 + k1, b1 + k1]);
            m.triangles.push([b0 + k, b1 + k1, b1 + k]);
        }
        for (z, up) in [(-h, false), (h, true)] {
            let c = m.push(Point3::new(0.0, 0.0, z));
            let r = ring(&mut m, z);
            for k in 0..n as u32 {
                let k1 = (k + 1) % n as u32;
                if up {
                    m.triangles.push([c, r + k, r + k1]);
                } else {
                    m.triangles.push([c, r + k1, r + k]);
                }
            }
        }
        m
    }

    /// A capsule (`length` between the centres of its half-spheres, along z) of `radius`;
    /// `length = 0` gives a sphere. `n` segments around, `n / 2` from pole to pole.
    pub fn capsule(radius: f64, length: f64, n: usize) -> TriMesh {
        let n = n.max(4);
        let rings = (n / 2).max(2);
        let h = length / 2.0;
        let mut m = TriMesh::default();
        // Latitude rings from the south pole to the north pole; the equator is doubled when
        // the capsule has a straight part.
        let mut lats: Vec<(f64, f64)> = Vec::new();
        for i in 0..=rings {
            let phi = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * i as f64 / rings as f64;
            let z_off = if i * 2 < rings {
                -h
            } else if i * 2 > rings {
                h
            } else {
                lats.push((phi, -h));
                h
            };
            lats.push((phi, z_off));
        }
        let mut starts = Vec::new();
        for &(phi, z) in &lats {
            starts.push(m.vertices.len() as u32);
            for k in 0..n {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                m.push(Point3::new(
                    radius * phi.cos() * a.cos(),
                    radius * phi.cos() * a.sin(),
                    radius * phi.sin() + z,
                ));
            }
        }
        for w in starts.windows(2) {
            let (r0, r1) = (w[0], w[1]);
            for k in 0..n as u32 {
                let k1 = (k + 1) % n as u32;
                m.triangles.push([r0 + k, r0 + k1, r1 + k1]);
                m.triangles.push([r0 + k, r1 + k1, r1 + k]);
            }
        }
        // Degenerate triangles at the poles are harmless (zero area) but waste time: drop them.
        let v = &m.vertices;
        m.triangles.retain(|t| {
            let [a, b, c] = t.map(|i| v[i as usize]);
            (b - a).cross(&(c - a)).norm_squared() > 1e-24
        });
        m
    }
}

/// Parse an OBJ (`.obj`) or binary/ASCII STL (`.stl`) file's bytes; `name` picks the format.
pub fn parse(name: &str, bytes: &[u8]) -> Result<TriMesh, String> {
    let lower = name.to_ascii_lowercase();
    let mesh = if lower.ends_with(".obj") {
        parse_obj(bytes)?
    } else if lower.ends_with(".stl") {
        parse_stl(bytes)?
    } else {
        return Err("a mesh file ends in .obj or .stl".into());
    };
    if mesh.triangles.is_empty() {
        return Err("no triangles".into());
    }
    if mesh.triangles.len() > MAX_TRIANGLES {
        return Err(format!(
            "{} triangles is more than {MAX_TRIANGLES}",
            mesh.triangles.len()
        ));
    }
    if let Some(v) = mesh
        .vertices
        .iter()
        .find(|v| !v.iter().all(|c| c.is_finite()))
    {
        return Err(format!("vertex {v:?} is not finite"));
    }
    let n = mesh.vertices.len() as u32;
    if mesh.triangles.iter().flatten().any(|&i| i >= n) {
        return Err("a face names a vertex that does not exist".into());
    }
    Ok(mesh)
}

fn parse_obj(bytes: &[u8]) -> Result<TriMesh, String> {
    let mut reader = std::io::BufReader::new(bytes);
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ..Default::default()
    };
    let (models, _) =
        tobj::load_obj_buf(&mut reader, &opts, |_| Err(tobj::LoadError::OpenFileFailed))
            .map_err(|e| format!("bad OBJ: {e}"))?;
    let mut out = TriMesh::default();
    for model in models {
        let m = model.mesh;
        let base = out.vertices.len() as u32;
        if out.vertices.len() + m.positions.len() / 3 > 3 * MAX_TRIANGLES {
            return Err("too many vertices".into());
        }
        out.vertices.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))),
        );
        for t in m.indices.chunks_exact(3) {
            out.triangles.push([base + t[0], base + t[1], base + t[2]]);
        }
    }
    Ok(out)
}

fn parse_stl(bytes: &[u8]) -> Result<TriMesh, String> {
    let mut cursor = std::io::Cursor::new(bytes);
    let stl = stl_io::read_stl(&mut cursor).map_err(|e| format!("bad STL: {e}"))?;
    Ok(TriMesh {
        vertices: stl
            .vertices
            .iter()
            .map(|v| Point3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
            .collect(),
        triangles: stl
            .faces
            .iter()
            .map(|f| f.vertices.map(|i| i as u32))
            .collect(),
    })
}
