//! What a viewer draws besides the robot's own streams: a planned arm motion as
//! `nav_msgs/Path`, a navigation map as `nav_msgs/OccupancyGrid`, and the simulated world's
//! bodies as `visualization_msgs/MarkerArray`.

use std::time::Duration;

use ferrobot::events::PlannedArmPath;
use ferrobot::nav::{Cell, MapImage};
#[cfg(feature = "sim")]
use ferrobot::scene::{Scene, Shape};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};

use crate::cdr::CdrWriter;
use crate::encode::{header, pose, time};

/// `nav_msgs/Path` of the end effector along `plan`, planned at `t`: each pose stamped when it
/// would be reached, in the arm's base frame.
pub fn planned_path(t: Duration, plan: &PlannedArmPath) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(64 + plan.ee_path.len() * 100);
    header(&mut w, t, &plan.frame);
    w.seq_len(plan.ee_path.len());
    for (at, p) in &plan.ee_path {
        header(
            &mut w,
            t + Duration::from_secs_f64(at.max(0.0)),
            &plan.frame,
        );
        pose(&mut w, p);
    }
    w.into_bytes()
}

/// `nav_msgs/OccupancyGrid` of `map` in `frame`: 0 free, 100 occupied, -1 unknown, rows from
/// the bottom as the map's.
pub fn occupancy_grid(t: Duration, frame: &str, map: &MapImage) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(128 + map.cells.len());
    header(&mut w, t, frame);
    time(&mut w, t);
    w.f32(map.resolution as f32);
    w.u32(map.width as u32);
    w.u32(map.height as u32);
    let origin = Isometry3::translation(map.origin[0], map.origin[1], 0.0);
    pose(&mut w, &origin);
    let cells: Vec<i8> = map
        .cells
        .iter()
        .map(|c| match c {
            Cell::Free => 0,
            Cell::Occupied => 100,
            Cell::Unknown => -1,
        })
        .collect();
    w.i8_seq(&cells);
    w.into_bytes()
}

/// A marker's shape, as `visualization_msgs/Marker` draws it.
#[derive(Debug, Clone, PartialEq)]
pub enum MarkerShape {
    /// A box of full extents x, y, z, m.
    Cube([f64; 3]),
    /// An ellipsoid of diameters x, y, z, m.
    Sphere([f64; 3]),
    /// A cylinder along z: diameters x, y and height, m.
    Cylinder([f64; 3]),
    /// Triangles, each three consecutive points (in the marker's frame), m.
    Triangles(Vec<Point3<f64>>),
    /// A line through `points` (in the marker's frame), `width` m wide.
    LineStrip {
        /// Its points, m.
        points: Vec<Point3<f64>>,
        /// Its width, m.
        width: f64,
    },
}

/// One marker: its shape at `pose` in the array's frame, in `colour` (linear RGBA, 0-1).
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// The namespace; with `id`, what a later marker of the same pair replaces.
    pub ns: String,
    /// The id in its namespace.
    pub id: i32,
    /// The shape.
    pub shape: MarkerShape,
    /// The shape's pose in the frame.
    pub pose: Isometry3<f64>,
    /// RGBA, 0-1.
    pub colour: [f32; 4],
}

/// `visualization_msgs/MarkerArray` of `markers` in `frame`, each added (or replacing the one
/// of its namespace and id), for ever.
pub fn marker_array(t: Duration, frame: &str, markers: &[Marker]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(64 + markers.len() * 300);
    w.seq_len(markers.len());
    for m in markers {
        header(&mut w, t, frame);
        w.string(&m.ns);
        w.i32(m.id);
        let (kind, scale, points): (i32, [f64; 3], &[Point3<f64>]) = match &m.shape {
            MarkerShape::Cube(s) => (1, *s, &[]),
            MarkerShape::Sphere(s) => (2, *s, &[]),
            MarkerShape::Cylinder(s) => (3, *s, &[]),
            MarkerShape::LineStrip { points, width } => (4, [*width, 0.0, 0.0], points),
            MarkerShape::Triangles(points) => (11, [1.0; 3], points),
        };
        w.i32(kind);
        w.i32(0); // ADD
        pose(&mut w, &m.pose);
        w.f64_array(&scale);
        for c in m.colour {
            w.f32(c);
        }
        time(&mut w, Duration::ZERO); // lifetime: for ever
        w.u8(0); // frame_locked
        w.seq_len(points.len());
        for p in points {
            w.f64_array(&[p.x, p.y, p.z]);
        }
        w.seq_len(0); // colors
        w.string(""); // texture_resource
        header(&mut w, Duration::ZERO, ""); // texture: none
        w.string("");
        w.bytes(&[]);
        w.seq_len(0); // uv_coordinates
        w.string(""); // text
        w.string(""); // mesh_resource
        w.string(""); // mesh_file
        w.bytes(&[]);
        w.u8(0); // mesh_use_embedded_materials
    }
    w.into_bytes()
}

