//! A SLAM map on disk, so that a map survives the program and a robot can localise in it
//! later: keyframes (poses, camera mounts, descriptors, landmark ties, depth samples),
//! landmarks and the pose graph's edges, in a little-endian binary file that starts with
//! `FERROBOT-SLAM-MAP 1\n`. Reading checks every count, index and number: a truncated,
//! foreign or corrupt file is a typed error, never a panic or a huge allocation.

use std::path::Path;

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion};

use crate::error::{Error, Result};
use crate::map::{Keyframe, Landmark, Map, MIN_LANDMARK_SIGMA};
use crate::optimise::Edge;

const MAGIC: &[u8] = b"FERROBOT-SLAM-MAP 1\n";
/// Farthest a keyframe, landmark or depth point may lie, m.
const MAX_COORDINATE: f64 = 1e4;
/// Largest map file read, bytes.
pub const MAX_MAP_FILE: u64 = 2 << 30;

struct Writer(Vec<u8>);

impl Writer {
    fn u32(&mut self, v: usize) {
        self.0.extend_from_slice(&(v as u32).to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn pose(&mut self, p: &Isometry3<f64>) {
        let t = p.translation.vector;
        let q = p.rotation.coords;
        for v in [t.x, t.y, t.z, q.x, q.y, q.z, q.w] {
            self.f64(v);
        }
    }
    fn descriptor(&mut self, d: &crate::orb::Descriptor) {
        for w in d {
            self.0.extend_from_slice(&w.to_le_bytes());
        }
    }
}

struct Reader<'a> {
    data: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> std::result::Result<&[u8], String> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.data.len())
            .ok_or_else(|| format!("truncated at byte {}", self.at))?;
        let s = &self.data[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u32(&mut self) -> std::result::Result<usize, String> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    }
    /// A count of items of at least `item` bytes each that the rest of the file can hold.
    fn count(&mut self, item: usize, what: &str) -> std::result::Result<usize, String> {
        let n = self.u32()?;
        if n.saturating_mul(item) > self.data.len() - self.at {
            return Err(format!("{n} {what} cannot fit in the rest of the file"));
        }
        Ok(n)
    }
    fn f64(&mut self) -> std::result::Result<f64, String> {
        let b = self.take(8)?;
        let v = f64::from_le_bytes(b.try_into().map_err(|_| "short read".to_string())?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!(
                "a number that is not finite at byte {}",
                self.at - 8
            ))
        }
    }
    fn f32(&mut self) -> std::result::Result<f32, String> {
        let b = self.take(4)?;
        let v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!(
                "a number that is not finite at byte {}",
                self.at - 4
            ))
        }
    }
    fn pose(&mut self) -> std::result::Result<Isometry3<f64>, String> {
        let mut v = [0.0; 7];
        for x in &mut v {
            *x = self.f64()?;
        }
        let q = Quaternion::new(v[6], v[3], v[4], v[5]);
        if (q.norm() - 1.0).abs() > 1e-3 {
            return Err(format!("a rotation that is not a unit quaternion: {v:?}"));
        }
        Ok(Isometry3::from_parts(
            Translation3::new(v[0], v[1], v[2]),
            UnitQuaternion::from_quaternion(q),
        ))
    }
    fn descriptor(&mut self) -> std::result::Result<crate::orb::Descriptor, String> {
        let b = self.take(32)?;
        let mut d = [0u64; 4];
        for (w, c) in d.iter_mut().zip(b.chunks_exact(8)) {
            *w = u64::from_le_bytes(c.try_into().map_err(|_| "short read".to_string())?);
        }
        Ok(d)
    }
}

impl Map {
    /// Writes the map to `path`.
    pub fn save(&self, path: &Path) -> Result<()> {
        let mut w = Writer(MAGIC.to_vec());
        w.u32(self.keyframes.len());
        for kf in &self.keyframes {
            w.f64(kf.time);
            w.pose(&kf.pose);
            w.pose(&kf.camera);
            w.u32(kf.descriptors.len());
            for (d, l) in kf.descriptors.iter().zip(&kf.landmarks) {
                w.descriptor(d);
                // Landmark index + 1, 0 for none.
                w.u32(l.map_or(0, |l| l + 1));
            }
            w.u32(kf.cloud.len());
            for (p, c) in &kf.cloud {
                w.f32(p.x);
                w.f32(p.y);
                w.f32(p.z);
                w.0.extend_from_slice(c);
            }
        }
        w.u32(self.landmarks.len());
        for l in &self.landmarks {
            w.u32(l.keyframe);
            for v in [l.local.x, l.local.y, l.local.z, l.sigma] {
                w.f64(v);
            }
            w.descriptor(&l.descriptor);
            w.0.push(l.level);
            w.u32(l.found as usize);
            w.u32(l.visible as usize);
        }
        w.u32(self.edges.len());
        for e in &self.edges {
            w.u32(e.a);
            w.u32(e.b);
            w.pose(&e.z);
            w.f64(e.sigma_t);
            w.f64(e.sigma_r);
        }
        crate::error::write_file(path, &w.0)
    }

