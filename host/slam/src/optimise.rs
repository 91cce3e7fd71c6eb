//! Least squares on poses: the pose of one frame from its matched landmarks (reprojection and
//! disparity errors, robust, with an optional odometry prior), and a pose graph of keyframes.
//!
//! Poses are of the body (`base_link` for a robot, the camera itself for a hand-held
//! sequence) in the world; perturbations act on the right, in the body's frame, through a
//! [`Dof`] basis: the three planar ones of a ground robot (x, y, yaw) or all six.
//!
//! Why a solver of our own: `docs/design/slam.md`.

use nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3, Vector6,
};

/// Which motions of the body are estimated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dof {
    /// A ground robot: x, y and yaw in the world's floor plane (z, roll and pitch stay).
    Planar,
    /// A free camera: three translations and three rotations.
    Free,
}

impl Dof {
    /// Number of unknowns.
    pub fn count(self) -> usize {
        match self {
            Dof::Planar => 3,
            Dof::Free => 6,
        }
    }

    /// The body twist `[v; ω]` of the unknowns `d`.
    fn twist(self, d: &[f64]) -> Vector6<f64> {
        match self {
            Dof::Planar => Vector6::new(d[0], d[1], 0.0, 0.0, 0.0, d[2]),
            Dof::Free => Vector6::from_column_slice(d),
        }
    }

    /// The columns of the twist the unknowns move.
    fn columns(self) -> &'static [usize] {
        match self {
            Dof::Planar => &[0, 1, 5],
            Dof::Free => &[0, 1, 2, 3, 4, 5],
        }
    }
}

/// `T · exp(ξ)` for a body twist ξ = `[v; ω]` (rotation by the rotation vector ω, then the
/// translation v: a first-order retraction, exact enough for the small steps of a solver).
pub fn retract(t: &Isometry3<f64>, xi: &Vector6<f64>) -> Isometry3<f64> {
    let d = Isometry3::from_parts(
        Translation3::new(xi[0], xi[1], xi[2]),
        UnitQuaternion::from_scaled_axis(Vector3::new(xi[3], xi[4], xi[5])),
    );
    t * d
}

/// The twist `[v; ω]` of a small transform (its translation and rotation vector).
pub fn log(t: &Isometry3<f64>) -> Vector6<f64> {
    let w = t.rotation.scaled_axis();
    Vector6::new(
        t.translation.x,
        t.translation.y,
        t.translation.z,
        w.x,
        w.y,
        w.z,
    )
}

/// Whether every number of `t` is finite and its rotation a unit quaternion (to 1e-6): a
/// pose a solver may keep.
pub fn is_sound(t: &Isometry3<f64>) -> bool {
    t.translation.vector.iter().all(|x| x.is_finite())
        && t.rotation.coords.iter().all(|x| x.is_finite())
        && (t.rotation.coords.norm() - 1.0).abs() < 1e-6
}

/// `t` with its rotation made a unit quaternion again: many compositions of unit quaternions
/// drift from unit length (a pose composed with itself frame after frame shrinks to zero).
pub fn renormalised(t: &Isometry3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        t.translation,
        UnitQuaternion::new_normalize(*t.rotation.quaternion()),
    )
}

/// A planar pose `[x, y, θ]` (m, rad) as an isometry at height 0.
pub fn planar(p: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p[0], p[1], 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), p[2]),
    )
}

/// The planar pose `[x, y, θ]` of an isometry (its yaw about the world's z).
pub fn to_planar(t: &Isometry3<f64>) -> [f64; 3] {
    let r = t.rotation.to_rotation_matrix();
    let m = r.matrix();
    [t.translation.x, t.translation.y, m[(1, 0)].atan2(m[(0, 0)])]
}

