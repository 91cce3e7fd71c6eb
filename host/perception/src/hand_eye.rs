//! Hand-eye calibration of a camera on a robot's head against a marker on its arm: the
//! camera's mount (`head_tilt_link -> camera_link` on the LoCoBot) by least squares on the
//! marker corners' reprojection, as PyRobot's `locobot_calibration` does.
//!
//! Each view gives the mount's parent link in the robot's base frame (`head`) and the
//! marker's link there (`marker`), both from the measured joints, and the marker's corners
//! found in the image. A corner c (in the marker link's frame) is predicted at
//! `K · (head · X · L)⁻¹ · marker · c`, with X the unknown mount and L the fixed optical frame
//! in the camera link. Levenberg-Marquardt minimises the squared pixel errors over X
//! (perturbed on the right, in the camera link's frame: translation and rotation vector);
//! views with a corner beyond the inlier threshold (PyRobot: 20 px) are dropped and the fit
//! repeated. Before answering, the fit checks that the views observe every direction of X:
//! the weakest direction of the normal equations must move the corners by at least
//! [`HandEyeProblem::min_sensitivity`] px per mm (or mrad).
//!
//! Why a solver of our own: `docs/design/perception.md`.

use nalgebra::{DMatrix, DVector, Isometry3, Point3, Translation3, UnitQuaternion, Vector6};

use crate::error::{PerceptionError, Result};
use crate::intrinsics::Intrinsics;

/// One image of the marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerView {
    /// Pose of the mount's parent link (`head_tilt_link`) in the robot's base frame.
    pub head: Isometry3<f64>,
    /// Pose of the marker's link in the robot's base frame.
    pub marker: Isometry3<f64>,
    /// The marker's corners found in the image, (u, v) px, in the order of
    /// [`HandEyeProblem::corners`].
    pub corners: [[f64; 2]; 4],
}

/// What the calibration is given.
#[derive(Debug, Clone, PartialEq)]
pub struct HandEyeProblem {
    /// The camera's intrinsics.
    pub intrinsics: Intrinsics,
    /// The optical frame's pose in the camera link (fixed by the camera's make).
    pub link_to_optical: Isometry3<f64>,
    /// The marker's corners in its link's frame, m.
    pub corners: [Point3<f64>; 4],
    /// The views.
    pub views: Vec<MarkerView>,
    /// Where the fit starts: the nominal mount (camera link in the parent link).
    pub initial: Isometry3<f64>,
    /// A view with a corner farther than this from its prediction is dropped, px (PyRobot: 20).
    pub inlier_px: f64,
    /// Fewest views kept.
    pub min_views: usize,
    /// Least change of the corners, px (root-sum-square over every corner of every view), for
    /// 1 mm or 1 mrad along the worst-observed direction of the mount.
    pub min_sensitivity: f64,
}

/// What the calibration found.
#[derive(Debug, Clone, PartialEq)]
pub struct HandEyeSolution {
    /// The mount: the camera link's pose in the parent link.
    pub mount: Isometry3<f64>,
    /// Root-mean-square corner error of the kept views, px.
    pub rms_px: f64,
    /// Views kept (inliers).
    pub views: usize,
    /// Views dropped as outliers.
    pub dropped: usize,
    /// The change of the corners (px, root-sum-square) along the worst-observed direction,
    /// per mm or mrad (see [`HandEyeProblem::min_sensitivity`]).
    pub sensitivity: f64,
}

impl HandEyeProblem {
    /// The corner errors (px, u then v, per corner per view) of `views` at mount `x`; `None`
    /// if a corner falls behind the camera.
    fn residuals(&self, x: &Isometry3<f64>, views: &[MarkerView]) -> Option<DVector<f64>> {
        let k = &self.intrinsics;
        let mut r = DVector::zeros(views.len() * 8);
        for (i, v) in views.iter().enumerate() {
            let cam = (v.head * x * self.link_to_optical).inverse() * v.marker;
            for (j, c) in self.corners.iter().enumerate() {
                let (u, w) = k.project(&(cam * c))?;
                r[i * 8 + 2 * j] = u - v.corners[j][0];
                r[i * 8 + 2 * j + 1] = w - v.corners[j][1];
            }
        }
        Some(r)
    }

    /// The residuals and their Jacobian (central differences) at `x` perturbed by `delta`.
    fn jacobian(&self, x: &Isometry3<f64>, views: &[MarkerView]) -> Option<DMatrix<f64>> {
        const H: f64 = 1e-6;
        let mut j = DMatrix::zeros(views.len() * 8, 6);
        for p in 0..6 {
            let mut d = Vector6::zeros();
            d[p] = H;
            let plus = self.residuals(&(x * perturbation(&d)), views)?;
            let minus = self.residuals(&(x * perturbation(&(-d))), views)?;
            j.set_column(p, &((plus - minus) / (2.0 * H)));
        }
        Some(j)
    }

