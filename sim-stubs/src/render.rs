//! The camera's renderer: a deterministic CPU rasteriser of the scene's bodies and the
//! robot's links into a colour image and a depth image aligned to it.
//!
//! Why our own and not a GPU or a ray tracer: it must run on any CI machine without a GPU,
//! bit-identically, at hundreds of frames per second on one core; a scanline z-buffer over a
//! few thousand triangles does that, and its depth is exact (1/z interpolated per pixel, so a
//! plane renders at its true distance to within f32 rounding).
//!
//! Conventions: the camera is a pinhole with intrinsics `fx, fy, cx, cy` (px) in the optical
//! frame (x right, y down, z forward); pixel (row r, column c) samples the ray through
//! `K⁻¹ [c, r, 1]`, so a point projects to column `fx x / z + cx` and row `fy y / z + cy`.
//! Depth is z in the optical frame (m), 0 where nothing was hit. Shading is flat per
//! triangle: ambient, a sun from above and a weak headlight, times the surface's colour or
//! texture (procedural patterns or an image, in the body's own frame so textures move with
//! the body).

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::body::RobotBody;
use crate::mesh::TriMesh;
use crate::scene::{Body, Scene, Shape, Texture};

/// Segments around a tessellated cylinder, sphere or capsule.
pub const ROUND_SEGMENTS: usize = 24;
/// Nearest distance drawn, m (triangles are clipped there).
pub const NEAR: f32 = 0.01;

/// A pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeCamera {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Focal length x, px.
    pub fx: f64,
    /// Focal length y, px.
    pub fy: f64,
    /// Principal point x (column), px.
    pub cx: f64,
    /// Principal point y (row), px.
    pub cy: f64,
    /// Pose of the optical frame (x right, y down, z forward) in the world.
    pub pose: Isometry3<f64>,
}

impl PinholeCamera {
    /// Where a world point projects, `(column, row)` in px, if it is in front of the camera.
    pub fn project(&self, p: &Point3<f64>) -> Option<(f64, f64)> {
        let c = self.pose.inverse_transform_point(p);
        (c.z > 0.0).then(|| (self.fx * c.x / c.z + self.cx, self.fy * c.y / c.z + self.cy))
    }
}

/// A rendered colour and depth image pair.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderedImage {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Row-major RGB, 8 bit.
    pub rgb: Vec<u8>,
    /// Row-major depth (z in the optical frame), m; 0 where nothing was hit.
    pub depth: Vec<f32>,
    /// Which body or link each pixel shows (see [`Renderer::label_name`]); 0 for nothing.
    pub labels: Vec<u32>,
}

impl RenderedImage {
    /// An image of `width` × `height` px with nothing in it.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        RenderedImage {
            width,
            height,
            rgb: vec![0; 3 * n],
            depth: vec![0.0; n],
            labels: vec![0; n],
        }
    }
}

/// A surface's appearance.
#[derive(Debug, Clone, PartialEq)]
struct Material {
    colour: [f32; 3],
    texture: Option<Texture>,
}

/// A mesh ready to draw: its triangles' vertices and outward normals in the owner's frame.
#[derive(Debug, Clone)]
struct DrawMesh {
    /// Vertices of each triangle, m.
    tris: Vec<[Vector3<f32>; 3]>,
    /// Unit outward normal of each triangle.
    normals: Vec<Vector3<f32>>,
    /// Pose of the mesh in its owner's frame (link shapes' origins; identity for bodies).
    origin: Isometry3<f64>,
    material: u32,
    /// Closed and outward-wound: back faces can be skipped.
    closed: bool,
    label: u32,
}

/// Where a mesh sits: a scene body or a robot link.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Owner {
    Body(usize),
    Link(usize),
}

/// The renderer of one scene with one robot body.
#[derive(Debug, Clone)]
pub struct Renderer {
    meshes: Vec<(Owner, DrawMesh)>,
    materials: Vec<Material>,
    labels: Vec<String>,
    /// Direction towards the sun (world frame, unit).
    sun: Vector3<f32>,
    /// Colour where nothing is hit (the sky), 0-1.
    pub background: [f32; 3],
}

fn tessellate(shape: &Shape) -> (TriMesh, bool) {
    match shape {
        Shape::Box(s) => (TriMesh::cuboid(*s), true),
        Shape::Cylinder { radius, length } => {
            (TriMesh::cylinder(*radius, *length, ROUND_SEGMENTS), true)
        }
        Shape::Sphere(r) => (TriMesh::capsule(*r, 0.0, ROUND_SEGMENTS), true),
        Shape::Capsule { radius, length } => {
            (TriMesh::capsule(*radius, *length, ROUND_SEGMENTS), true)
        }
        // A file's winding is not trusted: both faces are drawn.
        Shape::Mesh { mesh, .. } => (mesh.clone(), false),
    }
}

