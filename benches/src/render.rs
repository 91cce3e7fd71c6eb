//! What the render bench (`benches/render.rs`) and the `render_fps` example share: the camera
//! views of the bundled scenes, their export to PyBullet, CPU time and PNG output.

use std::path::Path;
use std::sync::Arc;

use ferrobot_description::{CameraSection, RobotConfig};
use ferrobot_sim::body::RobotBody;
use ferrobot_sim::camera::StereoNoise;
use ferrobot_sim::mesh::TriMesh;
use ferrobot_sim::render::{PinholeCamera, RenderedImage, Renderer};
use ferrobot_sim::rng::SimRng;
use ferrobot_sim::scene::{Scene, Shape};
use nalgebra::{Isometry3, Matrix4};
use serde_json::{json, Value};

/// Near and far planes of PyBullet's projection, m.
const NEAR: f64 = 0.01;
const FAR: f64 = 20.0;

/// One camera view of a scene.
pub struct View {
    /// The bundled scene's name.
    pub name: &'static str,
    /// The scene.
    pub scene: Arc<Scene>,
    /// The LoCoBot's body (its links' shapes).
    pub body: Arc<RobotBody>,
    /// The renderer of the scene and the body.
    pub renderer: Renderer,
    /// The LoCoBot's camera: the description's intrinsics at the optical frame's pose.
    pub camera: PinholeCamera,
    /// World poses of the scene's bodies.
    pub bodies: Vec<Isometry3<f64>>,
    /// World poses of the robot's links.
    pub links: Vec<Isometry3<f64>>,
}

impl View {
    /// The LoCoBot's camera in bundled scene `name`, head tilted `tilt` rad down.
    pub fn new(name: &'static str, tilt: f64) -> View {
        let cfg = RobotConfig::bundled("locobot").expect("locobot");
        let desc = ferrobot_sim::robots::from_description(&cfg);
        let body = desc.body.clone().expect("the LoCoBot has a body");
        let scene = Arc::new(Scene::bundled(name).expect("scene"));
        let section: &CameraSection = cfg.camera.as_ref().expect("camera");
        let mut q = vec![0.0; body.tree.joints().len()];
        // The head down, the arm folded up and back out of the view.
        for (joint, value) in [
            ("head_tilt_joint", tilt),
            ("joint_2", -1.5),
            ("joint_3", 1.5),
            ("joint_4", 0.6),
        ] {
            q[body.tree.joint_index(joint).expect("joint")] = value;
        }
        let [x, y, heading] = scene.robot_pose;
        let root = RobotBody::root_pose([x, y, heading], scene.robot_height);
        let links = body.link_poses(&root, &q);
        let optical = body.tree.link_index(&section.frame).expect("optical frame");
        let camera = PinholeCamera {
            width: section.width,
            height: section.height,
            fx: section.fx,
            fy: section.fy,
            cx: section.cx,
            cy: section.cy,
            pose: links[optical],
        };
        View {
            name,
            renderer: Renderer::new(&scene, Some(&body)),
            bodies: scene.bodies.iter().map(|b| b.pose).collect(),
            scene,
            body,
            camera,
            links,
        }
    }

    /// One frame of the view into `out`, with the D435's depth noise when `noise` is given.
    pub fn render(&self, out: &mut RenderedImage, noise: Option<&mut SimRng>) {
        self.renderer
            .render(&self.camera, &self.bodies, &self.links, out);
        if let Some(rng) = noise {
            let w = self.camera.width as usize;
            StereoNoise::D435.apply(&mut out.depth, w, self.camera.fx, rng);
        }
    }

