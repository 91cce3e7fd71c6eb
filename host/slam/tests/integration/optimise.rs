//! The least-squares pieces on synthetic problems with known answers: a frame's pose from
//! noisy observations with outliers (planar and free), a pose graph closing a drifted loop,
//! and the rigid alignment of point sets.

use ferrobot_slam::optimise::{
    align, chi2, optimise_graph, optimise_pose, planar, to_planar, Dof, Edge, Observation, Pinhole,
    PlanarPrior, CHI2_3,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// A small seeded generator (SplitMix64): uniform in [0, 1) and standard normal.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (a, b) = (self.next().max(1e-12), self.next());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

const CAM: Pinhole = Pinhole {
    fx: 620.0,
    fy: 620.0,
    cx: 320.0,
    cy: 240.0,
    baseline: 0.05,
};

/// The LoCoBot's camera on its body, roughly: 0.1 m ahead, 0.55 m up, looking ahead and a
/// little down (optical z forward, x right, y down).
fn camera_on_body() -> Isometry3<f64> {
    let look = UnitQuaternion::from_euler_angles(
        -std::f64::consts::FRAC_PI_2 - 0.3,
        0.0,
        -std::f64::consts::FRAC_PI_2,
    );
    Isometry3::from_parts(Translation3::new(0.1, 0.0, 0.55), look)
}

/// Observations of `n` points spread in front of the camera at body pose `truth`: pixel noise
/// σ 0.5 px, disparity noise σ 0.1 px, and every fifth replaced by a gross outlier.
fn scene(
    truth: &Isometry3<f64>,
    t_bc: &Isometry3<f64>,
    n: usize,
    rng: &mut Rng,
) -> (Vec<Observation>, Vec<bool>) {
    let mut obs = Vec::new();
    let mut good = Vec::new();
    let t_wc = truth * t_bc;
    while obs.len() < n {
        let pc = Point3::new(
            rng.next() * 4.0 - 2.0,
            rng.next() * 2.0 - 1.0,
            0.5 + rng.next() * 3.5,
        );
        let u = CAM.fx * pc.x / pc.z + CAM.cx;
        let v = CAM.fy * pc.y / pc.z + CAM.cy;
        if !(0.0..640.0).contains(&u) || !(0.0..480.0).contains(&v) {
            continue;
        }
        let outlier = obs.len() % 5 == 4;
        let shift = if outlier { 40.0 } else { 0.0 };
        obs.push(Observation {
            point: t_wc * pc,
            measured: Vector3::new(
                u + 0.5 * rng.normal() + shift,
                v + 0.5 * rng.normal() - shift,
                CAM.fx * CAM.baseline / pc.z + 0.1 * rng.normal(),
            ),
            sigma_px: 1.0,
            sigma_disparity: 0.2,
        });
        good.push(!outlier);
    }
    (obs, good)
}

#[test]
fn a_planar_pose_is_recovered_through_noise_and_outliers() {
    let mut rng = Rng(7);
    let t_bc = camera_on_body();
    for trial in 0..20 {
        let truth = planar([
            rng.next() * 4.0 - 2.0,
            rng.next() * 4.0 - 2.0,
            rng.next() * 6.0 - 3.0,
        ]);
        let (obs, good) = scene(&truth, &t_bc, 150, &mut rng);
        // Start 5 cm and 3° off.
        let mut pose = truth * planar([0.05, -0.03, 0.05]);
        let mut inl = Vec::new();
        let n = optimise_pose(&CAM, &mut pose, &t_bc, &obs, Dof::Planar, None, &mut inl);
        let e = to_planar(&(truth.inverse() * pose));
        assert!(
            e[0].hypot(e[1]) < 0.003 && e[2].abs() < 0.001,
            "trial {trial}: {e:?}"
        );
        // Every outlier is refused and nearly every good one kept.
        assert!(
            inl.iter().zip(&good).all(|(&i, &g)| g || !i),
            "trial {trial}"
        );
        assert!(n >= 110, "trial {trial}: {n} inliers");
        assert!(obs
            .iter()
            .zip(&inl)
            .all(|(o, &i)| !i || chi2(&CAM, &pose, &t_bc, o) <= CHI2_3));
    }
}

#[test]
fn a_free_pose_is_recovered_and_too_few_observations_leave_it_alone() {
    let mut rng = Rng(11);
    let truth = Isometry3::from_parts(
        Translation3::new(0.3, -0.2, 1.1),
        UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7),
    );
    let (obs, _) = scene(&truth, &Isometry3::identity(), 200, &mut rng);
    let start = truth
        * Isometry3::from_parts(
            Translation3::new(0.04, 0.02, -0.03),
            UnitQuaternion::from_euler_angles(0.02, 0.01, -0.03),
        );
    let mut pose = start;
    let mut inl = Vec::new();
    optimise_pose(
        &CAM,
        &mut pose,
        &Isometry3::identity(),
        &obs,
        Dof::Free,
        None,
        &mut inl,
    );
    let d = truth.inverse() * pose;
    assert!(d.translation.vector.norm() < 0.003, "{d:?}");
    assert!(d.rotation.angle() < 0.001, "{d:?}");
    // Three observations cannot fix six unknowns well: with one the pose is not touched.
    let mut pose = start;
    assert_eq!(
        optimise_pose(
            &CAM,
            &mut pose,
            &Isometry3::identity(),
            &obs[..1],
            Dof::Free,
            None,
            &mut inl
        ),
        0
    );
    assert_eq!(pose, start);
}

