//! The skills under hostile values: pushing, grasping and hand-eye calibration fed seeded
//! random mixes of ordinary and absurd options and clouds (see `ferrobot`'s `hostile_api`
//! tests, whose value generator and judge they share). Each call must return quickly, never
//! panic, and refuse every absurd input.

use ferrobot::Robot;
use ferrobot_skills::Skills;
use nalgebra::Isometry3;
use proptest::prelude::*;

#[path = "../../../ferrobot/tests/integration/support/hostile.rs"]
mod hostile;
use hostile::*;

/// `Robot::push_object` refuses absurd options (tilt, lifts, margins, the push's geometry)
/// with a typed input error before anything moves.
#[test]
fn the_push_refuses_hostile_options() {
    use ferrobot_skills::PushOptions;
    let bot = Robot::builder("locobot")
        .scene("tabletop")
        .build()
        .expect("robot");
    let q0 = bot.arm().expect("arm").get_joint_angles().expect("q");
    let hostile = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::MAX,
        -f64::MAX,
        1e300,
        -1e300,
        1e38,
        -1.0,
    ];
    for v in hostile {
        let cases: Vec<(&str, PushOptions)> = vec![
            (
                "tilt",
                PushOptions {
                    tilt: v,
                    ..Default::default()
                },
            ),
            (
                "lifts",
                PushOptions {
                    lifts: vec![0.05, v],
                    ..Default::default()
                },
            ),
            (
                "object_margin",
                PushOptions {
                    object_margin: v,
                    ..Default::default()
                },
            ),
            (
                "eps",
                PushOptions {
                    eps: v,
                    ..Default::default()
                },
            ),
            ("distance", {
                let mut o = PushOptions::default();
                o.push.distance = v;
                o
            }),
            ("gap", {
                let mut o = PushOptions::default();
                o.push.gap = v;
                o
            }),
            ("reach", {
                let mut o = PushOptions::default();
                o.push.reach = [0.1, v];
                o
            }),
            ("segment", {
                let mut o = PushOptions::default();
                o.segment.min_height = v;
                o
            }),
            ("low", {
                let mut o = PushOptions::default();
                o.push.low = [0.01, v];
                o
            }),
            ("along_axis", {
                let mut o = PushOptions::default();
                o.push.along_axis = v;
                o
            }),
            (
                "base_shifts",
                PushOptions {
                    base_shifts: vec![0.1, v],
                    ..Default::default()
                },
            ),
            (
                "table_clearance",
                PushOptions {
                    table_clearance: v,
                    ..Default::default()
                },
            ),
            (
                "route_clearance",
                PushOptions {
                    route_clearance: Some(v),
                    ..Default::default()
                },
            ),
        ];
        for (what, opts) in cases {
            if what == "tilt" && v == -1.0 {
                continue; // an ordinary tilt
            }
            let r = bot.push_object(&opts);
            match r {
                Err(e) => assert!(e.is_input(), "{what} = {v}: {e}"),
                Ok(p) => panic!("{what} = {v} accepted: {p:?}"),
            }
        }
    }
    let r = bot.push_object(&PushOptions {
        lifts: vec![],
        ..Default::default()
    });
    assert!(r.is_err_and(|e| e.is_input()));
    let r = bot.push_object(&PushOptions {
        min_samples: 0,
        ..Default::default()
    });
    assert!(r.is_err_and(|e| e.is_input()));
    // Nothing moved.
    let q1 = bot.arm().expect("arm").get_joint_angles().expect("q");
    for (a, b) in q0.iter().zip(&q1) {
        assert!((a - b).abs() < 0.01, "{q0:?} -> {q1:?}");
    }
}