/// The camera model the pose solver projects with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    /// Focal lengths and principal point, px.
    pub fx: f64,
    /// Focal length y, px.
    pub fy: f64,
    /// Principal point x, px.
    pub cx: f64,
    /// Principal point y, px.
    pub cy: f64,
    /// The depth sensor's stereo baseline, m: depth z is compared as disparity `fx b / z`, whose
    /// error does not grow with distance.
    pub baseline: f64,
}

/// A landmark seen in the frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// The landmark in the world, m.
    pub point: Point3<f64>,
    /// Where it was seen: column, row (px) and disparity `fx b / z` (px).
    pub measured: Vector3<f64>,
    /// Standard deviation of the pixel position, px.
    pub sigma_px: f64,
    /// Standard deviation of the disparity, px.
    pub sigma_disparity: f64,
}

/// The wheel odometry's word on a planar pose: the predicted pose and the standard deviations of
/// its x, y (m) and yaw (rad) error in the body frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarPrior {
    /// The predicted body pose in the world.
    pub pose: Isometry3<f64>,
    /// σ of x, y (m) and yaw (rad).
    pub sigma: [f64; 3],
}

/// χ² of three degrees of freedom at 95 %: a reprojection-and-disparity error beyond it is an
/// outlier (ORB-SLAM2's threshold for RGB-D).
pub const CHI2_3: f64 = 7.815;

/// The predicted measurement (u, v, disparity) of `p` (world) seen from body pose `t_wb` with
/// camera `t_bc`, and its Jacobian with respect to the body twist; `None` behind the camera.
fn project(
    cam: &Pinhole,
    t_wb: &Isometry3<f64>,
    t_bc: &Isometry3<f64>,
    p: &Point3<f64>,
) -> Option<(Vector3<f64>, nalgebra::Matrix3x6<f64>)> {
    let pb = t_wb.inverse_transform_point(p);
    let pc = t_bc.inverse_transform_point(&pb);
    if pc.z < 1e-3 {
        return None;
    }
    let iz = 1.0 / pc.z;
    let pred = Vector3::new(
        cam.fx * pc.x * iz + cam.cx,
        cam.fy * pc.y * iz + cam.cy,
        cam.fx * cam.baseline * iz,
    );
    let dproj = Matrix3::new(
        cam.fx * iz,
        0.0,
        -cam.fx * pc.x * iz * iz,
        0.0,
        cam.fy * iz,
        -cam.fy * pc.y * iz * iz,
        0.0,
        0.0,
        -cam.fx * cam.baseline * iz * iz,
    );
    // p_b' = exp(-ξ) p_b ≈ p_b - v + [p_b]× ω.
    let r_cb = t_bc.rotation.inverse().to_rotation_matrix();
    let mut dpb = nalgebra::Matrix3x6::zeros();
    dpb.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-Matrix3::identity()));
    dpb.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&pb.coords.cross_matrix());
    Some((pred, dproj * r_cb.matrix() * dpb))
}

/// The normalised error (χ²) of one observation at `t_wb`; infinite behind the camera.
pub fn chi2(cam: &Pinhole, t_wb: &Isometry3<f64>, t_bc: &Isometry3<f64>, o: &Observation) -> f64 {
    match project(cam, t_wb, t_bc, &o.point) {
        Some((pred, _)) => {
            let r = o.measured - pred;
            (r.x / o.sigma_px).powi(2)
                + (r.y / o.sigma_px).powi(2)
                + (r.z / o.sigma_disparity).powi(2)
        }
        None => f64::INFINITY,
    }
}