    /// Levenberg-Marquardt from `x` on `views`.
    fn fit(&self, mut x: Isometry3<f64>, views: &[MarkerView]) -> Result<Isometry3<f64>> {
        let behind = || {
            PerceptionError::HandEye(
                "a marker corner falls behind the camera at the current estimate".into(),
            )
        };
        let mut r = self.residuals(&x, views).ok_or_else(behind)?;
        let mut cost = r.norm_squared();
        let mut lambda = 1e-3;
        for _ in 0..100 {
            let j = self.jacobian(&x, views).ok_or_else(behind)?;
            let jtj = j.transpose() * &j;
            let g = j.transpose() * &r;
            let mut improved = false;
            for _ in 0..10 {
                let mut a = jtj.clone();
                for d in 0..6 {
                    a[(d, d)] += lambda * jtj[(d, d)].max(1e-9);
                }
                let Some(step) = a.cholesky().map(|c| c.solve(&(-&g))) else {
                    lambda *= 10.0;
                    continue;
                };
                let d = Vector6::from_iterator(step.iter().copied());
                let next = x * perturbation(&d);
                if let Some(rn) = self.residuals(&next, views) {
                    let c = rn.norm_squared();
                    if c < cost {
                        let converged = cost - c < 1e-12 * cost.max(1e-12) || d.norm() < 1e-12;
                        x = next;
                        r = rn;
                        cost = c;
                        lambda = (lambda / 10.0).max(1e-12);
                        improved = true;
                        if converged {
                            return Ok(x);
                        }
                        break;
                    }
                }
                lambda *= 10.0;
            }
            if !improved {
                break;
            }
        }
        Ok(x)
    }

    /// Calibrate: fit, drop views beyond the inlier threshold, fit again, check that the kept
    /// views observe the mount.
    ///
    /// Errors ([`PerceptionError::HandEye`]): fewer views than [`HandEyeProblem::min_views`]
    /// (before or after dropping outliers), views that leave a direction of the mount
    /// unobserved, a non-finite input; [`PerceptionError::Parameter`] for an inlier threshold
    /// out of (0, 1000] px.
    pub fn solve(&self) -> Result<HandEyeSolution> {
        self.check()?;
        let need = self.min_views.max(1);
        if self.views.len() < need {
            return Err(too_few(self.views.len(), "images", need));
        }
        let (x, kept) = self.fit_inliers(need)?;
        let r = self
            .residuals(&x, &kept)
            .ok_or_else(|| PerceptionError::HandEye("a corner behind the camera".into()))?;
        let j = self
            .jacobian(&x, &kept)
            .ok_or_else(|| PerceptionError::HandEye("a corner behind the camera".into()))?;
        // Per mm and mrad: the Jacobian's columns are per m and per rad.
        let jtj = (j.transpose() * &j) * 1e-6;
        let sensitivity = jtj
            .symmetric_eigenvalues()
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
            .max(0.0)
            .sqrt();
        if sensitivity.is_nan() || sensitivity < self.min_sensitivity {
            return Err(PerceptionError::HandEye(format!(
                "the {} views leave the mount poorly observed: its worst direction moves the \
                 corners by {sensitivity:.3} px per mm or mrad, need {} (more images, more \
                 spread of arm and head poses)",
                kept.len(),
                self.min_sensitivity
            )));
        }
        Ok(HandEyeSolution {
            mount: x,
            rms_px: (r.norm_squared() / (kept.len() * 4) as f64).sqrt(),
            views: kept.len(),
            dropped: self.views.len() - kept.len(),
            sensitivity,
        })
    }

    /// Checks the thresholds' ranges and that every view and the initial mount are finite.
    fn check(&self) -> Result<()> {
        if !(self.inlier_px.is_finite() && self.inlier_px > 0.0 && self.inlier_px <= 1000.0) {
            return Err(PerceptionError::Parameter {
                name: "inlier threshold",
                value: self.inlier_px,
                range: "(0, 1000] px",
            });
        }
        // A NaN would pass every sensitivity: the observability check silently off.
        if !(self.min_sensitivity.is_finite() && self.min_sensitivity >= 0.0) {
            return Err(PerceptionError::Parameter {
                name: "minimum sensitivity",
                value: self.min_sensitivity,
                range: "[0, ∞) px per mm or mrad, finite",
            });
        }
        let finite = |p: &Isometry3<f64>| {
            p.translation.vector.iter().all(|v| v.is_finite())
                && p.rotation.coords.iter().all(|v| v.is_finite())
        };
        if !self.views.iter().all(|v| {
            finite(&v.head)
                && finite(&v.marker)
                && v.corners.iter().flatten().all(|c| c.is_finite())
        }) || !finite(&self.initial)
        {
            return Err(PerceptionError::HandEye("a view is not finite".into()));
        }
        Ok(())
    }

