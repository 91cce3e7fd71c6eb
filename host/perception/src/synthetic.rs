//! Seeded synthetic clouds for tests and benchmarks, in a world frame with z up (m): Gaussian
//! blobs with uniform noise, the surfaces of boxes and planes sampled uniformly, and a
//! table-top scene (a table, boxes and cylinders on it, the floor) seen by a depth camera
//! ray-cast at the D435's intrinsics with depth noise growing with the square of distance.
//! The same seed gives the same points on every machine (ChaCha8).

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::cloud::{backproject, DepthRange, PointCloud};
use crate::error::Result;
use crate::image::DepthImage;
use crate::intrinsics::Intrinsics;

/// A standard normal sample (Box-Muller).
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = 1.0 - rng.random::<f64>(); // (0, 1]
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// `per_blob` points around each centre (isotropic Gaussian, standard deviation `sigma`, m),
/// then `noise` points uniform in the box `lo..hi` (m), all shuffled together.
pub fn blobs(
    seed: u64,
    centres: &[[f64; 3]],
    per_blob: usize,
    sigma: f64,
    noise: usize,
    lo: [f64; 3],
    hi: [f64; 3],
) -> Vec<Point3<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut pts = Vec::with_capacity(centres.len() * per_blob + noise);
    for c in centres {
        for _ in 0..per_blob {
            pts.push(Point3::new(
                c[0] + sigma * gauss(&mut rng),
                c[1] + sigma * gauss(&mut rng),
                c[2] + sigma * gauss(&mut rng),
            ));
        }
    }
    for _ in 0..noise {
        pts.push(Point3::new(
            uniform(&mut rng, lo[0], hi[0]),
            uniform(&mut rng, lo[1], hi[1]),
            uniform(&mut rng, lo[2], hi[2]),
        ));
    }
    shuffle(&mut rng, &mut pts);
    pts
}

fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// Fisher-Yates, so that a cloud's order says nothing about its structure.
fn shuffle<T>(rng: &mut ChaCha8Rng, v: &mut [T]) {
    for i in (1..v.len()).rev() {
        let j = rng.random_range(0..=i);
        v.swap(i, j);
    }
}

/// A solid resting on the table (or anywhere): a box turned about z, or an upright cylinder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Solid {
    /// A box: centre (m), full size along its own x, y, z (m), turned by `yaw` about z (rad).
    Box {
        /// Centre, m.
        centre: Point3<f64>,
        /// Full size along the box's axes, m.
        size: Vector3<f64>,
        /// Rotation about z, rad.
        yaw: f64,
    },
    /// An upright cylinder: centre (m), radius (m), full height (m).
    Cylinder {
        /// Centre, m.
        centre: Point3<f64>,
        /// Radius, m.
        radius: f64,
        /// Full height, m.
        height: f64,
    },
}

impl Solid {
    /// The solid's centre, m.
    pub fn centre(&self) -> Point3<f64> {
        match *self {
            Solid::Box { centre, .. } | Solid::Cylinder { centre, .. } => centre,
        }
    }

    /// Height of its top above its centre, m.
    pub fn half_height(&self) -> f64 {
        match *self {
            Solid::Box { size, .. } => size.z / 2.0,
            Solid::Cylinder { height, .. } => height / 2.0,
        }
    }

    /// Radius of a vertical cylinder around its centre that holds it, m.
    pub fn footprint_radius(&self) -> f64 {
        match *self {
            Solid::Box { size, .. } => 0.5 * (size.x * size.x + size.y * size.y).sqrt(),
            Solid::Cylinder { radius, .. } => radius,
        }
    }

    /// Where the ray `o + s d` (s > 0) first meets the solid's surface, or `None`.
    pub fn hit(&self, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
        match *self {
            Solid::Box { centre, size, yaw } => {
                let r = Rotation3::from_axis_angle(&Vector3::z_axis(), -yaw);
                slab(&(r * (o - centre)), &(r * d), &(size / 2.0))
            }
            Solid::Cylinder {
                centre,
                radius,
                height,
            } => cylinder(&(o - centre), d, radius, height / 2.0),
        }
    }