#[test]
fn grasping_refuses_hostile_clouds_and_options() {
    use ferrobot::perception::{
        detect_grasps, AnalyticScorer, GraspParams, GripperGeometry, SegmentedObject,
    };
    use ferrobot_skills::grasp::{view_table, GraspOptions};
    use nalgebra::Point3;
    let bot = Robot::new("locobot").expect("robot");
    let calls = std::cell::Cell::new(0usize);
    // A table of ordinary points 1 cm apart with a small block on it, some coordinates
    // replaced by hostile ones.
    let table: Vec<[f64; 3]> = (0..400)
        .map(|i| {
            [
                0.3 + 0.01 * (i % 20) as f64,
                -0.1 + 0.01 * (i / 20) as f64,
                0.1,
            ]
        })
        .chain((0..27).map(|i| {
            let (a, b, c) = (i % 3, (i / 3) % 3, i / 9);
            [
                0.4 + 0.01 * a as f64,
                0.01 * b as f64,
                0.12 + 0.01 * c as f64,
            ]
        }))
        .collect();
    let strategy = (
        prop::collection::vec((0usize..427, 0usize..3, value()), 0..3),
        (value(), value(), value(), count(), count()),
        (count(), value(), value()),
        [value(), value(), value(), value()],
    );
    runner(15)
        .run(
            &strategy,
            |(spoil, (tilt, pregrasp, lift, attempts, stride), (yaws, depth, gap), g)| {
                let mut pts = table.clone();
                for &(i, k, v) in &spoil {
                    pts[i][k] = v;
                }
                let points: Vec<Point3<f64>> = pts.iter().map(|p| Point3::from(*p)).collect();
                let bad_cloud = pts.iter().any(|p| absurd(p));
                let params = GraspParams {
                    yaws,
                    target_depth: depth,
                    table_gap: gap,
                };
                let good_params = (1..=64).contains(&yaws)
                    && depth.is_finite()
                    && depth > 0.0
                    && depth <= 0.5
                    && gap.is_finite()
                    && (0.0..=0.5).contains(&gap);
                let bad_params = !good_params;
                let opts = GraspOptions {
                    head_tilt: tilt,
                    pregrasp,
                    lift,
                    attempts,
                    stride,
                    params,
                    ..Default::default()
                };
                let bad_opts = bad_params
                    || absurd(&[tilt, pregrasp, lift])
                    || tilt.abs() > std::f64::consts::FRAC_PI_2
                    || !(0.0..=1.0).contains(&pregrasp)
                    || !(0.0..=1.0).contains(&lift)
                    || !(1..=100).contains(&attempts)
                    || !(1..=16).contains(&stride);
                let gripper = GripperGeometry {
                    opening: g[0],
                    finger_thickness: g[1],
                    finger_width: g[2],
                    finger_length: g[3],
                };
                let bad_gripper = g.iter().any(|v| !(v.is_finite() && *v > 0.0 && *v <= 0.5));
                let scorer = AnalyticScorer::default();
                let r = view_table(points.clone(), &gripper, &opts, &scorer);
                judge("view_table", bad_cloud || bad_opts || bad_gripper, &r)?;
                let object = SegmentedObject {
                    indices: (400..427).collect(),
                    features: ferrobot::perception::features(&points[..3]).unwrap_or_else(|_| {
                        ferrobot::perception::features(&[Point3::origin()]).unwrap()
                    }),
                };
                let plane = ferrobot::perception::Plane {
                    normal: nalgebra::Vector3::z_axis(),
                    offset: 0.1,
                };
                let r = detect_grasps(&points, &plane, &[object], &gripper, &params, &scorer);
                judge("detect_grasps", bad_cloud || bad_params || bad_gripper, &r)?;
                if bad_opts {
                    // Refused before anything moves.
                    let r = ferrobot_skills::grasp::pick(&bot, &opts);
                    judge("grasp::pick", true, &r)?;
                }
                calls.set(calls.get() + 2 + usize::from(bad_opts));
                Ok(())
            },
        )
        .expect("grasping refuses hostile clouds and options");
    report("grasping", calls.get());
}

