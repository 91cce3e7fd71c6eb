//! Inverse kinematics behind one trait, so that a weak solver can be swapped for a better one.
//!
//! [`NumericalIk`] works for any chain: damped least squares with Levenberg-Marquardt damping
//! on the full 6-D pose error (position in m, orientation as the rotation vector of the
//! remaining rotation, rad), joint limits enforced by clamping, random restarts within the
//! limits until a time budget runs out; why it is written here: `docs/design/kinematics.md`.

use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Matrix6, Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{Chain, JointType};
use crate::error::{Error, Result, ValueError};

/// Most joints the numerical solver handles.
pub const MAX_DOF: usize = 8;

/// [`IkOptions::attempts`] by default: about 5 ms of descents on an unreachable target for
/// the Sawyer (release build, 2026 desktop core; TRAC-IK's budget), and more than the
/// 10,000 random reachable poses of the `kinematics` benchmark needed.
pub const DEFAULT_ATTEMPTS: u32 = 200;

/// Tolerances and budget of one IK query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    /// Position tolerance, m.
    pub position_tolerance: f64,
    /// Orientation tolerance, rad.
    pub orientation_tolerance: f64,
    /// Give up after this long (wall-clock time), or after [`IkOptions::attempts`], whichever
    /// comes first. By default 1 s, a cap for a stalled machine rather than the budget: an
    /// answer the timeout cut short depends on the machine's speed and load.
    pub timeout: Duration,
    /// Most descents: the first from the seed, the others from random restarts. Within this
    /// budget the answer depends on the target, the seed and [`IkOptions::seed`] alone.
    pub attempts: u32,
    /// Seed of the restarts (same seed, same answer).
    pub seed: u64,
}

impl Default for IkOptions {
    fn default() -> Self {
        Self {
            position_tolerance: 1e-5,
            orientation_tolerance: 1e-5,
            timeout: Duration::from_secs(1),
            attempts: DEFAULT_ATTEMPTS,
            seed: 0x5eed,
        }
    }
}

/// An IK solver.
pub trait IkSolver: Send + Sync {
    /// Joint values (rad or m, chain order) that put the chain's tip at `target` (base frame),
    /// preferring a solution near `seed` when given. The request is validated first
    /// ([`check_request`]), for every solver, then handed to [`IkSolver::solve_valid`].
    fn solve(
        &self,
        chain: &Chain,
        target: &Isometry3<f64>,
        seed: Option<&[f64]>,
        opts: &IkOptions,
    ) -> Result<Vec<f64>> {
        check_request(chain, target, seed, opts)?;
        self.solve_valid(chain, target, seed, opts)
    }

    /// [`IkSolver::solve`] for a request that has passed [`check_request`].
    fn solve_valid(
        &self,
        chain: &Chain,
        target: &Isometry3<f64>,
        seed: Option<&[f64]>,
        opts: &IkOptions,
    ) -> Result<Vec<f64>>;
}

/// Validate an IK request: a target within ±[`ferrobot_geometry::validate::MAX_ARM_REACH`] m with a finite
/// unit rotation, a seed (when given) of one finite angle per joint within
/// ±[`ferrobot_geometry::validate::MAX_ANGLE`], tolerances in `[1e-12, 1]`, at least one attempt
/// and a timeout of at most 10 s.
/// Every solver calls it first.
pub fn check_request(
    chain: &Chain,
    target: &Isometry3<f64>,
    seed: Option<&[f64]>,
    opts: &IkOptions,
) -> Result<()> {
    let t = target.translation.vector;
    ferrobot_geometry::validate::arm_point("IK target position", [t.x, t.y, t.z])?;
    let q = target.rotation.coords;
    ferrobot_geometry::validate::unit_quaternion([q.x, q.y, q.z, q.w])?;
    check_seed(chain, seed)?;
    ferrobot_geometry::validate::in_range(
        "IK position tolerance",
        opts.position_tolerance,
        1e-12,
        1.0,
    )?;
    ferrobot_geometry::validate::in_range(
        "IK orientation tolerance",
        opts.orientation_tolerance,
        1e-12,
        1.0,
    )?;
    if opts.attempts == 0 {
        return Err(ValueError::OutOfRange {
            what: "IK attempts".into(),
            value: 0.0,
            min: 1.0,
            max: f64::from(u32::MAX),
        }
        .into());
    }
    if opts.timeout > Duration::from_secs(10) {
        return Err(ValueError::OutOfRange {
            what: "IK timeout".into(),
            value: opts.timeout.as_secs_f64(),
            min: 0.0,
            max: 10.0,
        }
        .into());
    }
    Ok(())
}

/// A seed, when given: one finite angle per joint within ±[`ferrobot_geometry::validate::MAX_ANGLE`].
pub fn check_seed(chain: &Chain, seed: Option<&[f64]>) -> Result<()> {
    if let Some(s) = seed {
        ferrobot_geometry::validate::length("IK seed", s.len(), chain.dof())?;
        ferrobot_geometry::validate::angles("IK seed", s)?;
    }
    Ok(())
}

/// Pose error (position, rotation vector) of `current` against `target`, base frame.
pub fn pose_error(target: &Isometry3<f64>, current: &Isometry3<f64>) -> Vector6<f64> {
    let p = target.translation.vector - current.translation.vector;
    let r = (target.rotation * current.rotation.inverse()).scaled_axis();
    Vector6::new(p.x, p.y, p.z, r.x, r.y, r.z)
}

/// Damped least squares with Levenberg-Marquardt damping and random restarts.
#[derive(Debug, Clone, Copy, Default)]
pub struct NumericalIk;