#[test]
fn with_no_observations_nothing_is_estimated() {
    let prior = PlanarPrior {
        pose: planar([1.0, 2.0, 0.5]),
        sigma: [0.01, 0.01, 0.01],
    };
    let obs: Vec<Observation> = Vec::new();
    let mut pose = planar([0.0, 0.0, 0.0]);
    let mut inl = Vec::new();
    optimise_pose(
        &CAM,
        &mut pose,
        &camera_on_body(),
        &obs,
        Dof::Planar,
        Some(&prior),
        &mut inl,
    );
    // Nothing seen: nothing is estimated, whatever the prior (the caller keeps the
    // odometry's pose).
    assert_eq!(pose, planar([0.0, 0.0, 0.0]));
}

#[test]
fn a_pose_graph_spreads_a_loops_drift() {
    // A square loop of 40 poses, 0.25 m apart; odometry edges with a yaw bias of 2 mrad per
    // step (the drift), and one loop edge saying the last pose is the first.
    let n = 40;
    let truth: Vec<Isometry3<f64>> = (0..n)
        .map(|i| {
            let side = i / 10;
            let s = (i % 10) as f64 * 0.25;
            let (x, y) = match side {
                0 => (s, 0.0),
                1 => (2.5, s),
                2 => (2.5 - s, 2.5),
                _ => (0.0, 2.5 - s),
            };
            planar([x, y, side as f64 * std::f64::consts::FRAC_PI_2])
        })
        .collect();
    let mut edges = Vec::new();
    let mut nodes = vec![truth[0]];
    for i in 1..n {
        let z = truth[i - 1].inverse() * truth[i] * planar([0.0, 0.0, 0.002]);
        nodes.push(nodes[i - 1] * z);
        edges.push(Edge {
            a: i - 1,
            b: i,
            z,
            sigma_t: 0.01,
            sigma_r: 0.01,
        });
    }
    let close = truth[n - 1].inverse() * truth[0];
    edges.push(Edge {
        a: n - 1,
        b: 0,
        z: close,
        sigma_t: 0.002,
        sigma_r: 0.001,
    });
    let err = |nodes: &[Isometry3<f64>]| -> f64 {
        nodes
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a.translation.vector - b.translation.vector).norm())
            .fold(0.0, f64::max)
    };
    let before = err(&nodes);
    optimise_graph(&mut nodes, &edges, Dof::Planar, 10).expect("a sound solve");
    let after = err(&nodes);
    assert!(before > 0.1, "the drift is {before} m");
    assert!(after < before / 5.0, "{before} -> {after} m");
    // Node 0 is held.
    assert_eq!(nodes[0], truth[0]);
}

#[test]
fn alignment_recovers_a_rigid_transform() {
    let mut rng = Rng(3);
    let t = Isometry3::from_parts(
        Translation3::new(1.0, -2.0, 0.5),
        UnitQuaternion::from_euler_angles(0.3, -0.1, 2.0),
    );
    let a: Vec<Point3<f64>> = (0..20)
        .map(|_| Point3::new(rng.next(), rng.next(), rng.next()))
        .collect();
    let b: Vec<Point3<f64>> = a.iter().map(|p| t * p).collect();
    let found = align(&a, &b).expect("align");
    assert!((found.translation.vector - t.translation.vector).norm() < 1e-9);
    assert!(found.rotation.angle_to(&t.rotation) < 1e-9);
    // Collinear points and too few points have no unique answer.
    let line: Vec<Point3<f64>> = (0..5).map(|i| Point3::new(i as f64, 0.0, 0.0)).collect();
    assert!(align(&line, &line).is_none());
    assert!(align(&a[..2], &b[..2]).is_none());
}