    /// Whether point `p` lies inside the solid grown by `margin` (m).
    pub fn contains(&self, p: &Point3<f64>, margin: f64) -> bool {
        match *self {
            Solid::Box { centre, size, yaw } => {
                let q = Rotation3::from_axis_angle(&Vector3::z_axis(), -yaw) * (p - centre);
                (0..3).all(|k| q[k].abs() <= size[k] / 2.0 + margin)
            }
            Solid::Cylinder {
                centre,
                radius,
                height,
            } => {
                let q = p - centre;
                q.xy().norm() <= radius + margin && q.z.abs() <= height / 2.0 + margin
            }
        }
    }
}

/// The entry parameter of the ray `o + s d` (s > 0) into the axis-aligned box of half sizes
/// `h` centred at the origin.
fn slab(o: &Vector3<f64>, d: &Vector3<f64>, h: &Vector3<f64>) -> Option<f64> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        if d[k].abs() < 1e-15 {
            if o[k].abs() > h[k] {
                return None;
            }
            continue;
        }
        let (a, b) = ((-h[k] - o[k]) / d[k], (h[k] - o[k]) / d[k]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1 && t0 > 0.0).then_some(t0)
}

/// The entry parameter of the ray `o + s d` (s > 0) into the upright cylinder of radius `r`
/// and half height `h` centred at the origin (side or top/bottom cap).
fn cylinder(o: &Vector3<f64>, d: &Vector3<f64>, r: f64, h: f64) -> Option<f64> {
    let mut best: Option<f64> = None;
    let mut take = |s: f64| {
        if s > 0.0 && best.is_none_or(|b| s < b) {
            best = Some(s);
        }
    };
    let a = d.x * d.x + d.y * d.y;
    if a > 1e-15 {
        let b = o.x * d.x + o.y * d.y;
        let c = o.x * o.x + o.y * o.y - r * r;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let s = (-b - disc.sqrt()) / a;
            if (o.z + s * d.z).abs() <= h {
                take(s);
            }
        }
    }
    if d.z.abs() > 1e-15 {
        for z in [h, -h] {
            let s = (z - o.z) / d.z;
            let q = o + s * d;
            if q.x * q.x + q.y * q.y <= r * r {
                take(s);
            }
        }
    }
    best
}

/// A table-top scene in the world frame (z up, the floor at z = 0): a table (a box from the
/// floor to `table_height`) and solids standing on it.
#[derive(Debug, Clone, PartialEq)]
pub struct Tabletop {
    /// Centre of the table's top face, x y, m.
    pub table_centre: [f64; 2],
    /// Table top's size along x and y, m.
    pub table_size: [f64; 2],
    /// Height of the table's top face above the floor, m.
    pub table_height: f64,
    /// The objects standing on the table.
    pub objects: Vec<Solid>,
}

impl Tabletop {
    /// A table like the simulator's `tabletop` (top 0.6 x 1.0 m at 0.1 m, its near edge
    /// 0.35 m ahead of the origin) with `objects` boxes and cylinders of 2-8 cm placed at
    /// random, seeded, at least `gap` (m) apart and 5 cm inside the table's edges.
    pub fn random(seed: u64, objects: usize, gap: f64) -> Tabletop {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut scene = Tabletop {
            table_centre: [0.65, 0.0],
            table_size: [0.6, 1.0],
            table_height: 0.1,
            objects: Vec::new(),
        };
        let mut tries = 0;
        while scene.objects.len() < objects && tries < 10_000 {
            tries += 1;
            let h = uniform(&mut rng, 0.02, 0.08);
            let solid = if rng.random::<bool>() {
                let size = Vector3::new(
                    uniform(&mut rng, 0.02, 0.08),
                    uniform(&mut rng, 0.02, 0.08),
                    h,
                );
                Solid::Box {
                    centre: Point3::origin(),
                    size,
                    yaw: uniform(&mut rng, 0.0, std::f64::consts::PI),
                }
            } else {
                Solid::Cylinder {
                    centre: Point3::origin(),
                    radius: uniform(&mut rng, 0.01, 0.04),
                    height: h,
                }
            };
            let fr = solid.footprint_radius();
            let half = [
                scene.table_size[0] / 2.0 - 0.05 - fr,
                scene.table_size[1] / 2.0 - 0.05 - fr,
            ];
            let x = scene.table_centre[0] + uniform(&mut rng, -half[0], half[0]);
            let y = scene.table_centre[1] + uniform(&mut rng, -half[1], half[1]);
            let far_enough = scene.objects.iter().all(|o| {
                let c = o.centre();
                ((c.x - x).powi(2) + (c.y - y).powi(2)).sqrt() > fr + o.footprint_radius() + gap
            });
            if !far_enough {
                continue;
            }
            let centre = Point3::new(x, y, scene.table_height + h / 2.0);
            scene.objects.push(match solid {
                Solid::Box { size, yaw, .. } => Solid::Box { centre, size, yaw },
                Solid::Cylinder { radius, height, .. } => Solid::Cylinder {
                    centre,
                    radius,
                    height,
                },
            });
        }
        scene
    }

