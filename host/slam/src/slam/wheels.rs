//! The wheels' word on the camera's: where the odometry since the last anchor (a pose that
//! agreed with it) puts the body, with its error (m, rad); whether a pose agrees with it; the
//! pose from the matches seen where the wheels put them; relocalisations the wheels refuse.

use nalgebra::Isometry3;

use super::Slam;
use crate::frame::FrameFeatures;
use crate::optimise::{chi2, optimise_pose, planar, to_planar, Observation, PlanarPrior, CHI2_3};

/// Tracking agrees with the wheels when it lies within this many of their standard
/// deviations ([`SlamSettings::odometry_agreement`](super::SlamSettings::odometry_agreement)) of where they put the body.
const AGREEMENT: f64 = 3.0;

/// For this many frames after tracking is lost the wheels' pose is trusted over a
/// relocalisation's (about a third of a second at 30 Hz).
const WHEELS_TRUSTED: usize = 10;

/// A match agrees with the wheels when seen where their pose puts it, give or take this many
/// of their standard deviations.
const WITHIN: f64 = 2.0;

/// Whether planar pose `b` lies within [`AGREEMENT`] standard deviations `sigma` (m, rad) of `a`.
pub(super) fn agrees(a: &Isometry3<f64>, b: &Isometry3<f64>, sigma: [f64; 2]) -> bool {
    within(a, b, sigma, AGREEMENT)
}

/// Whether planar pose `b` lies within `k` standard deviations `sigma` (m, rad) of `a`.
fn within(a: &Isometry3<f64>, b: &Isometry3<f64>, sigma: [f64; 2], k: f64) -> bool {
    let [x, y, th] = to_planar(&(a.inverse() * b));
    x.hypot(y) <= k * sigma[0] && th.abs() <= k * sigma[1]
}

/// A pose found from the matches that agree with the wheels: the pose, the matches
/// `(feature, landmark)`, each one's verdict and the inlier count.
type Agreeing = (Isometry3<f64>, Vec<(usize, usize)>, Vec<bool>, usize);

impl Slam {
    /// Makes `pose` (at `odometry`) the anchor the wheels' word is measured from: when
    /// `force`d, when it agrees closely with the wheels (within one standard deviation), or
    /// when it lies beyond their word (a relocalisation after a kidnap). A pose between those
    /// is not: the anchor stays, so a drag by something moving with the robot, each step
    /// within the wheels' error, still adds up against it.
    pub(super) fn rebase(&mut self, pose: Isometry3<f64>, odometry: Option<[f64; 3]>, force: bool) {
        let Some(now) = odometry else {
            self.anchor = None;
            return;
        };
        let keep = !force
            && self.wheels_pose(Some(now)).is_some_and(|(w, sigma)| {
                !within(&w, &pose, sigma, 1.0) && agrees(&w, &pose, sigma)
            });
        if !keep {
            self.anchor = Some((pose, now));
        }
    }

    /// Where the wheels put the body now: the anchor moved by the odometry since, with the
    /// standard deviations (m, rad) of that prediction's error.
    pub(super) fn wheels_pose(
        &self,
        odometry: Option<[f64; 3]>,
    ) -> Option<(Isometry3<f64>, [f64; 2])> {
        let (at, then) = self.anchor?;
        self.carried(at, then, odometry?)
    }

    /// Pose `at` (odometry `then`) carried by the odometry to `now`, with the standard
    /// deviations (m, rad) of the carried pose's error.
    fn carried(
        &self,
        at: Isometry3<f64>,
        then: [f64; 3],
        now: [f64; 3],
    ) -> Option<(Isometry3<f64>, [f64; 2])> {
        let d = planar(then).inverse() * planar(now);
        let [dx, dy, dth] = to_planar(&d);
        let dist = dx.hypot(dy);
        let [floor, f] = self.settings.odometry_agreement;
        Some((
            at * d,
            [floor + f * dist, floor + f * dth.abs() + 0.01 * dist],
        ))
    }

    /// Notes a relocalised pose the wheels refused (`pose`, at odometry `odometry`); returns
    /// whether the wheels' motion since the first one refused this time contradicts it (it
    /// is on something that moved with the robot, so the wheels are right).
    pub(super) fn refuse(&mut self, pose: Isometry3<f64>, odometry: Option<[f64; 3]>) -> bool {
        let Some(now) = odometry else {
            return false;
        };
        match self.refused {
            None => {
                self.refused = Some((pose, now));
                false
            }
            Some((first, then)) => self
                .carried(first, then, now)
                .is_some_and(|(p, sigma)| !agrees(&p, &pose, sigma)),
        }
    }

    /// The pose from the matches that agree with the wheels' pose `wheels`: the landmarks
    /// searched for where it puts them (within `radius` px), kept when seen there give or
    /// take its error `sigma` (m, rad), the pose refined on them with the wheels as a prior.
    /// Returns the pose, the matches, each one's verdict and the inlier count; `None` when too
    /// few agree or their pose strays from the wheels' as well.
    pub(super) fn pose_agreeing(
        &mut self,
        feats: &FrameFeatures,
        t_bc: &Isometry3<f64>,
        wheels: &Isometry3<f64>,
        sigma: [f64; 2],
        radius: f64,
    ) -> Option<Agreeing> {
        let matches = self.search_local(feats, wheels, t_bc, radius);
        let obs = self.observations(feats, &matches);
        let fb = self.cam.fx * self.cam.baseline;
        let agreeing: Vec<usize> = obs
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                let z = fb / o.measured.z;
                let px = self.cam.fx * WITHIN * (sigma[1] + sigma[0] / z);
                let disparity = fb * WITHIN * sigma[0] / (z * z);
                let wide = Observation {
                    sigma_px: o.sigma_px.hypot(px),
                    sigma_disparity: o.sigma_disparity.hypot(disparity),
                    ..**o
                };
                chi2(&self.cam, wheels, t_bc, &wide) <= CHI2_3
            })
            .map(|(i, _)| i)
            .collect();
        if agreeing.len() < self.settings.min_inliers {
            return None;
        }
        let sub: Vec<Observation> = agreeing.iter().map(|&i| obs[i]).collect();
        let prior = PlanarPrior {
            pose: *wheels,
            sigma: [sigma[0], sigma[0], sigma[1]],
        };
        let mut pose = *wheels;
        let mut ok = Vec::new();
        let n = optimise_pose(
            &self.cam,
            &mut pose,
            t_bc,
            &sub,
            self.settings.dof,
            Some(&prior),
            &mut ok,
        );
        if n < self.settings.min_inliers || !agrees(wheels, &pose, sigma) {
            return None;
        }
        let mut all = vec![false; obs.len()];
        for (&i, &good) in agreeing.iter().zip(&ok) {
            all[i] = good;
        }
        Some((pose, matches, all, n))
    }

    /// The wheels' pose while it is still trusted over a relocalisation's: for the first
    /// [`WHEELS_TRUSTED`] frames lost. (A relocalisation far from it then is more likely on
    /// something the robot moved than a kidnap; a kidnapped robot stays lost longer.)
    pub(super) fn trusted(
        &self,
        wheels: Option<(Isometry3<f64>, [f64; 2])>,
    ) -> Option<(Isometry3<f64>, [f64; 2])> {
        wheels.filter(|_| self.lost < WHEELS_TRUSTED)
    }
}
