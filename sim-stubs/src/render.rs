//! The camera's renderer: a deterministic CPU rasteriser of the scene's bodies and the
//! robot's links into a colour image, a depth image aligned to it and a label image.
//! The camera is a pinhole with intrinsics `fx, fy, cx, cy` (px) in the optical frame (x
//! right, y down, z forward); pixel (row r, column c) samples the ray through `K⁻¹ [c, r, 1]`,
//! so a point projects to column `fx x / z + cx` and row `fy y / z + cy`. Depth is z in the
//! optical frame (m), 0 where nothing was hit. Shading is flat per triangle: ambient, a sun
//! from above and a weak headlight, times the surface's colour or texture (in the body's own
//! frame, so textures move with the body). Design: `docs/design/sim-stubs.md`, "render".

use nalgebra::{Isometry3, Point3, Vector3};

use crate::body::RobotBody;
use crate::mesh::TriMesh;
use crate::scene::{Body, Scene, Shape, Texture};

mod raster;
mod shading;
mod textures;

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

/// Where a mesh sits: a scene body, a link of the robot, or link `.1` of other robot `.0`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Owner {
    Body(usize),
    Link(usize),
    Other(usize, usize),
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
    /// The other robots' links ([`Renderer::set_others`]), drawn after the robot's own.
    others: Vec<(Owner, DrawMesh)>,
    /// Labels and materials of the scene and the robot itself (the others' come after).
    own: (usize, usize),
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
            others: Vec::new(),
            own: (0, 0),
        };
        for (i, b) in scene.bodies.iter().enumerate() {
            r.add_body(i, b);
        }
        if let Some(body) = body {
            let links = r.link_meshes(body, "robot", Owner::Link);
            r.meshes.extend(links);
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
        r.own = (r.labels.len(), r.materials.len());
        r
    }

    /// Draw the other robots `others` too (their links, labelled `robots/K/LINK` for the
    /// `K`th), in place of those set before; their link poses come with each frame
    /// ([`Renderer::render_among`]).
    pub fn set_others(&mut self, others: &[&RobotBody]) {
        self.labels.truncate(self.own.0);
        self.materials.truncate(self.own.1);
        self.others.clear();
        for (k, body) in others.iter().enumerate() {
            let links = self.link_meshes(body, &format!("robots/{k}"), |li| Owner::Other(k, li));
            self.others.extend(links);
        }
    }

    /// The meshes of `body`'s links with shapes, each link labelled `PREFIX/LINK` and owned
    /// by `owner(link index)`; their labels and materials added.
    fn link_meshes(
        &mut self,
        body: &RobotBody,
        prefix: &str,
        owner: impl Fn(usize) -> Owner,
    ) -> Vec<(Owner, DrawMesh)> {
        let mut out = Vec::new();
        for (li, (name, shapes)) in body.tree.links().zip(&body.shapes).enumerate() {
            if shapes.is_empty() {
                continue;
            }
            self.labels.push(format!("{prefix}/{name}"));
            let label = (self.labels.len() - 1) as u32;
            for s in shapes {
                let (m, closed) = tessellate(&s.shape);
                self.materials.push(Material {
                    colour: s.colour,
                    texture: None,
                });
                let mat = (self.materials.len() - 1) as u32;
                out.push((owner(li), draw_mesh(&m, closed, s.origin, mat, label)));
            }
        }
        out
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
        self.meshes
            .iter()
            .chain(&self.others)
            .map(|(_, m)| m.tris.len())
            .sum()
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
        self.render_among(camera, bodies, links, &[], out);
    }

    /// [`Renderer::render`] among the other robots of [`Renderer::set_others`], robot `k`'s
    /// links at `others[k]` (world poses, link-tree order; a robot left out is not drawn).
    pub fn render_among(
        &self,
        camera: &PinholeCamera,
        bodies: &[Isometry3<f64>],
        links: &[Isometry3<f64>],
        others: &[&[Isometry3<f64>]],
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
        let view = View::new(camera, self.sun);
        let shades = self.rasterise(
            &view,
            &Poses {
                bodies,
                links,
                others,
            },
            out,
        );
        self.shade(&shades, &view.k, out);
    }
}

/// Where the owners of the meshes are in one frame (world poses).
struct Poses<'a> {
    bodies: &'a [Isometry3<f64>],
    links: &'a [Isometry3<f64>],
    others: &'a [&'a [Isometry3<f64>]],
}

impl Poses<'_> {
    fn of(&self, owner: Owner) -> Option<&Isometry3<f64>> {
        match owner {
            Owner::Body(i) => self.bodies.get(i),
            Owner::Link(i) => self.links.get(i),
            Owner::Other(k, i) => self.others.get(k).and_then(|l| l.get(i)),
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

/// One frame's camera model: the world in the optical frame, the intrinsics, the sun and the
/// side planes of the view.
struct View {
    world_to_cam: Isometry3<f64>,
    k: Intr,
    /// Direction towards the sun (optical frame, unit).
    sun: Vector3<f32>,
    /// The side planes of the view (through the optical centre, unit normals pointing in).
    frustum: [Vector3<f32>; 4],
}

impl View {
    /// The view of `camera`, with the sun towards `sun` (world frame, unit).
    fn new(camera: &PinholeCamera, sun: Vector3<f32>) -> View {
        let (w, h) = (camera.width as usize, camera.height as usize);
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
            * sun;
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
        View {
            world_to_cam,
            k,
            sun,
            frustum,
        }
    }
}