/// The simulated world's bodies as markers in `odom` (where the robot started, its base frame
/// `height` above the floor): each of `scene`'s bodies at its live pose in the world in
/// `poses` (the simulator's truth, [`Scene::bodies`] order), in its colour. A capsule is a
/// cylinder and two spheres; a mesh, its triangles.
#[cfg(feature = "sim")]
pub fn scene_markers(scene: &Scene, poses: &[Isometry3<f64>]) -> Vec<Marker> {
    let [x, y, yaw] = scene.robot_pose;
    let odom = Isometry3::from_parts(
        Translation3::new(x, y, scene.robot_height),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
    );
    let to_odom = odom.inverse();
    let mut out = Vec::new();
    for (body, world) in scene.bodies.iter().zip(poses) {
        let pose = to_odom * world;
        // The scene's colours are linear; viewers take sRGB.
        let c = body.colour.map(|v| v.clamp(0.0, 1.0).powf(1.0 / 2.2));
        let marker = |id: i32, shape: MarkerShape, pose: Isometry3<f64>| Marker {
            ns: body.id.clone(),
            id,
            shape,
            pose,
            colour: [c[0], c[1], c[2], 1.0],
        };
        match &body.shape {
            Shape::Box(s) => out.push(marker(0, MarkerShape::Cube(*s), pose)),
            Shape::Sphere(r) => out.push(marker(0, MarkerShape::Sphere([2.0 * r; 3]), pose)),
            Shape::Cylinder { radius, length } => {
                let d = 2.0 * radius;
                out.push(marker(0, MarkerShape::Cylinder([d, d, *length]), pose));
            }
            Shape::Capsule { radius, length } => {
                let d = 2.0 * radius;
                out.push(marker(0, MarkerShape::Cylinder([d, d, *length]), pose));
                for (id, z) in [(1, length / 2.0), (2, -length / 2.0)] {
                    let end = pose * Translation3::new(0.0, 0.0, z);
                    out.push(marker(id, MarkerShape::Sphere([d; 3]), end));
                }
            }
            Shape::Mesh { mesh, .. } => {
                let points = mesh
                    .triangles
                    .iter()
                    .flat_map(|t| t.map(|i| mesh.vertices[i as usize]))
                    .collect();
                out.push(marker(0, MarkerShape::Triangles(points), pose));
            }
            #[allow(unreachable_patterns)]
            _ => {}
        }
    }
    out
}

/// The world's messages a viewer wants beside the robot's streams, read from the robot as its
/// time passes: the simulated world's bodies ([`crate::topics::SCENE_MARKERS`], on the
/// simulator, every [`WorldFeed::SCENE_PERIOD`]) and SLAM's occupancy map
/// ([`crate::topics::MAP`], while SLAM runs, every [`WorldFeed::MAP_PERIOD`] when it changed).
#[derive(Debug, Default)]
pub struct WorldFeed {
    scene_at: Option<Duration>,
    map_at: Option<Duration>,
    map_last: Option<MapImage>,
}

impl WorldFeed {
    /// How often the world's bodies are sent, robot time.
    pub const SCENE_PERIOD: Duration = Duration::from_millis(500);
    /// How often the map is looked at, robot time.
    pub const MAP_PERIOD: Duration = Duration::from_secs(1);

    /// What is due at the robot's time now: each message with its topic.
    pub fn poll(&mut self, robot: &ferrobot::Robot) -> Vec<(crate::topics::Topic, Vec<u8>)> {
        let now = Duration::from_secs_f64(robot.time().max(0.0));
        let due = |at: Option<Duration>, period: Duration| at.is_none_or(|a| now >= a + period);
        let mut out = Vec::new();
        #[cfg(feature = "sim")]
        if due(self.scene_at, Self::SCENE_PERIOD) {
            self.scene_at = Some(now);
            let scene = robot.scene();
            if let (Ok(truth), false) = (robot.truth(), scene.bodies.is_empty()) {
                let markers = scene_markers(&scene, &truth.bodies);
                let frame = crate::topics::ODOM_FRAME;
                out.push((
                    crate::topics::SCENE_MARKERS,
                    marker_array(now, frame, &markers),
                ));
            }
        }
        if due(self.map_at, Self::MAP_PERIOD) {
            self.map_at = Some(now);
            if let Ok(Some(map)) = robot.slam_occupancy_map() {
                if self.map_last.as_ref() != Some(&map) {
                    let frame = crate::topics::MAP_FRAME;
                    out.push((crate::topics::MAP, occupancy_grid(now, frame, &map)));
                    self.map_last = Some(map);
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cdr::CdrReader;

    #[test]
    fn an_occupancy_grid_reads_back_as_nav_msgs_lays_it_out() {
        let map = MapImage {
            origin: [-1.5, 2.0],
            resolution: 0.05,
            width: 3,
            height: 2,
            cells: vec![
                Cell::Free,
                Cell::Occupied,
                Cell::Unknown,
                Cell::Occupied,
                Cell::Free,
                Cell::Free,
            ],
        };
        let t = Duration::from_millis(2500);
        let bytes = occupancy_grid(t, "map", &map);
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!((r.i32().unwrap(), r.u32().unwrap()), (2, 500_000_000));
        assert_eq!(r.string().unwrap(), "map");
        assert_eq!((r.i32().unwrap(), r.u32().unwrap()), (2, 500_000_000));
        assert_eq!(f32::from_bits(r.u32().unwrap()), 0.05);
        assert_eq!((r.u32().unwrap(), r.u32().unwrap()), (3, 2));
        assert_eq!(
            r.f64_array(7).unwrap(),
            [-1.5, 2.0, 0.0, 0.0, 0.0, 0.0, 1.0]
        );
        let cells: Vec<i8> = r.bytes().unwrap().iter().map(|&b| b as i8).collect();
        assert_eq!(cells, [0, 100, -1, 100, 0, 0]);
    }
}