fn draw_mesh(
    m: &TriMesh,
    closed: bool,
    origin: Isometry3<f64>,
    material: u32,
    label: u32,
) -> DrawMesh {
    let mut tris = Vec::with_capacity(m.triangles.len());
    let mut normals = Vec::with_capacity(m.triangles.len());
    for t in &m.triangles {
        let [a, b, c] = t.map(|i| m.vertices[i as usize].coords.cast::<f32>());
        let n = (b - a).cross(&(c - a));
        let Some(n) = n.try_normalize(1e-20) else {
            continue;
        };
        tris.push([a, b, c]);
        normals.push(n);
    }
    DrawMesh {
        tris,
        normals,
        origin,
        material,
        closed,
        label,
    }
}

impl Renderer {
    /// A renderer of `scene`'s bodies and `body`'s links.
    pub fn new(scene: &Scene, body: Option<&RobotBody>) -> Self {
        let mut r = Renderer {
            meshes: Vec::new(),
            materials: Vec::new(),
            labels: vec![String::new()],
            sun: Vector3::new(0.35f32, 0.25, 0.9).normalize(),
            background: [0.75, 0.8, 0.85],
        };
        for (i, b) in scene.bodies.iter().enumerate() {
            r.add_body(i, b);
        }
        if let Some(body) = body {
            for (li, (name, shapes)) in body.tree.links().zip(&body.shapes).enumerate() {
                if shapes.is_empty() {
                    continue;
                }
                r.labels.push(format!("robot/{name}"));
                let label = (r.labels.len() - 1) as u32;
                for s in shapes {
                    let (m, closed) = tessellate(&s.shape);
                    r.materials.push(Material {
                        colour: s.colour,
                        texture: None,
                    });
                    let mat = (r.materials.len() - 1) as u32;
                    r.meshes
                        .push((Owner::Link(li), draw_mesh(&m, closed, s.origin, mat, label)));
                }
            }
        }
        r
    }

    fn add_body(&mut self, i: usize, b: &Body) {
        let (m, closed) = tessellate(&b.shape);
        self.materials.push(Material {
            colour: b.colour,
            texture: b.texture.clone(),
        });
        self.labels.push(b.id.clone());
        let mat = (self.materials.len() - 1) as u32;
        let label = (self.labels.len() - 1) as u32;
        self.meshes.push((
            Owner::Body(i),
            draw_mesh(&m, closed, Isometry3::identity(), mat, label),
        ));
    }

    /// What a label of [`RenderedImage::labels`] shows: a scene body's id, `robot/LINK` for
    /// a robot link, `""` for nothing.
    pub fn label_name(&self, label: u32) -> Option<&str> {
        self.labels.get(label as usize).map(String::as_str)
    }

    /// Triangles drawn per frame (before culling).
    pub fn triangles(&self) -> usize {
        self.meshes.iter().map(|(_, m)| m.tris.len()).sum()
    }

