//! The sparse map: keyframes (their poses, features and a sample of their depth) and the
//! landmarks they anchor. A landmark lives in its anchor keyframe's camera frame, so moving
//! keyframes (loop closure) moves their landmarks and dense points with them.

use nalgebra::{Isometry3, Point3};

use crate::orb::Descriptor;

/// A keyframe.
#[derive(Debug, Clone)]
pub struct Keyframe {
    /// Time of its frame, s.
    pub time: f64,
    /// Pose of the body in the world.
    pub pose: Isometry3<f64>,
    /// Pose of the camera's optical frame in the body.
    pub camera: Isometry3<f64>,
    /// Descriptors of its features with depth.
    pub(crate) descriptors: Vec<Descriptor>,
    /// The landmark each feature is, when it is one.
    pub(crate) landmarks: Vec<Option<usize>>,
    /// A sample of the depth image: points in the optical frame (m) and colours.
    pub(crate) cloud: Vec<(Point3<f32>, [u8; 3])>,
}

impl Keyframe {
    /// Pose of the optical frame in the world.
    pub fn camera_pose(&self) -> Isometry3<f64> {
        self.pose * self.camera
    }
}

/// A landmark's position is never trusted beyond this, m (its fused measurements' errors are
/// not all independent).
pub(crate) const MIN_LANDMARK_SIGMA: f64 = 0.001;

/// A landmark: a 3-D point with the descriptor it was first seen with.
#[derive(Debug, Clone)]
pub(crate) struct Landmark {
    /// Its anchor keyframe.
    pub keyframe: usize,
    /// The point in the anchor's optical frame, m.
    pub local: Point3<f64>,
    /// The point in the world, m (kept in step with the anchor's pose).
    pub world: Point3<f64>,
    pub descriptor: Descriptor,
    /// Pyramid level it was found on.
    pub level: u8,
    /// Standard deviation of its position, m (from the depths it was measured at).
    pub sigma: f64,
    /// Frames that looked for it and found it.
    pub found: u32,
    /// Frames that looked for it.
    pub visible: u32,
}

/// Keyframes, the landmarks they anchor, and the pose graph's edges between keyframes.
#[derive(Debug, Clone, Default)]
pub struct Map {
    pub(crate) keyframes: Vec<Keyframe>,
    pub(crate) landmarks: Vec<Landmark>,
    pub(crate) edges: Vec<crate::optimise::Edge>,
}

impl Map {
    /// The keyframes, oldest first.
    pub fn keyframes(&self) -> &[Keyframe] {
        &self.keyframes
    }

    /// Number of landmarks.
    pub fn landmark_count(&self) -> usize {
        self.landmarks.len()
    }

    /// Landmarks' world positions from their anchors' poses (after the poses moved).
    pub(crate) fn refresh_landmarks(&mut self) {
        for l in &mut self.landmarks {
            let kf = &self.keyframes[l.keyframe];
            l.world = kf.camera_pose() * l.local;
        }
    }

    /// The keyframes whose camera is within `radius` m of `position` and looks within
    /// `max_angle` rad of `direction` (a unit vector in the world), nearest first.
    pub(crate) fn keyframes_near(
        &self,
        camera: &Isometry3<f64>,
        radius: f64,
        max_angle: f64,
    ) -> Vec<usize> {
        let pos = camera.translation.vector;
        let dir = camera.rotation * nalgebra::Vector3::z();
        let cos = max_angle.cos();
        let mut v: Vec<(f64, usize)> = self
            .keyframes
            .iter()
            .enumerate()
            .filter_map(|(i, kf)| {
                let c = kf.camera_pose();
                let d = (c.translation.vector - pos).norm();
                let look = (c.rotation * nalgebra::Vector3::z()).dot(&dir);
                (d <= radius && look >= cos).then_some((d, i))
            })
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        v.into_iter().map(|(_, i)| i).collect()
    }
}