/// Refines the body pose `t_wb` from `obs` (Huber-weighted, four rounds that set aside the
/// observations beyond [`CHI2_3`] and look at them again), with the odometry `prior` when
/// given. Marks each observation's verdict in `inlier` and returns the number of inliers.
pub fn optimise_pose(
    cam: &Pinhole,
    t_wb: &mut Isometry3<f64>,
    t_bc: &Isometry3<f64>,
    obs: &[Observation],
    dof: Dof,
    prior: Option<&PlanarPrior>,
    inlier: &mut Vec<bool>,
) -> usize {
    inlier.clear();
    inlier.resize(obs.len(), true);
    let n = dof.count();
    // Each observation measures three numbers; too few leave the pose undetermined.
    if 3 * obs.len() < 2 * n {
        inlier.iter_mut().for_each(|b| *b = false);
        return 0;
    }
    let start = *t_wb;
    for round in 0..4 {
        for _ in 0..if round == 0 { 10 } else { 5 } {
            if !pose_step(cam, t_wb, t_bc, obs, dof, prior, inlier) {
                break;
            }
        }
        // Verdicts of every observation at the new pose.
        let mut changed = false;
        for (o, ok) in obs.iter().zip(inlier.iter_mut()) {
            let good = chi2(cam, t_wb, t_bc, o) <= CHI2_3;
            changed |= good != *ok;
            *ok = good;
        }
        if !changed && round > 0 {
            break;
        }
    }
    // Keep the rotation a unit quaternion despite the rounding of many small steps.
    *t_wb = renormalised(t_wb);
    if !is_sound(t_wb) {
        *t_wb = start;
        inlier.iter_mut().for_each(|b| *b = false);
        return 0;
    }
    inlier.iter().filter(|&&b| b).count()
}

/// One Gauss-Newton step of [`optimise_pose`] on the observations marked `inlier` (and the
/// `prior`), capped at 0.5 m or rad; false when none can be taken or it was below 1e-9.
fn pose_step(
    cam: &Pinhole,
    t_wb: &mut Isometry3<f64>,
    t_bc: &Isometry3<f64>,
    obs: &[Observation],
    dof: Dof,
    prior: Option<&PlanarPrior>,
    inlier: &[bool],
) -> bool {
    let n = dof.count();
    let mut h = DMatrix::<f64>::zeros(n, n);
    let mut g = DVector::<f64>::zeros(n);
    add_observations(cam, t_wb, t_bc, obs, dof, inlier, &mut h, &mut g);
    if let Some(p) = prior {
        add_prior(p, t_wb, dof, &mut h, &mut g);
    }
    for i in 0..n {
        h[(i, i)] *= 1.0 + 1e-6;
        h[(i, i)] += 1e-9;
    }
    let Some(ch) = h.cholesky() else {
        return false;
    };
    let mut d = ch.solve(&g);
    // A step beyond 0.5 (m or rad) is an ill-posed system's, not a correction: cap it.
    let norm = d.norm();
    if !norm.is_finite() {
        return false;
    }
    if norm > 0.5 {
        d *= 0.5 / norm;
    }
    // r = z - h(x) and J is of h: the step is +H⁻¹ Jᵀ r.
    *t_wb = retract(t_wb, &dof.twist(d.as_slice()));
    d.norm() >= 1e-9
}

/// Adds the Huber-weighted normal equations `h`, `g` of the observations marked `inlier` at
/// `t_wb`.
#[allow(clippy::too_many_arguments)]
fn add_observations(
    cam: &Pinhole,
    t_wb: &Isometry3<f64>,
    t_bc: &Isometry3<f64>,
    obs: &[Observation],
    dof: Dof,
    inlier: &[bool],
    h: &mut DMatrix<f64>,
    g: &mut DVector<f64>,
) {
    let n = dof.count();
    let cols = dof.columns();
    let huber = CHI2_3.sqrt();
    for (o, &ok) in obs.iter().zip(inlier.iter()) {
        if !ok {
            continue;
        }
        let Some((pred, j6)) = project(cam, t_wb, t_bc, &o.point) else {
            continue;
        };
        let s = Vector3::new(o.sigma_px, o.sigma_px, o.sigma_disparity);
        let r = (o.measured - pred).component_div(&s);
        let e = r.norm();
        let w = if e <= huber { 1.0 } else { huber / e };
        for a in 0..3 {
            let ja: Vec<f64> = cols.iter().map(|&c| j6[(a, c)] / s[a]).collect();
            for i in 0..n {
                g[i] += w * ja[i] * r[a];
                for k in 0..n {
                    h[(i, k)] += w * ja[i] * ja[k];
                }
            }
        }
    }
}

