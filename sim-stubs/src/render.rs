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
    /// The renderer's scratch: the triangle each pixel shows.
    ids: Vec<u32>,
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
            ids: vec![u32::MAX; n],
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
    /// A sphere around every vertex: centre in the mesh's frame and radius, m.
    centre: Vector3<f32>,
    radius: f32,
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
    /// Index in `meshes` of the first of the robot's decals (they come last).
    first_decal: usize,
    /// Whether the decals (the hand-eye marker) are drawn.
    pub decals: bool,
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
    let (lo, hi) = m.bounds();
    let centre = ((lo.coords + hi.coords) / 2.0).cast::<f32>();
    let radius = tris
        .iter()
        .flatten()
        .map(|p| (p - centre).norm())
        .fold(0.0f32, f32::max)
        * 1.0001
        + 1e-6;
    DrawMesh {
        tris,
        normals,
        origin,
        material,
        closed,
        label,
        centre,
        radius,
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
            first_decal: usize::MAX,
            decals: false,
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
            r.first_decal = r.meshes.len();
            for (li, s) in &body.decals {
                let name = body.tree.links().nth(*li).unwrap_or_default();
                r.labels.push(format!("robot/{name}/marker"));
                let label = (r.labels.len() - 1) as u32;
                let (m, closed) = tessellate(&s.shape);
                r.materials.push(Material {
                    colour: s.colour,
                    texture: None,
                });
                let mat = (r.materials.len() - 1) as u32;
                r.meshes.push((
                    Owner::Link(*li),
                    draw_mesh(&m, closed, s.origin, mat, label),
                ));
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
        if out.width != camera.width || out.height != camera.height || out.ids.len() != w * h {
            *out = RenderedImage::new(camera.width, camera.height);
        }
        // While rasterising, the depth buffer holds 1/z (0: nothing yet); the shading pass
        // turns it into z.
        out.depth.fill(0.0);
        out.ids.fill(u32::MAX);
        let world_to_cam = camera.pose.inverse();
        let k = Intr {
            fx: camera.fx as f32,
            fy: camera.fy as f32,
            cx: camera.cx as f32,
            cy: camera.cy as f32,
            w,
            h,
        };
        let sun: Vector3<f32> = world_to_cam
            .rotation
            .to_rotation_matrix()
            .matrix()
            .cast::<f32>()
            * self.sun;
        // The side planes of the view (through the optical centre, unit normals pointing in):
        // the image's outer pixel edges, half a pixel beyond the outer pixel centres.
        let (wf, hf) = (w as f32, h as f32);
        let frustum = [
            Vector3::new(k.fx, 0.0, k.cx + 0.5),
            Vector3::new(-k.fx, 0.0, wf - 0.5 - k.cx),
            Vector3::new(0.0, k.fy, k.cy + 0.5),
            Vector3::new(0.0, -k.fy, hf - 0.5 - k.cy),
        ]
        .map(|n| n.normalize());
        // Every triangle that survives culling gets a shading record; the id buffer names the
        // nearest one per pixel (deferred shading: each pixel is shaded once).
        let mut shades: Vec<Shade> = Vec::with_capacity(self.triangles());
        let drawn = if self.decals {
            self.meshes.len()
        } else {
            self.first_decal.min(self.meshes.len())
        };
        for (owner, m) in &self.meshes[..drawn] {
            let owner_pose = match owner {
                Owner::Body(i) => bodies.get(*i),
                Owner::Link(i) => links.get(*i),
            };
            let Some(owner_pose) = owner_pose else {
                continue;
            };
            let t = world_to_cam * owner_pose * m.origin;
            let rot: Matrix3<f32> = t.rotation.to_rotation_matrix().matrix().cast::<f32>();
            let tr: Vector3<f32> = t.translation.vector.cast::<f32>();
            // Meshes wholly behind the near plane or outside the view are skipped.
            let c = rot * m.centre + tr;
            if c.z + m.radius < NEAR || frustum.iter().any(|n| n.dot(&c) < -m.radius) {
                continue;
            }
            let mat = &self.materials[m.material as usize];
            for (tri, n) in m.tris.iter().zip(&m.normals) {
                let v = tri.map(|p| rot * p + tr);
                let mut nc = rot * n;
                let facing = nc.dot(&v[0]);
                if facing >= 0.0 {
                    if m.closed {
                        continue;
                    }
                    nc = -nc;
                }
                let id = shades.len() as u32;
                if !raster_clipped(&k, &v, &mut out.depth, &mut out.ids, id) {
                    continue;
                }
                // Flat shading: ambient, sun, and a headlight along the optical axis.
                let view = -Vector3::z();
                let light = 0.35 + 0.45 * nc.dot(&sun).max(0.0) + 0.3 * nc.dot(&view).max(0.0);
                // The texture's plane: the mesh-frame axes across the dominant axis of the
                // normal, as camera-frame rows (u = a . p + a0).
                let (ia, ib) = if n.x.abs() >= n.y.abs() && n.x.abs() >= n.z.abs() {
                    (1, 2)
                } else if n.y.abs() >= n.z.abs() {
                    (0, 2)
                } else {
                    (0, 1)
                };
                let rt = rot.transpose();
                let (ra, rb): (Vector3<f32>, Vector3<f32>) =
                    (rt.row(ia).transpose(), rt.row(ib).transpose());
                let units = mat.texture.as_ref().map_or(1.0, texture_units);
                let second = match &mat.texture {
                    Some(Texture::Checker { colour, .. } | Texture::Noise { colour, .. }) => {
                        *colour
                    }
                    _ => mat.colour,
                };
                let c1 = mat.colour.map(|c| c * light * 255.0);
                shades.push(Shade {
                    rgb: mat.colour.map(|c| to_u8(c * light)),
                    light,
                    material: m.material,
                    c1,
                    dc: [0, 1, 2].map(|i| (second[i] * light * 255.0 - c1[i]) / 255.0),
                    a: (ra * units).into(),
                    a0: -ra.dot(&tr) * units,
                    b: (rb * units).into(),
                    b0: -rb.dot(&tr) * units,
                    label: m.label,
                });
            }
        }
        let bg = self.background.map(to_u8);
        let mut scratch = Scratch {
            indices: vec![0; w],
            palette_of: vec![u32::MAX; shades.len()],
            palettes: Vec::new(),
        };
        for r in 0..h {
            let row = r * w;
            let ry = (r as f32 - k.cy) / k.fy;
            let ids = &out.ids[row..row + w];
            let mut x = 0;
            while x < w {
                // One run of pixels showing the same triangle is shaded at a time.
                let id = ids[x];
                let end = run_end(ids, x);
                let span = row + x..row + end;
                let depth = &mut out.depth[span.clone()];
                let labels = &mut out.labels[span.clone()];
                let rgb = &mut out.rgb[3 * span.start..3 * span.end];
                match shades.get(id as usize) {
                    None => {
                        depth.fill(0.0);
                        labels.fill(0);
                        for p in rgb.chunks_exact_mut(3) {
                            p.copy_from_slice(&bg);
                        }
                    }
                    Some(sh) => {
                        labels.fill(sh.label);
                        // The buffer held 1/z while rasterising.
                        for d in depth.iter_mut() {
                            *d = 1.0 / *d;
                        }
                        self.shade_run(sh, id, &k, x, ry, depth, rgb, &mut scratch);
                    }
                }
                x = end;
            }
        }
    }

    /// Colour one run of pixels of one triangle, starting at column `x0` of the row at
    /// normalised height `ry`, from their depths.
    #[allow(clippy::too_many_arguments)]
    fn shade_run(
        &self,
        sh: &Shade,
        id: u32,
        k: &Intr,
        x0: usize,
        ry: f32,
        depth: &[f32],
        rgb: &mut [u8],
        scratch: &mut Scratch,
    ) {
        let mat = &self.materials[sh.material as usize];
        let Some(tex) = &mat.texture else {
            for p in rgb.chunks_exact_mut(3) {
                p.copy_from_slice(&sh.rgb);
            }
            return;
        };
        // Texture coordinates are affine in the camera-frame point p = z (rx, ry, 1) with
        // rx = (x - cx) / fx: u = z (ua x + ub) + a0, v likewise.
        let coeffs = |a: &[f32; 3]| (a[0] / k.fx, a[1] * ry + a[2] - a[0] * k.cx / k.fx);
        let ((ua, ub), (va, vb)) = (coeffs(&sh.a), coeffs(&sh.b));
        let x0 = x0 as i32;
        let uv = |i: i32, z: f32| {
            let x = (x0 + i) as f32;
            (z * (ua * x + ub) + sh.a0, z * (va * x + vb) + sh.b0)
        };
        match tex {
            Texture::Noise { .. } => {
                let t = noise_table();
                let palette = scratch.palette(id, sh);
                // First the table's indices (a loop that vectorises), then the look-ups.
                let indices = &mut scratch.indices[..depth.len()];
                let mask = NOISE_SIZE as u32 - 1;
                for (i, (ix, &z)) in (0..).zip(indices.iter_mut().zip(depth)) {
                    let (u, v) = uv(i, z);
                    *ix = (floor_bits(v) & mask) * NOISE_SIZE as u32 + (floor_bits(u) & mask);
                }
                let palette = &scratch.palettes[palette];
                for (p, &ix) in rgb.chunks_exact_mut(3).zip(indices.iter()) {
                    p.copy_from_slice(&palette[usize::from(t[ix as usize])]);
                }
            }
            Texture::Checker { .. } => {
                let (c1, c2) = (sh.c1.map(to_u8_255), (sh.c1, sh.dc));
                let c2 = [0, 1, 2].map(|c| to_u8_255(c2.0[c] + c2.1[c] * 255.0));
                for (i, (p, &z)) in (0..).zip(rgb.chunks_exact_mut(3).zip(depth)) {
                    let (u, v) = uv(i, z);
                    let odd = floor_bits(u).wrapping_add(floor_bits(v)) & 1 != 0;
                    p.copy_from_slice(if odd { &c2 } else { &c1 });
                }
            }
            _ => {
                for (i, (p, &z)) in (0..).zip(rgb.chunks_exact_mut(3).zip(depth)) {
                    let (u, v) = uv(i, z);
                    let c = texture_colour(tex, mat.colour, u, v);
                    for ch in 0..3 {
                        p[ch] = to_u8(c[ch] * sh.light);
                    }
                }
            }
        }
    }
}