    /// The table as a solid (a box from the floor to its top).
    pub fn table(&self) -> Solid {
        Solid::Box {
            centre: Point3::new(
                self.table_centre[0],
                self.table_centre[1],
                self.table_height / 2.0,
            ),
            size: Vector3::new(self.table_size[0], self.table_size[1], self.table_height),
            yaw: 0.0,
        }
    }

    /// Where the ray `o + s d` (s > 0) first meets the floor, the table or an object.
    pub fn hit(&self, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
        let mut best = (d.z < 0.0).then(|| -o.z / d.z).filter(|&s| s > 0.0);
        for solid in std::iter::once(self.table()).chain(self.objects.iter().copied()) {
            if let Some(s) = solid.hit(o, d) {
                if best.is_none_or(|b| s < b) {
                    best = Some(s);
                }
            }
        }
        best
    }

    /// The index of the object whose surface holds point `p` (within `margin`, m), if any.
    pub fn object_at(&self, p: &Point3<f64>, margin: f64) -> Option<usize> {
        self.objects.iter().position(|o| o.contains(p, margin))
    }
}

/// A depth camera looking at a scene: where it is and how it sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthCamera {
    /// The optical centre in the world, m.
    pub eye: Point3<f64>,
    /// Heading of the view about z (0 looks along +x), rad.
    pub yaw: f64,
    /// Tilt of the view below the horizontal, rad (PyRobot's grasping view: 0.8).
    pub tilt: f64,
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// The depths kept.
    pub range: DepthRange,
    /// Standard deviation of the depth noise at 1 m, m (it grows with the square of the
    /// depth, as a stereo camera's does); 0 for exact depth.
    pub noise_at_1m: f64,
}

impl DepthCamera {
    /// A camera with `intrinsics` on a LoCoBot-like head: 0.55 m above the floor, looking along
    /// +x, tilted 0.8 rad down (PyRobot's grasping view), keeping depths in (0.2, 1.5) m, with
    /// 2 mm of noise at 1 m. A robot's intrinsics are a fact of its description
    /// (`[camera]` in its TOML): the caller brings them.
    pub fn looking_down(intrinsics: Intrinsics) -> DepthCamera {
        DepthCamera {
            eye: Point3::new(0.03, 0.0, 0.55),
            yaw: 0.0,
            tilt: 0.8,
            intrinsics,
            range: DepthRange::PYROBOT,
            noise_at_1m: 0.002,
        }
    }

    /// The same camera with its image scaled by `f` (intrinsics and size), e.g. 0.5 for
    /// 320x240.
    pub fn scaled(mut self, f: f64) -> DepthCamera {
        let k = &mut self.intrinsics;
        k.width = ((k.width as f64 * f).round() as u32).max(1);
        k.height = ((k.height as f64 * f).round() as u32).max(1);
        k.fx *= f;
        k.fy *= f;
        k.cx = (k.cx + 0.5) * f - 0.5;
        k.cy = (k.cy + 0.5) * f - 0.5;
        self
    }