/// Adds the normal equations `h`, `g` of the odometry's prior `p` at `t_wb`.
fn add_prior(
    p: &PlanarPrior,
    t_wb: &Isometry3<f64>,
    dof: Dof,
    h: &mut DMatrix<f64>,
    g: &mut DVector<f64>,
) {
    // Error of the pose in the prior's frame: (x, y, yaw) of T_p⁻¹ T.
    let e = p.pose.inverse() * *t_wb;
    let [ex, ey, eth] = to_planar(&e);
    let (s, c) = eth.sin_cos();
    // d(error)/d(x, y, yaw) of the right perturbation.
    let j = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    let r = [ex, ey, eth];
    let pc = dof.columns();
    for (a, (&ra, &sa)) in r.iter().zip(&p.sigma).enumerate() {
        // The prior's a-th error moves with the planar unknowns only.
        for (i, &ci) in pc.iter().enumerate() {
            let ji = planar_entry(&j, a, ci) / sa;
            if ji == 0.0 {
                continue;
            }
            g[i] -= ji * ra / sa;
            for (k, &ck) in pc.iter().enumerate() {
                h[(i, k)] += ji * planar_entry(&j, a, ck) / sa;
            }
        }
    }
}

/// Entry of the planar error Jacobian `j` (rows x, y, yaw; columns of the twist 0, 1, 5).
fn planar_entry(j: &Matrix3<f64>, row: usize, twist_col: usize) -> f64 {
    match twist_col {
        0 => j[(row, 0)],
        1 => j[(row, 1)],
        5 => j[(row, 2)],
        _ => 0.0,
    }
}

/// A relative-pose constraint between two keyframes of a pose graph: `z` is the measured
/// `T_a⁻¹ T_b`, weighted by `1 / σ` for translation (m) and rotation (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// First node.
    pub a: usize,
    /// Second node.
    pub b: usize,
    /// Measured `T_a⁻¹ T_b`.
    pub z: Isometry3<f64>,
    /// σ of translation, m.
    pub sigma_t: f64,
    /// σ of rotation, rad.
    pub sigma_r: f64,
}

/// The error of edge `e` at poses `ta`, `tb`: the twist of `z⁻¹ T_a⁻¹ T_b`, weighted.
fn edge_error(e: &Edge, ta: &Isometry3<f64>, tb: &Isometry3<f64>) -> Vector6<f64> {
    let d = log(&(e.z.inverse() * ta.inverse() * tb));
    Vector6::new(
        d[0] / e.sigma_t,
        d[1] / e.sigma_t,
        d[2] / e.sigma_t,
        d[3] / e.sigma_r,
        d[4] / e.sigma_r,
        d[5] / e.sigma_r,
    )
}

/// Optimises the poses `nodes` of a pose graph (Gauss–Newton, numeric Jacobians, dense normal
/// equations) with node 0 held; returns the final cost (sum of squared weighted errors), or
/// `None`, with `nodes` as they were, when the solve is degenerate (a step or a pose not
/// finite, or a cost that is not).
pub fn optimise_graph(
    nodes: &mut [Isometry3<f64>],
    edges: &[Edge],
    dof: Dof,
    iterations: usize,
) -> Option<f64> {
    let before = nodes.to_vec();
    let cost = solve_graph(nodes, edges, dof, iterations);
    if cost.is_finite() && nodes.iter().all(is_sound) {
        Some(cost)
    } else {
        nodes.copy_from_slice(&before);
        None
    }
}