/// Where the run of equal ids starting at `x` ends (exclusive).
fn run_end(ids: &[u32], x: usize) -> usize {
    let id = ids[x];
    let mut end = x + 1;
    // Eight at a time first (a comparison that vectorises).
    while let Some(chunk) = ids.get(end..end + 8) {
        if !chunk.iter().fold(true, |same, &i| same & (i == id)) {
            break;
        }
        end += 8;
    }
    while end < ids.len() && ids[end] == id {
        end += 1;
    }
    end
}

/// The shading pass's scratch: a row of noise-table indices, and the noise texture's colours
/// per shading record, made when the record is first shaded.
struct Scratch {
    indices: Vec<u32>,
    /// Index into `palettes` per shading record (`u32::MAX`: none yet).
    palette_of: Vec<u32>,
    /// Entry n: the colour at the noise table's value n.
    palettes: Vec<[[u8; 3]; 256]>,
}

impl Scratch {
    /// The palette of shading record `id`, made now if it has none yet.
    fn palette(&mut self, id: u32, sh: &Shade) -> usize {
        let slot = &mut self.palette_of[id as usize];
        if *slot == u32::MAX {
            *slot = self.palettes.len() as u32;
            self.palettes.push(std::array::from_fn(|n| {
                [0, 1, 2].map(|c| to_u8_255(sh.c1[c] + sh.dc[c] * n as f32))
            }));
        }
        *slot as usize
    }
}

