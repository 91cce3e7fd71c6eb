//! The settings of [`Slam`](super::Slam) and their checks: sensor noise (px), depth ranges
//! and keyframe spacing (m, rad), the odometry's error model.

use crate::error::{Error, Result};
use crate::optimise::Dof;
use crate::orb::OrbSettings;

/// Settings of [`Slam`](super::Slam).
#[derive(Debug, Clone, PartialEq)]
pub struct SlamSettings {
    /// Which motions are estimated: [`Dof::Planar`] for a ground robot, [`Dof::Free`] for a
    /// hand-held camera.
    pub dof: Dof,
    /// The feature extractor's settings.
    pub orb: OrbSettings,
    /// The depth sensor's baseline, m (D435: 0.05).
    pub baseline: f64,
    /// Standard deviation of a feature's position, px at full resolution.
    pub sigma_px: f64,
    /// Standard deviation of a feature's disparity `fx b / z`, px.
    pub sigma_disparity: f64,
    /// Depths that make features, m.
    pub depth_range: [f64; 2],
    /// Farthest depth that makes new landmarks and dense map points, m.
    pub map_depth: f64,
    /// Points within this radius (m) of the body's z axis are the robot itself: dropped.
    pub self_radius: f64,
    /// A new keyframe after this much travel, m ...
    pub keyframe_distance: f64,
    /// ... or this much turn, rad.
    pub keyframe_angle: f64,
    /// Fewest inlier matches that make a pose, 6 to [`MAX_INLIERS`].
    pub min_inliers: usize,
    /// Keyframes older than this many are "old": seeing many of their landmarks closes a loop;
    /// 1 to [`MAX_LOOP_AGE`].
    pub loop_age: usize,
    /// Odometry's error per metre driven (fraction) and per radian turned (fraction).
    pub odometry_drift: [f64; 2],
    /// How far tracking may stray from where the wheels put the body (carried from the last
    /// pose that agreed with them) before the matches are asked whether some of them moved
    /// with the robot: the standard deviation of that prediction's error, m and rad as a floor
    /// (the pose's own noise and the odometry's timing) and a fraction of the distance driven
    /// and the angle turned.
    pub odometry_agreement: [f64; 2],
    /// Pixel stride of the depth sample kept per keyframe for the dense maps.
    pub cloud_stride: usize,
}

impl SlamSettings {
    /// For a ground robot with a D435 (planar, the body masked within `self_radius` m).
    pub fn ground_robot(self_radius: f64) -> Self {
        SlamSettings {
            dof: Dof::Planar,
            self_radius,
            ..Self::handheld()
        }
    }

    /// For a hand-held RGB-D camera (all six motions, nothing masked).
    pub fn handheld() -> Self {
        SlamSettings {
            dof: Dof::Free,
            orb: OrbSettings::default(),
            baseline: 0.05,
            sigma_px: 1.0,
            sigma_disparity: 0.2,
            depth_range: [0.3, 4.0],
            map_depth: 3.0,
            self_radius: 0.0,
            keyframe_distance: 0.25,
            keyframe_angle: 0.35,
            min_inliers: 25,
            loop_age: 15,
            odometry_drift: [0.2, 0.2],
            odometry_agreement: [0.006, 0.05],
            cloud_stride: 4,
        }
    }

    pub(super) fn check(&self) -> Result<()> {
        let bad = |why: String| Err(Error::InvalidSettings { why });
        let pos = |x: f64| x.is_finite() && x > 0.0;
        if !(pos(self.baseline) && pos(self.sigma_px) && pos(self.sigma_disparity)) {
            return bad("baseline and sigmas must be finite and positive".into());
        }
        let [a, b] = self.depth_range;
        if !(a.is_finite() && b.is_finite() && 0.0 < a && a < b && b <= 100.0) {
            return bad(format!("depth range {a}..{b} m is not within (0, 100] m"));
        }
        if !(pos(self.map_depth) && self.self_radius.is_finite() && self.self_radius >= 0.0) {
            return bad("map depth and self radius must be finite (positive, non-negative)".into());
        }
        if !(pos(self.keyframe_distance) && pos(self.keyframe_angle)) {
            return bad("keyframe spacing must be finite and positive".into());
        }
        if !(6..=MAX_INLIERS).contains(&self.min_inliers)
            || self.cloud_stride == 0
            || self.cloud_stride > 64
        {
            return bad(format!(
                "min_inliers must be in 6..={MAX_INLIERS} and cloud_stride in 1..=64"
            ));
        }
        // A loop needs keyframes older than the ones tracking sees: at 0 every keyframe would
        // be old, and every frame would close a loop with its neighbours.
        if !(1..=MAX_LOOP_AGE).contains(&self.loop_age) {
            return bad(format!("loop_age must be in 1..={MAX_LOOP_AGE} keyframes"));
        }
        if !self.odometry_drift.iter().all(|&x| pos(x))
            || !self.odometry_agreement.iter().all(|&x| pos(x))
        {
            return bad("odometry drift must be finite and positive".into());
        }
        Ok(())
    }
}

/// Largest [`SlamSettings::min_inliers`]: far more than any frame's features (a multiple of
/// it is compared with feature counts).
pub const MAX_INLIERS: usize = 100_000;
/// Largest [`SlamSettings::loop_age`], keyframes.
pub const MAX_LOOP_AGE: usize = 100_000;
