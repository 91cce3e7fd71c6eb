//! A movable mesh's collision shape: its convex hull, whose faces of more than four vertices
//! meet other shapes at four vertices spread over the face.
//!
//! Why: rapier builds face-to-face contacts from each shape's support face, at most four
//! vertices (parry's `PolygonalFeature`), and parry's `ConvexPolyhedron` hands over the
//! *first four* vertices of a larger face (a `TODO` there: "select four vertices that
//! maximize the area"). A mug's base, one 24-sided face, then stood on four neighbouring
//! corners on one side of it, and the mug, supported off its centre, rocked and walked across
//! the table by itself (about 1.4 mm/s, at some yaws). [`Hull`] is that convex polyhedron
//! with the four vertices of greatest area chosen once per face, so a resting hull stands on
//! its whole base; everything else (mass, ray casts, point queries, support points) is
//! parry's own.

use rapier3d::parry::bounding_volume::{Aabb, BoundingSphere};
use rapier3d::parry::mass_properties::MassProperties;
use rapier3d::parry::query::{PointProjection, PointQuery, Ray, RayCast, RayIntersection};
use rapier3d::parry::shape::{
    ConvexPolyhedron, FeatureId, PackedFeatureId, PolygonalFeature, PolygonalFeatureMap, Shape,
    ShapeType, SupportMap, TypedShape,
};
use rapier3d::prelude::{Real, Vector};

/// Faces with more vertices than this get four evenly spaced ones instead of the search for
/// the largest quadrilateral (whose cost grows with the fourth power of the count).
pub const SEARCH_MAX: usize = 40;

/// A convex hull whose faces of more than four vertices are represented by the four spanning
/// the greatest area (see the module). Local frame of the mesh, m.
#[derive(Debug, Clone)]
pub struct Hull {
    poly: ConvexPolyhedron,
    /// Per face, the positions (in `vertices_adj_to_face` from the face's first) of the
    /// vertices it meets other shapes with: all of them up to four.
    corners: Vec<Vec<u32>>,
}

impl Hull {
    /// The convex hull of `points` (m); `None` when they span no volume.
    pub fn new(points: &[Vector]) -> Option<Hull> {
        let poly = ConvexPolyhedron::from_convex_hull(points)?;
        let corners = poly
            .faces()
            .iter()
            .map(|f| {
                let first = f.first_vertex_or_edge as usize;
                let n = f.num_vertices_or_edges as usize;
                let at: Vec<Vector> = (first..first + n)
                    .map(|i| poly.points()[poly.vertices_adj_to_face()[i] as usize])
                    .collect();
                widest_quad(&at)
            })
            .collect();
        Some(Hull { poly, corners })
    }
}

/// Of a convex polygon's vertices (in order around it), the positions of at most four
/// spanning the greatest area, in order.
fn widest_quad(at: &[Vector]) -> Vec<u32> {
    let n = at.len();
    if n <= 4 {
        return (0..n as u32).collect();
    }
    if n > SEARCH_MAX {
        return (0..4).map(|k| (k * n / 4) as u32).collect();
    }
    let area = |q: [usize; 4]| {
        let c = (at[q[0]] - at[q[2]]).cross(at[q[1]] - at[q[3]]);
        c.length()
    };
    let mut best = ([0, 1, 2, 3], area([0, 1, 2, 3]));
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                for l in k + 1..n {
                    let a = area([i, j, k, l]);
                    if a > best.1 {
                        best = ([i, j, k, l], a);
                    }
                }
            }
        }
    }
    best.0.iter().map(|&i| i as u32).collect()
}

impl PolygonalFeatureMap for Hull {
    fn local_support_feature(&self, dir: Vector, out: &mut PolygonalFeature) {
        let faces = self.poly.faces();
        let mut best = 0;
        let mut best_dot = faces[0].normal.dot(dir);
        for (i, f) in faces.iter().enumerate().skip(1) {
            let d = f.normal.dot(dir);
            if d > best_dot {
                best = i;
                best_dot = d;
            }
        }
        let first = faces[best].first_vertex_or_edge as usize;
        let corners = &self.corners[best];
        for (k, &c) in corners.iter().enumerate() {
            let vid = self.poly.vertices_adj_to_face()[first + c as usize];
            let eid = self.poly.edges_adj_to_face()[first + c as usize];
            out.vertices[k] = self.poly.points()[vid as usize];
            out.vids[k] = PackedFeatureId::vertex(vid);
            out.eids[k] = PackedFeatureId::edge(eid);
        }
        out.fid = PackedFeatureId::face(best as u32);
        out.num_vertices = corners.len();
    }

    fn is_convex_polyhedron(&self) -> bool {
        true
    }
}

impl SupportMap for Hull {
    fn local_support_point(&self, dir: Vector) -> Vector {
        self.poly.local_support_point(dir)
    }
}

impl RayCast for Hull {
    fn cast_local_ray_and_get_normal(
        &self,
        ray: &Ray,
        max_time_of_impact: Real,
        solid: bool,
    ) -> Option<RayIntersection> {
        self.poly
            .cast_local_ray_and_get_normal(ray, max_time_of_impact, solid)
    }
}

impl PointQuery for Hull {
    fn project_local_point(&self, pt: Vector, solid: bool) -> PointProjection {
        self.poly.project_local_point(pt, solid)
    }

    fn project_local_point_and_get_feature(&self, pt: Vector) -> (PointProjection, FeatureId) {
        self.poly.project_local_point_and_get_feature(pt)
    }
}

impl Shape for Hull {
    fn compute_local_aabb(&self) -> Aabb {
        self.poly.compute_local_aabb()
    }

    fn compute_local_bounding_sphere(&self) -> BoundingSphere {
        self.poly.compute_local_bounding_sphere()
    }

    fn clone_dyn(&self) -> Box<dyn Shape> {
        Box::new(self.clone())
    }

    fn scale_dyn(&self, scale: Vector, _num_subdivisions: u32) -> Option<Box<dyn Shape>> {
        let points: Vec<Vector> = self.poly.points().iter().map(|p| *p * scale).collect();
        Hull::new(&points).map(|h| Box::new(h) as Box<dyn Shape>)
    }

    fn mass_properties(&self, density: Real) -> MassProperties {
        self.poly.mass_properties(density)
    }

    fn shape_type(&self) -> ShapeType {
        ShapeType::Custom
    }

    fn as_typed_shape(&self) -> TypedShape<'_> {
        TypedShape::Custom(self)
    }

    fn ccd_thickness(&self) -> Real {
        self.poly.ccd_thickness()
    }

    fn ccd_angular_thickness(&self) -> Real {
        self.poly.ccd_angular_thickness()
    }

    fn is_convex(&self) -> bool {
        true
    }

    fn as_support_map(&self) -> Option<&dyn SupportMap> {
        Some(self)
    }

    fn as_polygonal_feature_map(&self) -> Option<(&dyn PolygonalFeatureMap, Real)> {
        Some((self, 0.0))
    }

    fn feature_normal_at_point(
        &self,
        subshape: u32,
        feature: FeatureId,
        point: Vector,
    ) -> Option<Vector> {
        self.poly.feature_normal_at_point(subshape, feature, point)
    }
}