/// floor(x) in the low bits (two's complement) for |x| < 2^21: x - 1/2 rounded to an integer
/// by adding 1.5 * 2^23, which leaves no fraction bits (ties, at integers, may go either way).
fn floor_bits(x: f32) -> u32 {
    const MAGIC: f32 = 12_582_912.0;
    (x - 0.5 + MAGIC).to_bits()
}

/// A colour channel 0-255 as 8 bits.
fn to_u8_255(x: f32) -> u8 {
    (x.clamp(0.0, 255.0) + 0.5) as u8
}

/// A colour channel 0-1 as 8 bits.
fn to_u8(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// How one drawn triangle is shaded.
struct Shade {
    /// Lit colour without texture.
    rgb: [u8; 3],
    /// Light factor.
    light: f32,
    material: u32,
    /// The lit colour, 0-255 per channel, and the step towards the texture's second colour
    /// per step of the noise table ((second - first) / 255).
    c1: [f32; 3],
    dc: [f32; 3],
    /// Texture coordinates in the texture's units (see [`texture_units`]): u = a . p + a0,
    /// v = b . p + b0 for a camera-frame point p.
    a: [f32; 3],
    a0: f32,
    b: [f32; 3],
    b0: f32,
    label: u32,
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

/// Clip a camera-frame triangle at the near plane and rasterise the pieces; true if any
/// pixel was written.
fn raster_clipped(
    k: &Intr,
    v: &[Vector3<f32>; 3],
    inv_depth: &mut [f32],
    ids: &mut [u32],
    id: u32,
) -> bool {
    let inside = v.map(|p| p.z >= NEAR);
    if inside.iter().all(|&i| i) {
        return raster(k, v, inv_depth, ids, id);
    }
    if !inside.iter().any(|&i| i) {
        return false;
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
            // From the nearer end, so that the triangle on the other side of a shared edge
            // (which runs it the other way) gets the same point.
            let (p0, p1) = if a.z < b.z { (a, b) } else { (b, a) };
            let t = (NEAR - p0.z) / (p1.z - p0.z);
            let mut p = p0 + (p1 - p0) * t;
            p.z = NEAR;
            poly[n] = p;
            n += 1;
        }
    }
    let first = raster(k, &[poly[0], poly[1], poly[2]], inv_depth, ids, id);
    let second = n == 4 && raster(k, &[poly[0], poly[2], poly[3]], inv_depth, ids, id);
    first || second
}

/// Rasterise a triangle in front of the near plane: every pixel centre inside it (top-left
/// fill rule) nearer than the buffer of 1/z gets its 1/z and `id`; true if any did.
///
/// Edge functions and 1/z are affine in the pixel coordinates. Each row's span is solved from
/// the edge functions; an edge shared by two triangles gets the same (negated) coefficients
/// in both, so the fill rule leaves no crack and no overlap along it.
fn raster(
    k: &Intr,
    v: &[Vector3<f32>; 3],
    inv_depth: &mut [f32],
    ids: &mut [u32],
    id: u32,
) -> bool {
    let s = v.map(|p| {
        let iz = 1.0 / p.z;
        (k.fx * p.x * iz + k.cx, k.fy * p.y * iz + k.cy, iz)
    });
    let area = (s[1].0 - s[0].0) * (s[2].1 - s[0].1) - (s[1].1 - s[0].1) * (s[2].0 - s[0].0);
    if !area.is_finite() || area.abs() < 1e-12 {
        return false;
    }
    let (a, b, c) = if area > 0.0 {
        (s[0], s[1], s[2])
    } else {
        (s[0], s[2], s[1])
    };
    let xmin = a.0.min(b.0).min(c.0).ceil().max(0.0);
    let xmax = a.0.max(b.0).max(c.0).floor().min(k.w as f32 - 1.0);
    let ymin = a.1.min(b.1).min(c.1).ceil().max(0.0);
    let ymax = a.1.max(b.1).max(c.1).floor().min(k.h as f32 - 1.0);
    if xmin > xmax || ymin > ymax {
        return false;
    }
    // Edge from q0 to q1: e(x, y) = dx (y - y0) - dy (x - x0) = ex x + ey y + e0, positive
    // inside; on an edge a pixel belongs to the triangle only for top or left edges. The
    // coefficients are computed from the edge's lower endpoint (in (y, x) order), so the two
    // triangles sharing an edge get exactly opposite ones.
    let edge = |q0: (f32, f32, f32), q1: (f32, f32, f32)| {
        let (dx, dy) = (q1.0 - q0.0, q1.1 - q0.1);
        let top_left = (dy == 0.0 && dx < 0.0) || dy > 0.0;
        let e0 = if (q0.1, q0.0) <= (q1.1, q1.0) {
            dy * q0.0 - dx * q0.1
        } else {
            -((-dy) * q1.0 - (-dx) * q1.1)
        };
        (-dy, dx, e0, top_left)
    };
    let es = [edge(b, c), edge(c, a), edge(a, b)];
    // 1/z = (e_bc a.iz + e_ca b.iz + e_ab c.iz) / area, affine too.
    let inv = 1.0 / area.abs();
    let zx = (es[0].0 * a.2 + es[1].0 * b.2 + es[2].0 * c.2) * inv;
    let zy = (es[0].1 * a.2 + es[1].1 * b.2 + es[2].1 * c.2) * inv;
    let z0 = (es[0].2 * a.2 + es[1].2 * b.2 + es[2].2 * c.2) * inv;
    let (ymin, ymax) = (ymin as usize, ymax as usize);
    let mut any = false;
    for y in ymin..=ymax {
        let fy = y as f32;
        // The row's span: each edge bounds x from one side (e = ex x + c >= 0).
        let (mut lo, mut hi) = (xmin as i64, xmax as i64);
        for &(ex, ey, e0, tl) in &es {
            let c = ey * fy + e0;
            if ex > 0.0 {
                // Clamped far beyond any image, so that the integer steps cannot overflow.
                let t = (-c / ex).clamp(-1e9, 1e9);
                let xs = if tl { ceil_i64(t) } else { floor_i64(t) + 1 };
                lo = lo.max(xs);
            } else if ex < 0.0 {
                let t = (-c / ex).clamp(-1e9, 1e9);
                let xe = if tl { floor_i64(t) } else { ceil_i64(t) - 1 };
                hi = hi.min(xe);
            } else if c < 0.0 || (c == 0.0 && !tl) {
                hi = lo - 1;
            }
        }
        if lo > hi {
            continue;
        }
        let (lo, hi) = (lo as usize, hi as usize);
        let row = y * k.w;
        let iz0 = zx * lo as f32 + zy * fy + z0;
        let zs = &mut inv_depth[row + lo..=row + hi];
        let is = &mut ids[row + lo..=row + hi];
        let mut wrote = 0u32;
        // Branch-free, so that it vectorises: 1/z at the span's i-th pixel from its start; the
        // id and 1/z go in through a mask (a select would be turned back into a branch).
        for (i, (zb, ib)) in (0i32..).zip(zs.iter_mut().zip(is.iter_mut())) {
            let iz = iz0 + zx * i as f32;
            let mask = 0u32.wrapping_sub(u32::from(iz > *zb));
            *zb = f32::from_bits(zb.to_bits() ^ ((zb.to_bits() ^ iz.to_bits()) & mask));
            *ib ^= (*ib ^ id) & mask;
            wrote |= mask;
        }
        let wrote = wrote != 0;
        any |= wrote;
    }
    any
}

/// floor(t) without a libm call (saturating beyond the i64 range, 0 for NaN).
fn floor_i64(t: f32) -> i64 {
    let i = t as i64;
    i - i64::from((i as f32) > t)
}

/// ceil(t) without a libm call (saturating beyond the i64 range, 0 for NaN).
fn ceil_i64(t: f32) -> i64 {
    let i = t as i64;
    i + i64::from((i as f32) < t)
}

/// A cheap integer hash to [0, 1).
fn hash2(x: i32, y: i32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343) ^ (y as u32).wrapping_mul(0xd816_3841);
    h ^= h >> 13;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    (h & 0xff_ffff) as f32 / 16_777_216.0
}