/// Hand-eye calibration under hostile values: camera mount errors for the simulator (refused
/// unless finite and within 0.1 m / 0.5 rad), head offsets, inlier thresholds and search radii
/// (refused before anything moves), predicted marker corners and search radii for the
/// detector, and views and thresholds for the solver. The calibration itself runs in
/// `hand_eye.rs`; here only its refusals.
#[test]
fn hand_eye_calibration_refuses_hostile_values() {
    use ferrobot::perception::{detect_square, HandEyeProblem, MarkerView};
    use ferrobot_skills::HandEyeOptions;
    let bot = Robot::new("locobot").expect("robot");
    let frame = bot.camera().expect("camera").get_frame().expect("frame");
    let k = frame.intrinsics;
    let calls = std::cell::Cell::new(0usize);
    let strategy = (
        [value(), value(), value(), value(), value(), value()],
        [
            value(),
            value(),
            value(),
            value(),
            value(),
            value(),
            value(),
            value(),
        ],
        (value(), value(), value()),
        (value(), value()),
    );
    runner(10)
        .run(
            &strategy,
            |(perturb, corners, (radius, pan, tilt), (inlier, search))| {
                if calls.get() < 40 {
                    let r = Robot::builder("locobot")
                        .use_arm(false)
                        .camera_mount_error(perturb)
                        .build();
                    let out = perturb[..3].iter().any(|v| !(-0.1..=0.1).contains(v))
                        || perturb[3..].iter().any(|v| !(-0.5..=0.5).contains(v));
                    judge("RobotBuilder::camera_mount_error", out, &r)?;
                }
                let c = [
                    [corners[0] * 300.0, corners[1] * 300.0],
                    [corners[2] * 300.0, corners[3] * 300.0],
                    [corners[4] * 300.0, corners[5] * 300.0],
                    [corners[6] * 300.0, corners[7] * 300.0],
                ];
                let r = detect_square(&frame.rgb, &c, radius * 100.0);
                judge(
                    "detect_square",
                    absurd(&corners)
                        || absurd(&[radius])
                        || radius.is_nan()
                        || radius * 100.0 < 1.0,
                    &r,
                )?;
                // Options out of range: refused before the arm or head moves.
                let opts = HandEyeOptions {
                    pan_offsets: vec![pan],
                    tilt_offsets: vec![tilt],
                    inlier_px: inlier * 100.0,
                    search_px: search * 100.0,
                    ..HandEyeOptions::default()
                };
                let bad = !(-1.0..=1.0).contains(&pan)
                    || !(-1.0..=1.0).contains(&tilt)
                    || !((0.1..=1000.0).contains(&(inlier * 100.0)))
                    || !((1.0..=1000.0).contains(&(search * 100.0)));
                if bad {
                    judge(
                        "Robot::calibrate_camera",
                        true,
                        &bot.calibrate_camera(&opts),
                    )?;
                }
                // The solver: hostile views and thresholds.
                let p = HandEyeProblem {
                    intrinsics: k,
                    link_to_optical: Isometry3::identity(),
                    corners: [nalgebra::Point3::new(corners[0], corners[1], 0.5); 4],
                    views: vec![
                        MarkerView {
                            head: Isometry3::translation(perturb[0], perturb[1], perturb[2]),
                            marker: Isometry3::translation(0.0, 0.0, 0.5),
                            corners: c,
                        };
                        4
                    ],
                    initial: Isometry3::identity(),
                    inlier_px: inlier * 100.0,
                    min_views: 3,
                    min_sensitivity: 0.1,
                };
                let r = p.solve();
                judge(
                    "HandEyeProblem::solve",
                    absurd(&corners) || absurd(&perturb[..3]) || !(inlier > 0.0 && inlier <= 10.0),
                    &r,
                )?;
                calls.set(calls.get() + 4);
                Ok(())
            },
        )
        .expect("hand-eye calibration refuses hostile values");
    report("hand-eye calibration", calls.get());
}