    /// The optical frame's pose in the world (x right, y down, z forward).
    pub fn pose(&self) -> Isometry3<f64> {
        let (st, ct) = self.tilt.sin_cos();
        let (sy, cy) = self.yaw.sin_cos();
        let forward = Vector3::new(cy * ct, sy * ct, -st);
        let right = Vector3::new(sy, -cy, 0.0);
        let down = forward.cross(&right);
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[right, down, forward]));
        Isometry3::from_parts(
            Translation3::from(self.eye.coords),
            UnitQuaternion::from_rotation_matrix(&r),
        )
    }

    /// The depth image of `scene`, seeded noise included (0 where nothing is hit).
    pub fn depth(&self, scene: &Tabletop, seed: u64) -> Result<DepthImage> {
        let k = self.intrinsics;
        k.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let pose = self.pose();
        let mut data = Vec::with_capacity(k.pixels());
        for r in 0..k.height {
            for c in 0..k.width {
                let ray = Vector3::new((c as f64 - k.cx) / k.fx, (r as f64 - k.cy) / k.fy, 1.0);
                let d = pose.rotation * ray;
                let z = match scene.hit(&self.eye, &d) {
                    Some(s) => s + self.noise_at_1m * s * s * gauss(&mut rng),
                    None => 0.0,
                };
                data.push(z as f32);
            }
        }
        DepthImage::new(k.width, k.height, data)
    }

    /// The cloud of `scene` in the world frame (m): the depth image back-projected, keeping
    /// the camera's depth range.
    pub fn cloud(&self, scene: &Tabletop, seed: u64) -> Result<PointCloud> {
        let depth = self.depth(scene, seed)?;
        Ok(backproject(&self.intrinsics, &depth, None, self.range)?.transformed(&self.pose()))
    }
}

/// Points sampled uniformly (by area, seeded) on a solid's surface except its bottom face,
/// about `density` points per square metre: what a camera all around it would see.
pub fn sample_solid(seed: u64, solid: &Solid, density: f64) -> Vec<Point3<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut pts = Vec::new();
    let count = |area: f64, rng: &mut ChaCha8Rng| {
        let x = area * density;
        let n = x.floor() as usize;
        n + usize::from(rng.random::<f64>() < x - n as f64)
    };
    match *solid {
        Solid::Box { centre, size, yaw } => {
            let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw);
            let h = size / 2.0;
            // Top, then the four sides: (axis fixed, its sign, the two free axes).
            let faces = [
                (2, 1.0, 0, 1),
                (0, 1.0, 1, 2),
                (0, -1.0, 1, 2),
                (1, 1.0, 0, 2),
                (1, -1.0, 0, 2),
            ];
            for (fixed, sign, a, b) in faces {
                for _ in 0..count(size[a] * size[b], &mut rng) {
                    let mut q = Vector3::zeros();
                    q[fixed] = sign * h[fixed];
                    q[a] = uniform(&mut rng, -h[a], h[a]);
                    q[b] = uniform(&mut rng, -h[b], h[b]);
                    pts.push(centre + rot * q);
                }
            }
        }
        Solid::Cylinder {
            centre,
            radius,
            height,
        } => {
            for _ in 0..count(std::f64::consts::PI * radius * radius, &mut rng) {
                let (rr, a) = (
                    radius * rng.random::<f64>().sqrt(),
                    uniform(&mut rng, 0.0, std::f64::consts::TAU),
                );
                pts.push(centre + Vector3::new(rr * a.cos(), rr * a.sin(), height / 2.0));
            }
            for _ in 0..count(std::f64::consts::TAU * radius * height, &mut rng) {
                let a = uniform(&mut rng, 0.0, std::f64::consts::TAU);
                let z = uniform(&mut rng, -height / 2.0, height / 2.0);
                pts.push(centre + Vector3::new(radius * a.cos(), radius * a.sin(), z));
            }
        }
    }
    pts
}