/// Texels per noise cell of the baked noise table.
const NOISE_TEXELS: usize = 8;
/// Side of the baked noise table, texels (a power of two): it repeats every
/// `NOISE_SIZE / NOISE_TEXELS` = 128 cells, far beyond what one view shows.
const NOISE_SIZE: usize = 1024;

/// Two octaves of value noise, tileable, baked once (a lookup per pixel instead of eight
/// hashes).
fn noise_table() -> &'static [u8] {
    static TABLE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let cells = (NOISE_SIZE / NOISE_TEXELS) as i32;
        let mut t = vec![0u8; NOISE_SIZE * NOISE_SIZE];
        for y in 0..NOISE_SIZE {
            for x in 0..NOISE_SIZE {
                let (u, v) = (
                    x as f32 / NOISE_TEXELS as f32,
                    y as f32 / NOISE_TEXELS as f32,
                );
                let n = 0.6 * value_noise(u, v, cells) + 0.4 * value_noise(u * 4.0, v * 4.0, cells);
                t[y * NOISE_SIZE + x] = (n * 255.0) as u8;
            }
        }
        t
    })
}

/// Smooth value noise in [0, 1), repeating every `period` cells.
fn value_noise(x: f32, y: f32, period: i32) -> f32 {
    let (xi, yi) = (floor_i(x), floor_i(y));
    let (fx, fy) = (x - xi as f32, y - yi as f32);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let h = |i: i32, j: i32| hash2(i.rem_euclid(period), j.rem_euclid(period));
    let a = h(xi, yi);
    let b = h(xi + 1, yi);
    let c = h(xi, yi + 1);
    let d = h(xi + 1, yi + 1);
    let top = a + (b - a) * sx;
    let bottom = c + (d - c) * sx;
    top + (bottom - top) * sy
}

fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * t)
}

/// floor(x) for |x| < 2^31 without a libm call.
fn floor_i(x: f32) -> i32 {
    let i = x as i32;
    i - i32::from((i as f32) > x)
}

/// x mod 1 in [0, 1).
fn fract(x: f32) -> f32 {
    x - floor_i(x) as f32
}

/// Texture coordinates per metre on the surface: one unit is a checker square, a tile, an
/// image's width or a texel of the noise table.
fn texture_units(t: &Texture) -> f32 {
    match t {
        Texture::Checker { scale, .. }
        | Texture::Tiles { scale, .. }
        | Texture::Image { scale, .. } => 1.0 / *scale as f32,
        Texture::Noise { scale, .. } => NOISE_TEXELS as f32 / *scale as f32,
    }
}

/// A texture's colour at planar coordinates (u, v) of the body's frame in the texture's
/// units ([`texture_units`]): the two axes across the dominant axis of the surface's normal.
fn texture_colour(t: &Texture, colour: [f32; 3], u: f32, v: f32) -> [f32; 3] {
    match t {
        Texture::Checker { colour: c2, .. } => {
            let parity = (floor_i(u).wrapping_add(floor_i(v))) & 1;
            if parity == 0 {
                colour
            } else {
                *c2
            }
        }
        Texture::Noise { colour: c2, .. } => {
            let t = noise_table();
            let x = (floor_i(u) as usize) & (NOISE_SIZE - 1);
            let y = (floor_i(v) as usize) & (NOISE_SIZE - 1);
            mix(colour, *c2, f32::from(t[y * NOISE_SIZE + x]) / 255.0)
        }
        Texture::Tiles { colour: c2, .. } => {
            let (fu, fv) = (fract(u), fract(v));
            if fu < 0.04 || fv < 0.04 {
                *c2
            } else {
                // Each tile a slightly different shade, so tiles are told apart.
                let shade = 0.9 + 0.2 * hash2(floor_i(u), floor_i(v));
                colour.map(|c| c * shade)
            }
        }
        Texture::Image {
            width,
            height,
            pixels,
            ..
        } => {
            let (fu, fv) = (fract(u), fract(v));
            let x = ((fu * *width as f32) as usize).min(*width as usize - 1);
            let y = (((1.0 - fv) * *height as f32) as usize).min(*height as usize - 1);
            let p = pixels[y * *width as usize + x];
            [0, 1, 2].map(|i| p[i] * colour[i])
        }
    }
}