fn solve_graph(nodes: &mut [Isometry3<f64>], edges: &[Edge], dof: Dof, iterations: usize) -> f64 {
    let k = dof.count();
    let n = nodes.len();
    let cost = |nodes: &[Isometry3<f64>]| -> f64 {
        edges
            .iter()
            .map(|e| edge_error(e, &nodes[e.a], &nodes[e.b]).norm_squared())
            .sum()
    };
    if n < 2 {
        return cost(nodes);
    }
    let m = (n - 1) * k;
    let eps = 1e-7;
    for _ in 0..iterations {
        let mut h = DMatrix::<f64>::zeros(m, m);
        let mut g = DVector::<f64>::zeros(m);
        for e in edges {
            let r0 = edge_error(e, &nodes[e.a], &nodes[e.b]);
            // Jacobians of the error with respect to each end's unknowns.
            let mut jac: [Option<nalgebra::OMatrix<f64, nalgebra::U6, nalgebra::Dyn>>; 2] =
                [None, None];
            for (side, &node) in [e.a, e.b].iter().enumerate() {
                if node == 0 {
                    continue;
                }
                let mut j = nalgebra::OMatrix::<f64, nalgebra::U6, nalgebra::Dyn>::zeros(k);
                for c in 0..k {
                    let mut d = vec![0.0; k];
                    d[c] = eps;
                    let moved = retract(&nodes[node], &dof.twist(&d));
                    let r = if side == 0 {
                        edge_error(e, &moved, &nodes[e.b])
                    } else {
                        edge_error(e, &nodes[e.a], &moved)
                    };
                    j.set_column(c, &((r - r0) / eps));
                }
                jac[side] = Some(j);
            }
            for (sa, na) in [(0, e.a), (1, e.b)] {
                let Some(ja) = &jac[sa] else { continue };
                let ia = (na - 1) * k;
                let gv = ja.transpose() * r0;
                for i in 0..k {
                    g[ia + i] -= gv[i];
                }
                for (sb, nb) in [(0, e.a), (1, e.b)] {
                    let Some(jb) = &jac[sb] else { continue };
                    let ib = (nb - 1) * k;
                    let block = ja.transpose() * jb;
                    for i in 0..k {
                        for j in 0..k {
                            h[(ia + i, ib + j)] += block[(i, j)];
                        }
                    }
                }
            }
        }
        for i in 0..m {
            h[(i, i)] += 1e-9;
        }
        let Some(ch) = h.cholesky() else { break };
        let d = ch.solve(&g);
        if !d.iter().all(|x| x.is_finite()) {
            return f64::NAN;
        }
        for (node, s) in nodes[1..].iter_mut().zip(d.as_slice().chunks_exact(k)) {
            *node = renormalised(&retract(node, &dof.twist(s)));
        }
        if d.amax() < 1e-9 {
            break;
        }
    }
    cost(nodes)
}

/// The rigid transform that best maps `from` onto `to` (least squares, Kabsch/Horn with
/// Umeyama's reflection guard); `None` for fewer than three pairs or a degenerate set.
pub fn align(from: &[Point3<f64>], to: &[Point3<f64>]) -> Option<Isometry3<f64>> {
    let n = from.len();
    if n < 3 || to.len() != n {
        return None;
    }
    let ca = from.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n as f64;
    let cb = to.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n as f64;
    let mut s = Matrix3::zeros();
    for (a, b) in from.iter().zip(to) {
        s += (b.coords - cb) * (a.coords - ca).transpose();
    }
    let svd = s.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    if svd.singular_values[1] < 1e-12 {
        return None;
    }
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    // U D Vᵀ of an SVD is orthonormal already (no iterative re-orthonormalisation).
    let r = nalgebra::Rotation3::from_matrix_unchecked(u * d * vt);
    let rot = UnitQuaternion::from_rotation_matrix(&r);
    let t = cb - rot * ca;
    Some(Isometry3::from_parts(Translation3::from(t), rot))
}