/// The mean of points sampled uniformly on a solid's surface except its bottom face (as
/// [`sample_solid`] samples it), m: the centroid such a sample converges to.
pub fn surface_centroid(solid: &Solid) -> Point3<f64> {
    let (top, side, c, hh) = match *solid {
        Solid::Box { centre, size, .. } => (
            size.x * size.y,
            2.0 * size.z * (size.x + size.y),
            centre,
            size.z / 2.0,
        ),
        Solid::Cylinder {
            centre,
            radius,
            height,
        } => (
            std::f64::consts::PI * radius * radius,
            std::f64::consts::TAU * radius * height,
            centre,
            height / 2.0,
        ),
    };
    // The sides' centroid is the solid's centre; the top's lies `hh` above it.
    c + Vector3::new(0.0, 0.0, hh * top / (top + side))
}

/// Points sampled uniformly (seeded) on a plane's rectangle `centre +- u * a/2 +- v * b/2`
/// (m), about `density` per square metre, with Gaussian noise of `sigma` (m) along the
/// normal `u x v`; points inside any of `holes` (grown by `margin`, m) are left out.
#[allow(clippy::too_many_arguments)]
pub fn sample_rectangle(
    seed: u64,
    centre: Point3<f64>,
    u: Vector3<f64>,
    v: Vector3<f64>,
    size: [f64; 2],
    density: f64,
    sigma: f64,
    holes: &[Solid],
    margin: f64,
) -> Vec<Point3<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = (size[0] * size[1] * density).round() as usize;
    let (u, v) = (u.normalize(), v.normalize());
    let normal = u.cross(&v);
    let mut pts = Vec::with_capacity(n);
    for _ in 0..n {
        let p = centre
            + u * uniform(&mut rng, -size[0] / 2.0, size[0] / 2.0)
            + v * uniform(&mut rng, -size[1] / 2.0, size[1] / 2.0)
            + normal * (sigma * gauss(&mut rng));
        if !holes.iter().any(|h| h.contains(&p, margin)) {
            pts.push(p);
        }
    }
    pts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_camera_sees_the_table_and_the_objects_where_they_are() {
        let scene = Tabletop::random(3, 6, 0.05);
        assert_eq!(scene.objects.len(), 6);
        // A 320x240 pinhole with a 54 degree horizontal field of view.
        let k = Intrinsics {
            width: 320,
            height: 240,
            fx: 310.0,
            fy: 310.0,
            cx: 159.5,
            cy: 119.5,
        };
        let cam = DepthCamera {
            noise_at_1m: 0.0,
            ..DepthCamera::looking_down(k)
        };
        let cloud = cam.cloud(&scene, 1).unwrap();
        assert!(cloud.len() > 50_000, "{}", cloud.len());
        let mut on_objects = 0;
        for p in &cloud.points {
            // Every point lies on the floor, the table or an object (1e-9 m).
            let on_floor = p.z.abs() < 1e-6;
            let on_table = scene.table().contains(p, 1e-6);
            let on_object = scene.object_at(p, 1e-6).is_some();
            assert!(on_floor || on_table || on_object, "{p:?}");
            on_objects += usize::from(on_object);
        }
        assert!(on_objects > 1000, "{on_objects}");
        // The pose's forward axis is the optical z, tilted 0.8 rad down.
        let f = cam.pose().rotation * Vector3::z();
        assert!((f.z + 0.8f64.sin()).abs() < 1e-12);
    }

    #[test]
    fn surface_samples_converge_to_the_surface_centroid() {
        let b = Solid::Box {
            centre: Point3::new(0.5, 0.2, 0.3),
            size: Vector3::new(0.1, 0.04, 0.06),
            yaw: 0.7,
        };
        let c = Solid::Cylinder {
            centre: Point3::new(-0.5, 0.2, 0.3),
            radius: 0.03,
            height: 0.08,
        };
        for s in [b, c] {
            let pts = sample_solid(5, &s, 4e6);
            let m = pts.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / pts.len() as f64;
            assert!((m - surface_centroid(&s).coords).norm() < 5e-4, "{s:?}");
            assert!(pts.iter().all(|p| s.contains(p, 1e-9)));
        }
    }
}