    /// The mount fitted to every view, then again to the views within the inlier threshold
    /// until all are; the mount and the views kept (at least `need`).
    fn fit_inliers(&self, need: usize) -> Result<(Isometry3<f64>, Vec<MarkerView>)> {
        let mut x = self.fit(self.initial, &self.views)?;
        let mut kept: Vec<MarkerView> = self.views.clone();
        loop {
            let r = self
                .residuals(&x, &kept)
                .ok_or_else(|| PerceptionError::HandEye("a corner behind the camera".into()))?;
            let keep: Vec<bool> = (0..kept.len())
                .map(|i| {
                    (0..4).all(|j| {
                        (r[i * 8 + 2 * j].powi(2) + r[i * 8 + 2 * j + 1].powi(2)).sqrt()
                            <= self.inlier_px
                    })
                })
                .collect();
            if keep.iter().all(|&k| k) {
                break;
            }
            kept = kept
                .iter()
                .zip(&keep)
                .filter(|(_, &k)| k)
                .map(|(v, _)| *v)
                .collect();
            if kept.len() < need {
                return Err(too_few(
                    kept.len(),
                    "images within the inlier threshold",
                    need,
                ));
            }
            x = self.fit(x, &kept)?;
        }
        Ok((x, kept))
    }
}

/// `got` views (`what`) where at least `need` are needed.
fn too_few(got: usize, what: &str, need: usize) -> PerceptionError {
    PerceptionError::HandEye(format!("{got} {what} of the marker, need at least {need}"))
}

/// The pose of a perturbation: translation `d[0..3]` (m) and rotation vector `d[3..6]` (rad).
fn perturbation(d: &Vector6<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(d[0], d[1], d[2]),
        UnitQuaternion::from_scaled_axis(nalgebra::Vector3::new(d[3], d[4], d[5])),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn problem(truth: &Isometry3<f64>, n: usize) -> HandEyeProblem {
        let k = Intrinsics::new(640, 480, 619.9, 620.1, 320.65, 241.1).unwrap();
        let link_to_optical = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_euler_angles(
                -std::f64::consts::FRAC_PI_2,
                0.0,
                -std::f64::consts::FRAC_PI_2,
            ),
        );
        let h = 0.015;
        let corners = [[h, h], [-h, h], [-h, -h], [h, -h]].map(|[x, y]| Point3::new(x, y, 0.0));
        let mut views = Vec::new();
        for i in 0..n {
            let a = i as f64 / n as f64;
            // The head tilted down by 0.5-0.9 rad, panned ±0.3; the marker 0.4 m ahead, facing
            // up and back.
            let head = Isometry3::from_parts(
                Translation3::new(0.0, 0.0, 0.55),
                UnitQuaternion::from_euler_angles(0.0, 0.5 + 0.4 * a, 0.3 * (6.0 * a).sin()),
            );
            let marker = Isometry3::from_parts(
                Translation3::new(0.35 + 0.1 * a, 0.2 * (6.0 * a).sin(), 0.15 + 0.1 * a),
                UnitQuaternion::from_euler_angles(0.1 * a, -0.4, 0.3 * (6.0 * a).sin()),
            );
            let cam = (head * truth * link_to_optical).inverse() * marker;
            let c = corners.map(|p| {
                let (u, v) = k.project(&(cam * p)).unwrap();
                [u, v]
            });
            views.push(MarkerView {
                head,
                marker,
                corners: c,
            });
        }
        HandEyeProblem {
            intrinsics: k,
            link_to_optical,
            corners,
            views,
            initial: Isometry3::translation(0.06705, 0.0, -0.00425),
            inlier_px: 20.0,
            min_views: 3,
            min_sensitivity: 0.1,
        }
    }

    fn truth() -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(0.06705 + 0.02, -0.01, -0.00425 + 0.015),
            UnitQuaternion::from_euler_angles(0.03, -0.04, 0.05),
        )
    }

    #[test]
    fn exact_corners_give_the_mount_back_and_an_outlier_is_dropped() {
        let t = truth();
        let mut p = problem(&t, 12);
        p.views[3].corners[1][0] += 60.0;
        let s = p.solve().unwrap();
        let e = t.inverse() * s.mount;
        assert!(e.translation.vector.norm() < 1e-7, "{e}");
        assert!(e.rotation.angle() < 1e-7, "{e}");
        assert_eq!((s.views, s.dropped), (11, 1));
        assert!(s.rms_px < 1e-5, "{}", s.rms_px);
    }

    #[test]
    fn too_few_or_poorly_spread_views_are_refused() {
        let t = truth();
        let p = problem(&t, 2);
        assert!(matches!(p.solve(), Err(PerceptionError::HandEye(_))));
        let mut p = problem(&t, 1);
        p.min_views = 1;
        // One view of four corners: the depth along the view is weakly observed.
        p.min_sensitivity = 5.0;
        assert!(matches!(p.solve(), Err(PerceptionError::HandEye(_))));
        let mut p = problem(&t, 6);
        p.inlier_px = f64::NAN;
        assert!(matches!(p.solve(), Err(PerceptionError::Parameter { .. })));
        // A NaN minimum turned the observability check off: one view then passed.
        for bad in [f64::NAN, -1.0, f64::INFINITY] {
            let mut p = problem(&t, 1);
            p.min_views = 1;
            p.min_sensitivity = bad;
            assert!(
                matches!(p.solve(), Err(PerceptionError::Parameter { .. })),
                "{bad}"
            );
        }
    }
}