    /// Render the world seen by `camera`, the scene's bodies at `bodies` (world poses, scene
    /// order) and the robot's links at `links` (world poses, link-tree order), into `out`
    /// (resized to the camera's image).
    pub fn render(
        &self,
        camera: &PinholeCamera,
        bodies: &[Isometry3<f64>],
        links: &[Isometry3<f64>],
        out: &mut RenderedImage,
    ) {
        let (w, h) = (camera.width as usize, camera.height as usize);
        if out.width != camera.width || out.height != camera.height {
            *out = RenderedImage::new(camera.width, camera.height);
        }
        out.depth.fill(f32::INFINITY);
        out.labels.fill(0);
        // Per pixel: which mesh and triangle is nearest (deferred shading).
        let mut tri_of = vec![u32::MAX; w * h];
        let mut mesh_of = vec![u32::MAX; w * h];
        let world_to_cam = camera.pose.inverse();
        let k = Intr {
            fx: camera.fx as f32,
            fy: camera.fy as f32,
            cx: camera.cx as f32,
            cy: camera.cy as f32,
            w,
            h,
        };
        let mut to_cam = Vec::with_capacity(self.meshes.len());
        for (mi, (owner, m)) in self.meshes.iter().enumerate() {
            let owner_pose = match owner {
                Owner::Body(i) => bodies.get(*i),
                Owner::Link(i) => links.get(*i),
            };
            let Some(owner_pose) = owner_pose else {
                to_cam.push(None);
                continue;
            };
            let t = world_to_cam * owner_pose * m.origin;
            let rot: Matrix3<f32> = t.rotation.to_rotation_matrix().matrix().cast::<f32>();
            let tr: Vector3<f32> = t.translation.vector.cast::<f32>();
            to_cam.push(Some((rot, tr)));
            for (ti, (tri, n)) in m.tris.iter().zip(&m.normals).enumerate() {
                let v = tri.map(|p| rot * p + tr);
                let nc = rot * n;
                if m.closed && nc.dot(&v[0]) >= 0.0 {
                    continue;
                }
                raster_clipped(&k, &v, &mut out.depth, |px| {
                    tri_of[px] = ti as u32;
                    mesh_of[px] = mi as u32;
                });
            }
        }
        // Shade.
        let sun_cam: Vector3<f32> = (world_to_cam
            .rotation
            .to_rotation_matrix()
            .matrix()
            .cast::<f32>())
            * self.sun;
        let bg = self.background.map(|c| (c * 255.0).round() as u8);
        for px in 0..w * h {
            let mi = mesh_of[px];
            if mi == u32::MAX {
                out.depth[px] = 0.0;
                out.rgb[3 * px..3 * px + 3].copy_from_slice(&bg);
                continue;
            }
            let (_, m) = &self.meshes[mi as usize];
            let Some((rot, tr)) = &to_cam[mi as usize] else {
                continue;
            };
            let n = rot * m.normals[tri_of[px] as usize];
            let z = out.depth[px];
            let (r, c) = ((px / w) as f32, (px % w) as f32);
            let p_cam = Vector3::new((c - k.cx) / k.fx * z, (r - k.cy) / k.fy * z, z);
            // Two-sided surfaces face the camera.
            let n = if n.dot(&p_cam) > 0.0 { -n } else { n };
            let view = -p_cam.normalize();
            let light = 0.3 + 0.5 * n.dot(&sun_cam).max(0.0) + 0.25 * n.dot(&view).max(0.0);
            let mat = &self.materials[m.material as usize];
            let base = match &mat.texture {
                None => mat.colour,
                Some(t) => {
                    // The point and normal in the mesh's own frame pick the texture.
                    let local = rot.transpose() * (p_cam - tr);
                    let nl = rot.transpose() * n;
                    texture_colour(t, mat.colour, &local, &nl)
                }
            };
            for (o, b) in out.rgb[3 * px..3 * px + 3].iter_mut().zip(base) {
                *o = ((b * light).clamp(0.0, 1.0) * 255.0).round() as u8;
            }
            out.labels[px] = m.label;
        }
    }
}

/// Intrinsics in f32 for the inner loop.
struct Intr {
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    w: usize,
    h: usize,
}

/// Clip a camera-frame triangle at the near plane and rasterise the pieces.
fn raster_clipped(k: &Intr, v: &[Vector3<f32>; 3], depth: &mut [f32], mut hit: impl FnMut(usize)) {
    let inside = v.map(|p| p.z >= NEAR);
    if inside.iter().all(|&i| i) {
        raster(k, v, depth, &mut hit);
        return;
    }
    if !inside.iter().any(|&i| i) {
        return;
    }
    // Sutherland-Hodgman against z = NEAR: at most a quad.
    let mut poly: [Vector3<f32>; 4] = [Vector3::zeros(); 4];
    let mut n = 0;
    for i in 0..3 {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        let (ia, ib) = (a.z >= NEAR, b.z >= NEAR);
        if ia {
            poly[n] = a;
            n += 1;
        }
        if ia != ib {
            let t = (NEAR - a.z) / (b.z - a.z);
            let mut p = a + (b - a) * t;
            p.z = NEAR;
            poly[n] = p;
            n += 1;
        }
    }
    raster(k, &[poly[0], poly[1], poly[2]], depth, &mut hit);
    if n == 4 {
        raster(k, &[poly[0], poly[2], poly[3]], depth, &mut hit);
    }
}