struct Work {
    axes: [(Vector3<f64>, Vector3<f64>); MAX_DOF],
    jac: [[f64; MAX_DOF]; 6],
}

impl NumericalIk {
    fn jacobian_and_error(
        chain: &Chain,
        q: &[f64],
        target: &Isometry3<f64>,
        w: &mut Work,
    ) -> Vector6<f64> {
        let n = chain.dof();
        let tip = chain.fk_with_axes(q, &mut w.axes[..n]);
        let p = tip.translation.vector;
        for (c, (j, (z, o))) in chain.joints.iter().zip(&w.axes[..n]).enumerate() {
            let (v, a) = match j.kind {
                JointType::Revolute => (z.cross(&(p - o)), *z),
                JointType::Prismatic => (*z, Vector3::zeros()),
            };
            for r in 0..3 {
                w.jac[r][c] = v[r];
                w.jac[r + 3][c] = a[r];
            }
        }
        pose_error(target, &tip)
    }

    fn converged(e: &Vector6<f64>, opts: &IkOptions) -> bool {
        e.fixed_rows::<3>(0).norm() <= opts.position_tolerance
            && e.fixed_rows::<3>(3).norm() <= opts.orientation_tolerance
    }

    /// One descent from `q`; returns whether it converged.
    fn descend(
        chain: &Chain,
        target: &Isometry3<f64>,
        q: &mut [f64],
        opts: &IkOptions,
        w: &mut Work,
        deadline: Instant,
    ) -> bool {
        let n = chain.dof();
        let mut e = Self::jacobian_and_error(chain, q, target, w);
        let mut cost = e.norm_squared();
        let mut lambda = 1e-3;
        let mut trial = [0.0; MAX_DOF];
        let mut stale = 0;
        for it in 0..100 {
            if Self::converged(&e, opts) {
                return true;
            }
            if it % 16 == 15 && Instant::now() > deadline {
                return false;
            }
            // (J Jᵀ + λ I) x = e;  Δq = Jᵀ x.
            let mut a = Matrix6::<f64>::zeros();
            for r in 0..6 {
                for c in r..6 {
                    let mut s = 0.0;
                    for k in 0..n {
                        s += w.jac[r][k] * w.jac[c][k];
                    }
                    a[(r, c)] = s;
                    a[(c, r)] = s;
                }
                a[(r, r)] += lambda;
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let x = chol.solve(&e);
            for (k, (t, j)) in trial[..n].iter_mut().zip(&chain.joints).enumerate() {
                let mut dq = 0.0;
                for r in 0..6 {
                    dq += w.jac[r][k] * x[r];
                }
                *t = (q[k] + dq).clamp(j.lower, j.upper);
            }
            let saved = w.jac;
            let e_new = Self::jacobian_and_error(chain, &trial[..n], target, w);
            let c_new = e_new.norm_squared();
            if c_new < cost {
                q[..n].copy_from_slice(&trial[..n]);
                stale = if c_new > 0.9 * cost { stale + 1 } else { 0 };
                e = e_new;
                cost = c_new;
                lambda = (lambda * 0.3).max(1e-12);
            } else {
                w.jac = saved;
                lambda *= 8.0;
                stale += 1;
            }
            if stale > 12 || lambda > 1e6 {
                return Self::converged(&e, opts);
            }
        }
        Self::converged(&e, opts)
    }
}

impl IkSolver for NumericalIk {
    fn solve_valid(
        &self,
        chain: &Chain,
        target: &Isometry3<f64>,
        seed: Option<&[f64]>,
        opts: &IkOptions,
    ) -> Result<Vec<f64>> {
        let n = chain.dof();
        if n == 0 || n > MAX_DOF {
            return Err(Error::Unreachable {
                why: format!(
                    "the numerical solver handles 1 to {MAX_DOF} joints, the chain has {n}"
                ),
            });
        }
        if let Some(j) = chain
            .joints
            .iter()
            .find(|j| !(j.lower.is_finite() && j.upper.is_finite() && j.lower <= j.upper))
        {
            return Err(Error::Unreachable {
                why: format!(
                    "joint {} has limits [{}, {}]: the solver needs finite limits, lower first",
                    j.name, j.lower, j.upper
                ),
            });
        }
        let start = Instant::now();
        let deadline = start + opts.timeout;
        let mut w = Work {
            axes: [(Vector3::zeros(), Vector3::zeros()); MAX_DOF],
            jac: [[0.0; MAX_DOF]; 6],
        };
        let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
        let mut q = [0.0; MAX_DOF];
        match seed {
            Some(s) => {
                for (k, j) in chain.joints.iter().enumerate() {
                    q[k] = s.get(k).copied().unwrap_or(0.0).clamp(j.lower, j.upper);
                }
            }
            None => {
                for (k, j) in chain.joints.iter().enumerate() {
                    q[k] = 0.0f64.clamp(j.lower, j.upper);
                }
            }
        }
        let mut attempts = 0u32;
        loop {
            attempts += 1;
            if Self::descend(chain, target, &mut q, opts, &mut w, deadline) {
                return Ok(q[..n].to_vec());
            }
            if attempts >= opts.attempts || Instant::now() >= deadline {
                let e = pose_error(target, &chain.fk(&q[..n]));
                return Err(Error::Unreachable {
                    why: format!(
                        "no solution within {:?} or {} attempts ({attempts} made); last remaining error {:.2e} m, {:.2e} rad",
                        opts.timeout,
                        opts.attempts,
                        e.fixed_rows::<3>(0).norm(),
                        e.fixed_rows::<3>(3).norm()
                    ),
                });
            }
            for (k, j) in chain.joints.iter().enumerate() {
                q[k] = rng.random_range(j.lower..=j.upper);
            }
        }
    }
}