    /// Reads a map [`Map::save`] wrote. Errors name the file and what is wrong with it.
    pub fn load(path: &Path) -> Result<Map> {
        let bad = |why: String| Error::File {
            path: path.to_path_buf(),
            why,
        };
        let data = crate::error::read_file(path, MAX_MAP_FILE)?;
        if !data.starts_with(MAGIC) {
            return Err(bad("not a Ferrobot SLAM map (version 1)".into()));
        }
        let mut r = Reader {
            data: &data,
            at: MAGIC.len(),
        };
        Self::parse(&mut r).map_err(bad)
    }

    fn parse(r: &mut Reader<'_>) -> std::result::Result<Map, String> {
        let mut map = Map::default();
        let nk = r.count(8 + 2 * 56 + 8, "keyframes")?;
        for _ in 0..nk {
            map.keyframes.push(r.keyframe()?);
        }
        let nl = r.count(4 + 32 + 32 + 1 + 8, "landmarks")?;
        for i in 0..nl {
            let landmark = r.landmark(i, &map.keyframes)?;
            map.landmarks.push(landmark);
        }
        for (k, kf) in map.keyframes.iter().enumerate() {
            if let Some(&l) = kf.landmarks.iter().flatten().find(|&&l| l >= nl) {
                return Err(format!("keyframe {k} names landmark {l} of {nl}"));
            }
        }
        let ne = r.count(8 + 56 + 16, "edges")?;
        for i in 0..ne {
            map.edges.push(r.edge(i, nk)?);
        }
        if r.at != r.data.len() {
            return Err(format!("{} bytes after the map", r.data.len() - r.at));
        }
        Ok(map)
    }
}

impl Reader<'_> {
    /// A keyframe: time, poses, features with their landmark ties, depth sample.
    fn keyframe(&mut self) -> std::result::Result<Keyframe, String> {
        let r = self;
        let time = r.f64()?;
        let pose = r.pose()?;
        let camera = r.pose()?;
        if pose.translation.vector.norm() > MAX_COORDINATE
            || camera.translation.vector.norm() > MAX_COORDINATE
        {
            return Err(format!("a keyframe more than {MAX_COORDINATE} m away"));
        }
        let nf = r.count(36, "features")?;
        let mut descriptors = Vec::with_capacity(nf);
        let mut landmarks = Vec::with_capacity(nf);
        for _ in 0..nf {
            descriptors.push(r.descriptor()?);
            landmarks.push(r.u32()?.checked_sub(1));
        }
        let nc = r.count(15, "cloud points")?;
        let mut cloud = Vec::with_capacity(nc);
        for _ in 0..nc {
            let p = Point3::new(r.f32()?, r.f32()?, r.f32()?);
            if p.coords.norm() as f64 > MAX_COORDINATE {
                return Err(format!("a depth point more than {MAX_COORDINATE} m away"));
            }
            let c = r.take(3)?;
            cloud.push((p, [c[0], c[1], c[2]]));
        }
        Ok(Keyframe {
            time,
            pose,
            camera,
            descriptors,
            landmarks,
            cloud,
        })
    }

    /// Landmark `i`, anchored to one of `keyframes`.
    fn landmark(
        &mut self,
        i: usize,
        keyframes: &[Keyframe],
    ) -> std::result::Result<Landmark, String> {
        let r = self;
        let nk = keyframes.len();
        let keyframe = r.u32()?;
        if keyframe >= nk {
            return Err(format!(
                "landmark {i} is anchored to keyframe {keyframe} of {nk}"
            ));
        }
        let local = Point3::new(r.f64()?, r.f64()?, r.f64()?);
        let sigma = r.f64()?;
        if !(MIN_LANDMARK_SIGMA..=100.0).contains(&sigma) {
            return Err(format!("landmark {i} has a position sigma of {sigma} m"));
        }
        if local.coords.norm() > MAX_COORDINATE {
            return Err(format!("landmark {i} lies {local} m from its keyframe"));
        }
        let descriptor = r.descriptor()?;
        let level = r.take(1)?[0];
        if level > 11 {
            return Err(format!("landmark {i} is on pyramid level {level}"));
        }
        let found = r.u32()? as u32;
        let visible = r.u32()? as u32;
        let world = keyframes[keyframe].camera_pose() * local;
        Ok(Landmark {
            keyframe,
            local,
            world,
            descriptor,
            level,
            sigma,
            found,
            visible,
        })
    }

    /// Edge `i` of the pose graph, between two of `nk` keyframes.
    fn edge(&mut self, i: usize, nk: usize) -> std::result::Result<Edge, String> {
        let r = self;
        let (a, b) = (r.u32()?, r.u32()?);
        if a >= nk || b >= nk {
            return Err(format!("edge {i} joins keyframes {a} and {b} of {nk}"));
        }
        let z = r.pose()?;
        let (sigma_t, sigma_r) = (r.f64()?, r.f64()?);
        if sigma_t <= 0.0 || sigma_r <= 0.0 {
            return Err(format!("edge {i} has sigmas {sigma_t}, {sigma_r}"));
        }
        Ok(Edge {
            a,
            b,
            z,
            sigma_t,
            sigma_r,
        })
    }
}