    /// The scene as `pybullet_render.py` reads it; meshes are written as OBJ files in `dir`.
    pub fn export(&self, dir: &Path) -> Value {
        let mut shapes = Vec::new();
        let mut add = |shape: &Shape, pose: Isometry3<f64>, colour: [f32; 3], tag: String| {
            let mut s = match shape {
                Shape::Box(size) => json!({ "kind": "box", "size": size }),
                Shape::Cylinder { radius, length } => {
                    json!({ "kind": "cylinder", "radius": radius, "length": length })
                }
                Shape::Sphere(radius) => json!({ "kind": "sphere", "radius": radius }),
                Shape::Capsule { radius, length } => {
                    json!({ "kind": "capsule", "radius": radius, "length": length })
                }
                Shape::Mesh { mesh, .. } => {
                    let path = dir.join(format!("{}_{tag}.obj", self.name));
                    write_obj(&path, mesh);
                    json!({ "kind": "mesh", "obj": path })
                }
            };
            let t = pose.translation.vector;
            let q = pose.rotation.coords;
            s["position"] = json!([t.x, t.y, t.z]);
            s["quaternion"] = json!([q.x, q.y, q.z, q.w]);
            s["colour"] = json!(colour);
            shapes.push(s);
        };
        for (b, pose) in self.scene.bodies.iter().zip(&self.bodies) {
            add(&b.shape, *pose, b.colour, b.id.clone());
        }
        for (i, (link_shapes, pose)) in self.body.shapes.iter().zip(&self.links).enumerate() {
            for (j, s) in link_shapes.iter().enumerate() {
                add(&s.shape, pose * s.origin, s.colour, format!("link{i}_{j}"));
            }
        }
        let c = &self.camera;
        let (w, h) = (f64::from(c.width), f64::from(c.height));
        // OpenGL's camera (x right, y up, looking along -z) from the optical frame, and a
        // projection whose pixels fall where the pinhole puts columns and rows. TinyRenderer
        // samples at whole viewport coordinates (column c at x = c, row r at y = h - 1 - r),
        // not at OpenGL's pixel centres (+0.5): the principal point (cx, cy) of our rows
        // counted down is (cx, h - 1 - cy) in its viewport, which this matrix gives. Then the
        // two depth images agree to the rounding in 96 % of the tabletop's pixels.
        let gl = Matrix4::from_diagonal(&nalgebra::Vector4::new(1.0, -1.0, -1.0, 1.0));
        let view = gl * c.pose.inverse().to_homogeneous();
        let (cx, cy) = (c.cx, c.cy + 1.0);
        #[rustfmt::skip]
        let projection = Matrix4::new(
            2.0 * c.fx / w, 0.0, 1.0 - 2.0 * cx / w, 0.0,
            0.0, 2.0 * c.fy / h, 2.0 * cy / h - 1.0, 0.0,
            0.0, 0.0, -(FAR + NEAR) / (FAR - NEAR), -2.0 * FAR * NEAR / (FAR - NEAR),
            0.0, 0.0, -1.0, 0.0,
        );
        json!({
            "shapes": shapes,
            "camera": {
                "width": c.width,
                "height": c.height,
                "view": view.as_slice(),
                "projection": projection.as_slice(),
                "near": NEAR,
                "far": FAR,
            }
        })
    }
}

fn write_obj(path: &Path, m: &TriMesh) {
    let mut s = String::new();
    for v in &m.vertices {
        s += &format!("v {} {} {}\n", v.x, v.y, v.z);
    }
    for t in &m.triangles {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, s).expect("write OBJ");
}

/// The two views the benchmark measures.
pub fn views() -> Vec<View> {
    vec![View::new("tabletop", 0.8), View::new("apartment", 0.3)]
}

/// This thread's time on a CPU so far, s (Linux's /proc/thread-self/schedstat).
pub fn cpu_time() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .map_or(f64::NAN, |ns| ns as f64 * 1e-9)
}

/// An 8-bit PNG of `data` (`w` x `h` pixels of `colour`) at `path`.
pub fn write_png(path: &Path, w: u32, h: u32, colour: png::ColorType, data: &[u8]) {
    let f = std::io::BufWriter::new(std::fs::File::create(path).expect("create PNG"));
    let mut e = png::Encoder::new(f, w, h);
    e.set_color(colour);
    e.set_depth(png::BitDepth::Eight);
    e.write_header()
        .expect("PNG header")
        .write_image_data(data)
        .expect("PNG data");
}

/// Depth as grey, 0.25 m white to 4 m black (log scale); nothing (0) black.
pub fn depth_png(path: &Path, w: u32, h: u32, depth: &[f32]) {
    let grey: Vec<u8> = depth
        .iter()
        .map(|&d| {
            if d > 0.0 {
                (255.0 * (1.0 - (d / 0.25).ln() / 16f32.ln())).clamp(0.0, 255.0) as u8
            } else {
                0
            }
        })
        .collect();
    write_png(path, w, h, png::ColorType::Grayscale, &grey);
}
