//! Kinematics: FK of the bundled robots against the reference descriptions in `../shared`,
//! the Jacobian, and both IK solvers.

use ferrobot::kinematics::ik::{IkOptions, IkSolver, NumericalIk};
use ferrobot::kinematics::locobot_ik::LocobotIk;
use ferrobot::kinematics::Chain;
use ferrobot::RobotConfig;
use nalgebra::{Isometry3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn reference(file: &str) -> urdf_rs::Robot {
    let path = format!(
        "{}/../../../shared/robots/{file}",
        env!("CARGO_MANIFEST_DIR")
    );
    urdf_rs::read_file(&path).unwrap_or_else(|e| panic!("reference URDF {path}: {e}"))
}

fn random_q(chain: &Chain, rng: &mut ChaCha8Rng) -> Vec<f64> {
    chain
        .joints
        .iter()
        .map(|j| rng.random_range(j.lower.max(-6.0)..=j.upper.min(6.0)))
        .collect()
}

/// FK of our chain and the reference chain agree at 1,000 random configurations.
fn cross_check(robot: &str, reference_file: &str, frames: &[(&str, &str)]) {
    let ours = RobotConfig::bundled(robot).expect("bundled robot loads");
    let theirs = reference(reference_file);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for (base, tip) in frames {
        let a = Chain::from_urdf(&ours.urdf, base, tip).expect("our chain");
        let b = Chain::from_urdf(&theirs, base, tip).expect("reference chain");
        let names: Vec<_> = a.joints.iter().map(|j| &j.name).collect();
        assert_eq!(
            names,
            b.joints.iter().map(|j| &j.name).collect::<Vec<_>>(),
            "{robot} {base}->{tip}"
        );
        let mut worst = (0.0f64, 0.0f64);
        for _ in 0..1000 {
            // Within both descriptions' limits.
            let q: Vec<f64> = a
                .joints
                .iter()
                .zip(&b.joints)
                .map(|(x, y)| {
                    rng.random_range(x.lower.max(y.lower).max(-6.0)..=x.upper.min(y.upper).min(6.0))
                })
                .collect();
            let (ta, tb) = (a.fk(&q), b.fk(&q));
            let dp = (ta.translation.vector - tb.translation.vector).norm();
            let dr = (ta.rotation.inverse() * tb.rotation).angle();
            worst = (worst.0.max(dp), worst.1.max(dr));
        }
        assert!(
            worst.0 < 1e-6 && worst.1 < 1e-6,
            "{robot} {base}->{tip}: worst {worst:?}"
        );
    }
}

#[test]
fn locobot_fk_matches_pyrobot_cmu_description() {
    cross_check(
        "locobot",
        "pyrobot/cmu_locobot_description.urdf",
        &[
            ("base_link", "gripper_link"),
            ("base_link", "finger_l"),
            ("base_link", "camera_link"),
        ],
    );
}

#[test]
fn locobot_lite_fk_matches_pyrobot_lite_description() {
    cross_check(
        "locobot_lite",
        "pyrobot/locobot_lite_description.urdf",
        &[("base_link", "gripper_link"), ("base_link", "camera_link")],
    );
}

#[test]
fn sawyer_fk_matches_rethink_description() {
    cross_check(
        "sawyer",
        "sawyer/sawyer.urdf",
        &[
            ("base", "right_hand"),
            ("base", "right_hand_camera"),
            ("base", "head"),
        ],
    );
}

fn arm_chain(robot: &str) -> Chain {
    ferrobot::profile::arm_chain(&RobotConfig::bundled(robot).expect("robot")).expect("arm")
}

#[test]
fn locobot_closed_form_ik_round_trips_and_prefers_the_seed() {
    let chain = arm_chain("locobot");
    let ik = LocobotIk::from_chain(&chain).expect("fits");
    let opts = IkOptions {
        position_tolerance: 1e-6,
        orientation_tolerance: 1e-6,
        ..Default::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for _ in 0..1000 {
        let q = random_q(&chain, &mut rng);
        let target = chain.fk(&q);
        let sol = ik
            .solve(&chain, &target, Some(&q), &opts)
            .expect("reachable");
        let back = chain.fk(&sol);
        assert!((back.translation.vector - target.translation.vector).norm() < 1e-6);
        assert!((back.rotation.inverse() * target.rotation).angle() < 1e-6);
        // Seeded with the configuration that made the pose, it returns that configuration.
        let d: f64 = sol
            .iter()
            .zip(&q)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(d < 1e-6, "{q:?} -> {sol:?}");
    }
}

#[test]
fn locobot_refuses_orientations_it_cannot_reach() {
    let chain = arm_chain("locobot");
    let ik = LocobotIk::from_chain(&chain).expect("fits");
    let q = [0.3, 0.4, 0.2, 0.5, 0.1];
    let t = chain.fk(&q);
    // Yaw the target orientation by 0.3 rad about z: a 5-DOF arm cannot follow.
    let bad = Isometry3::from_parts(
        t.translation,
        nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3) * t.rotation,
    );
    let err = ik
        .solve(&chain, &bad, None, &IkOptions::default())
        .expect_err("unreachable");
    assert!(
        matches!(err, ferrobot::kinematics::Error::Unreachable { .. }),
        "{err}"
    );
    // Out of reach.
    let far = Isometry3::translation(2.0, 0.0, 0.3) * nalgebra::UnitQuaternion::identity();
    assert!(ik.solve(&chain, &far, None, &IkOptions::default()).is_err());
}

#[test]
fn sawyer_numerical_ik_solves_random_reachable_poses() {
    let chain = arm_chain("sawyer");
    // The default budget is a count of restarts, so the result depends only on the seed
    // (speed is the `kinematics` bench's business: `benches/benches/kinematics.rs`).
    let opts = IkOptions::default();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut failures = 0;
    for _ in 0..300 {
        let q = random_q(&chain, &mut rng);
        let target = chain.fk(&q);
        match NumericalIk.solve(&chain, &target, None, &opts) {
            Ok(sol) => {
                let e = ferrobot::kinematics::ik::pose_error(&target, &chain.fk(&sol));
                assert!(e.fixed_rows::<3>(0).norm() <= 1e-5 && e.fixed_rows::<3>(3).norm() <= 1e-5);
                assert!(chain.within_limits(&sol, 1e-12));
            }
            Err(_) => failures += 1,
        }
    }
    assert!(failures <= 1, "{failures} of 300 failed");
}

#[test]
fn config_errors_name_the_file_the_key_and_the_problem() {
    let base = include_str!("../../../description/robots/locobot.toml");
    let urdf = include_str!("../../../description/robots/locobot.urdf");
    let load = |text: &str| {
        RobotConfig::parse(text, std::path::Path::new("test.toml"), |_| {
            Ok(urdf.to_string())
        })
        .expect_err("invalid")
    };
    let e = load(&base.replace(
        "ik_position_tolerance = 1e-5",
        "ik_position_tolerance = 1e-5\nspeed = 3",
    ));
    let s = e.to_string();
    assert!(
        s.contains("test.toml") && s.contains("arm") && s.contains("unknown field `speed`"),
        "{s}"
    );
    let s =
        load(&base.replace("home = [0.0, 0.0, 0.0, 0.0, 0.0]", "home = [0.0, 0.0]")).to_string();
    assert!(
        s.contains("arm.home") && s.contains("2 values for 5 arm joints"),
        "{s}"
    );
    let s = load(&base.replace("max_linear = 0.5", "max_linear = \"fast\"")).to_string();
    assert!(
        s.contains("base.max_linear") && s.contains("invalid type"),
        "{s}"
    );
    let s = load(&base.replace("servo = { id = 9,", "servo = { id = 8,")).to_string();
    assert!(
        s.contains("joint[7].servo.id") && s.contains("used twice"),
        "{s}"
    );
    let s = load(&base.replace("name = \"joint_3\"", "name = \"joint_33\"")).to_string();
    assert!(s.contains("joint[2].name") && s.contains("joint_33"), "{s}");
    let e = RobotConfig::bundled("r2d2").expect_err("unknown");
    assert!(
        e.to_string().contains("locobot, locobot_lite, sawyer"),
        "{e}"
    );
    let e = RobotConfig::from_file("/nonexistent/robot.toml").expect_err("missing");
    assert!(
        e.to_string().contains("/nonexistent/robot.toml") && e.to_string().contains("cannot read"),
        "{e}"
    );
}

/// The largest absolute elementwise difference.
fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// An independent check: PyRobot's own test expectations (tests/test_arm_utils.py, numbers
/// computed by PyRobot's authors, summarised in `../shared/design/FACTS.md`), with PyRobot's
/// tolerances, on both LoCoBot arms.
#[test]
fn kinematics_match_pyrobots_own_test_expectations() {
    let q = [0.1, 0.2, 0.3, 0.4, 0.5];
    let rotation = [
        [0.6185, -0.4613, 0.6361],
        [0.0621, 0.8357, 0.5457],
        [-0.7833, -0.2980, 0.5455],
    ];
    let jacobian_at_zero = [
        [-0.0001, 0.2, 0.0, 0.0, 0.0],
        [0.3132, 0.0, 0.0, 0.0, 0.0],
        [0.0, -0.3132, -0.2632, -0.063, 0.0],
        [0.0, 0.0, 0.0, 0.0, -1.0],
        [0.0, 1.0, 1.0, 1.0, 0.0],
        [1.0, 0.0, 0.0, 0.0, 0.0],
    ];
    for (robot, position) in [
        ("locobot_lite", [0.3821, 0.0304, 0.2200]),
        ("locobot", [0.3994, 0.0304, 0.2500]),
    ] {
        let chain = arm_chain(robot);
        let t = chain.fk(&q);
        // FK position: LoCoBot-Lite (0.3821, 0.0304, 0.2200); the cmu LoCoBot as the original
        // 2019 URDF in x and y (0.3994, 0.0304), its plates putting z at 0.2500.
        let p = t.translation.vector;
        assert!(
            max_diff(p.as_slice(), &position) < 0.001,
            "{robot}: FK position {p:?}"
        );
        // FK rotation, every variant.
        let r = t.rotation.to_rotation_matrix();
        let ours: Vec<f64> = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| r[(i, j)])
            .collect();
        assert!(
            max_diff(&ours, &rotation.concat()) < 0.001,
            "{robot}: FK rotation {r}"
        );
        // Jacobian at q = 0, Frobenius error < 0.001.
        let jac = chain.jacobian(&[0.0; 5]);
        let frob: f64 = (0..6)
            .flat_map(|i| (0..5).map(move |j| (i, j)))
            .map(|(i, j)| (jac[(i, j)] - jacobian_at_zero[i][j]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(frob < 0.001, "{robot}: Jacobian at 0, error {frob}:\n{jac}");
        // FK velocity at q = 0, q' = [0.1 .. 0.5].
        let v = chain.fk_velocity(&[0.0; 5], &q);
        assert!(
            max_diff(v.as_slice(), &[0.04, 0.0313, -0.1668, -0.5, 0.9, 0.1]) < 0.001,
            "{robot}: FK velocity {v:?}"
        );
    }
    // IK of PyRobot's pose on the LoCoBot-Lite arm: FK of the solution within 0.01 m and the
    // rotation within a Frobenius distance of 0.1.
    let chain = arm_chain("locobot_lite");
    let target = Isometry3::from_parts(
        nalgebra::Translation3::new(0.3821, 0.0304, 0.22),
        nalgebra::UnitQuaternion::from_matrix(&nalgebra::Matrix3::from_row_slice(
            &rotation.concat(),
        )),
    );
    for solver in [
        Box::new(LocobotIk::from_chain(&chain).expect("solver")) as Box<dyn IkSolver>,
        Box::new(NumericalIk),
    ] {
        let sol = solver
            .solve(
                &chain,
                &target,
                None,
                // PyRobot's pose is rounded to 4 decimals, so it lies a little off the arm's
                // reachable orientations: solve to PyRobot's own acceptance.
                &IkOptions {
                    position_tolerance: 1e-3,
                    orientation_tolerance: 1e-2,
                    ..IkOptions::default()
                },
            )
            .expect("PyRobot's pose is reachable");
        let got = chain.fk(&sol);
        let dp = (got.translation.vector - target.translation.vector).norm();
        let dr = (got.rotation.to_rotation_matrix().matrix()
            - target.rotation.to_rotation_matrix().matrix())
        .norm();
        assert!(
            dp < 0.01 && dr < 0.1,
            "IK: position error {dp}, rotation {dr}"
        );
    }
}