/// Rasterise a triangle in front of the near plane: every pixel centre inside it (top-left
/// fill rule) whose depth is nearer than the buffer's is written and reported to `hit`.
fn raster(k: &Intr, v: &[Vector3<f32>; 3], depth: &mut [f32], hit: &mut impl FnMut(usize)) {
    // Screen coordinates (column, row) and 1/z.
    let s = v.map(|p| {
        let iz = 1.0 / p.z;
        (k.fx * p.x * iz + k.cx, k.fy * p.y * iz + k.cy, iz)
    });
    let area = (s[1].0 - s[0].0) * (s[2].1 - s[0].1) - (s[1].1 - s[0].1) * (s[2].0 - s[0].0);
    if !area.is_finite() || area.abs() < 1e-12 {
        return;
    }
    // Counter-clockwise in screen space (rows down) after this swap.
    let (a, b, c) = if area > 0.0 {
        (s[0], s[1], s[2])
    } else {
        (s[0], s[2], s[1])
    };
    let area = area.abs();
    let xmin = a.0.min(b.0).min(c.0).ceil().max(0.0);
    let xmax = a.0.max(b.0).max(c.0).floor().min(k.w as f32 - 1.0);
    let ymin = a.1.min(b.1).min(c.1).ceil().max(0.0);
    let ymax = a.1.max(b.1).max(c.1).floor().min(k.h as f32 - 1.0);
    if xmin > xmax || ymin > ymax {
        return;
    }
    // Edge functions e(p) = (q1 - q0) x (p - q0), positive inside; top-left rule for ties.
    let edge = |q0: (f32, f32, f32), q1: (f32, f32, f32)| {
        let (dx, dy) = (q1.0 - q0.0, q1.1 - q0.1);
        let top_left = (dy == 0.0 && dx < 0.0) || dy > 0.0;
        (dx, dy, q0.0, q0.1, top_left)
    };
    let es = [edge(b, c), edge(c, a), edge(a, b)];
    let inv_area = 1.0 / area;
    let (xmin, xmax, ymin, ymax) = (xmin as usize, xmax as usize, ymin as usize, ymax as usize);
    for y in ymin..=ymax {
        let py = y as f32;
        let row = y * k.w;
        for x in xmin..=xmax {
            let px = x as f32;
            let mut wts = [0.0f32; 3];
            let mut inside = true;
            for (wt, &(dx, dy, x0, y0, tl)) in wts.iter_mut().zip(&es) {
                let e = dx * (py - y0) - dy * (px - x0);
                if e < 0.0 || (e == 0.0 && !tl) {
                    inside = false;
                    break;
                }
                *wt = e;
            }
            if !inside {
                continue;
            }
            let iz = (wts[0] * a.2 + wts[1] * b.2 + wts[2] * c.2) * inv_area;
            if iz <= 0.0 {
                continue;
            }
            let z = 1.0 / iz;
            let i = row + x;
            if z < depth[i] {
                depth[i] = z;
                hit(i);
            }
        }
    }
}

/// A cheap integer hash to [0, 1).
fn hash2(x: i32, y: i32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343) ^ (y as u32).wrapping_mul(0xd816_3841);
    h ^= h >> 13;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    (h & 0xff_ffff) as f32 / 16_777_216.0
}

/// Smooth value noise in [0, 1).
fn value_noise(x: f32, y: f32) -> f32 {
    let (xi, yi) = (x.floor(), y.floor());
    let (fx, fy) = (x - xi, y - yi);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let (xi, yi) = (xi as i32, yi as i32);
    let a = hash2(xi, yi);
    let b = hash2(xi.wrapping_add(1), yi);
    let c = hash2(xi, yi.wrapping_add(1));
    let d = hash2(xi.wrapping_add(1), yi.wrapping_add(1));
    let top = a + (b - a) * sx;
    let bottom = c + (d - c) * sx;
    top + (bottom - top) * sy
}

fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * t)
}

/// A texture's colour at `p` on a surface with normal `n` (both in the body's frame):
/// planar projection along the normal's dominant axis.
fn texture_colour(t: &Texture, colour: [f32; 3], p: &Vector3<f32>, n: &Vector3<f32>) -> [f32; 3] {
    let (u, v) = if n.x.abs() >= n.y.abs() && n.x.abs() >= n.z.abs() {
        (p.y, p.z)
    } else if n.y.abs() >= n.z.abs() {
        (p.x, p.z)
    } else {
        (p.x, p.y)
    };
    match t {
        Texture::Checker { scale, colour: c2 } => {
            let s = *scale as f32;
            let parity = ((u / s).floor() as i64 + (v / s).floor() as i64).rem_euclid(2);
            if parity == 0 {
                colour
            } else {
                *c2
            }
        }
        Texture::Noise { scale, colour: c2 } => {
            let s = *scale as f32;
            let n = 0.6 * value_noise(u / s, v / s)
                + 0.4 * value_noise(u / s * 3.7 + 17.0, v / s * 3.7 - 5.0);
            mix(colour, *c2, n)
        }
        Texture::Tiles { scale, colour: c2 } => {
            let s = *scale as f32;
            let (fu, fv) = ((u / s).rem_euclid(1.0), (v / s).rem_euclid(1.0));
            if fu < 0.04 || fv < 0.04 {
                *c2
            } else {
                // Each tile a slightly different shade, so tiles are told apart.
                let shade = 0.9 + 0.2 * hash2((u / s).floor() as i32, (v / s).floor() as i32);
                colour.map(|c| c * shade)
            }
        }
        Texture::Image {
            scale,
            width,
            height,
            pixels,
            ..
        } => {
            let s = *scale as f32;
            let (fu, fv) = ((u / s).rem_euclid(1.0), (v / s).rem_euclid(1.0));
            let x = ((fu * *width as f32) as usize).min(*width as usize - 1);
            let y = (((1.0 - fv) * *height as f32) as usize).min(*height as usize - 1);
            let p = pixels[y * *width as usize + x];
            [0, 1, 2].map(|i| p[i] * colour[i])
        }
    }
}
