//! The library under hostile values: every public entry point that takes numbers, durations,
//! poses, grids or references, fed seeded random mixes of ordinary values and NaN, ±inf,
//! ±0, subnormals, ±1e38, ±f64::MAX, ±1e300, huge counts and `Duration::MAX`.
//!
//! Each call must return quickly, never panic (a panic fails the property), and return `Err`
//! whenever an input is absurd (not finite, or beyond 1e6 in magnitude, or a wrong count).
//! Motions that an ordinary value starts are cancelled at once, so the robot stays usable and
//! the test stays short. The case count is bounded for CI: `HOSTILE_CASES` raises it.

use std::time::Duration;

use ferrobot::base_control::{ilqr, Limits, NavField, Obstacles, OccupancyGrid, Reference};
use ferrobot::kinematics::ik::{IkOptions, IkSolver, NumericalIk};
use ferrobot::kinematics::locobot_ik::LocobotIk;
use ferrobot::odometry_calibration::{estimate, CalibrationRun, WheelGeometry};
use ferrobot::{GoalOptions, MoveOptions, Orientation, Robot};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;

#[path = "support/hostile.rs"]
mod hostile;
use hostile::*;

#[test]
fn the_arm_refuses_hostile_values() {
    let cell = std::cell::RefCell::new(Robot::new("locobot").expect("robot"));
    let calls = std::cell::Cell::new(0usize);
    let strategy = (
        vector(3..8),
        vector(4..6),
        triple(),
        [value(), value(), value(), value()],
        (value(), value()),
        (prop::option::of(value()), prop::option::of(duration())),
    );
    runner(1)
        .run(&strategy, |(q, qd, p, quat, (a, b), (tol, timeout))| {
            let bot = cell.borrow_mut();
            let dof = 5;
            let bad_q = q.len() != dof || absurd(&q);
            let arm = bot.arm().expect("arm");
            let opts = MoveOptions {
                plan: true,
                tolerance: tol,
                timeout,
            };
            let hostile_opts = tol.is_some_and(|t| absurd(&[t]))
                || timeout.is_some_and(|t| t > Duration::from_secs(3600));
            let r = arm.move_joints(&q, opts).map(|m| {
                let _ = m.cancel();
            });
            judge("move_joints", bad_q || hostile_opts, &r)?;
            let r = arm
                .move_to_pose(p, Orientation::Quaternion(quat), opts)
                .map(|m| {
                    let _ = m.cancel();
                });
            judge(
                "move_to_pose",
                absurd(&p) || absurd(&quat) || hostile_opts,
                &r,
            )?;
            let r = arm.compute_fk_position(&q, "gripper_link");
            judge("compute_fk_position", bad_q, &r)?;
            let r = arm.get_jacobian(&q);
            judge("get_jacobian", bad_q, &r)?;
            let r = arm.compute_fk_velocity(&q, &qd);
            judge(
                "compute_fk_velocity",
                bad_q || qd.len() != dof || absurd(&qd),
                &r,
            )?;
            let r = arm.set_joint_velocities(&qd[..qd.len().min(dof)]);
            judge(
                "set_joint_velocities",
                qd.len() < dof || absurd(&qd[..dof.min(qd.len())]),
                &r,
            )?;
            let _ = arm.set_joint_positions_with(
                &[0.0; 5],
                MoveOptions {
                    plan: false,
                    ..Default::default()
                },
            );
            let r = arm.compute_ik(p, Orientation::Quaternion(quat), Some(&q));
            judge("compute_ik", bad_q || absurd(&p) || absurd(&quat), &r)?;
            let r = arm.compute_ik(p, Orientation::YawPitchRoll([a, b, a]), None);
            judge("compute_ik (ypr)", absurd(&p) || absurd(&[a, b]), &r)?;
            let m = [[a, b, 0.0], [b, a, 0.0], [0.0, 0.0, 1.0]];
            let r = arm.compute_ik(p, Orientation::Matrix(m), None);
            judge("compute_ik (matrix)", absurd(&p) || absurd(&[a, b]), &r)?;
            let r = arm.set_ee_pose_pitch_roll(p, a, Some(b));
            judge("set_ee_pose_pitch_roll", absurd(&p) || absurd(&[a, b]), &r)?;
            let r = arm.compute_ik_pitch_roll(p, a, Some(b), Some(&q));
            let bad = bad_q || absurd(&p) || absurd(&[a, b]);
            judge("compute_ik_pitch_roll", bad, &r)?;
            let r = arm.compute_ik_pitch_roll(p, b, None, None);
            judge(
                "compute_ik_pitch_roll (no seed)",
                absurd(&p) || absurd(&[b]),
                &r,
            )?;
            let d = [p[0] * 0.05, p[1] * 0.05, p[2] * 0.05];
            let r = arm.move_ee_xyz(d, a.abs() * 0.01);
            judge("move_ee_xyz", absurd(&d) || absurd(&[a]) || a == 0.0, &r)?;
            calls.set(calls.get() + 14);
            let cam = bot.head().expect("camera");
            let r = cam.set_pan_tilt_async(a, b).map(|m| {
                let _ = m.cancel();
            });
            judge("set_pan_tilt", absurd(&[a, b]), &r)?;
            let r = bot.wait(a);
            judge("Robot::wait", absurd(&[a]) || a < 0.0, &r)?;
            calls.set(calls.get() + 2);
            Ok(())
        })
        .expect("the arm refuses hostile values");
    report("arm", calls.get());
    let bot = cell.into_inner();
    // Still obeys after all that.
    bot.resume().expect("resume");
    bot.arm()
        .expect("arm")
        .set_joint_positions(&[0.2, 0.0, 0.0, 0.0, 0.0])
        .expect("moves");
}

/// The planning scene and the planner: objects with hostile poses and sizes, point clouds
/// with hostile points and voxels, hostile joint and pose goals.
#[test]
fn the_planning_scene_refuses_hostile_values() {
    let bot = Robot::new("locobot").expect("robot");
    let arm = bot.arm().expect("arm");
    let calls = std::cell::Cell::new(0usize);
    let strategy = (
        vector(3..8),
        triple(),
        triple(),
        [value(), value(), value(), value()],
        (value(), prop::collection::vec(triple(), 0..4)),
    );
    runner(7)
        .run(&strategy, |(q, p, size, quat, (a, cloud))| {
            let bad_pose = absurd(&p) || absurd(&quat) || quat.iter().all(|v| *v == 0.0);
            let bad_size = absurd(&size) || size.iter().any(|v| v.is_nan() || *v <= 0.0);
            let r = arm.add_world_object("hostile", p, Orientation::Quaternion(quat), size);
            judge("add_world_object", bad_pose || bad_size, &r)?;
            let r = arm.add_world_shape(
                "ball",
                ferrobot::planning::Shape::Sphere(a),
                p,
                Orientation::YawPitchRoll([a, a, a]),
            );
            judge(
                "add_world_shape",
                absurd(&p) || absurd(&[a]) || a.is_nan() || a <= 0.0,
                &r,
            )?;
            let r = arm.attach_arm_object("held", p, Orientation::Quaternion(quat), size);
            judge("attach_arm_object", bad_pose || bad_size, &r)?;
            // Released where it is now: only what was attached, and only once.
            let attached = r.is_ok();
            let r = arm.release_arm_object("held");
            judge("release_arm_object", !attached, &r)?;
            if attached && r.is_err() {
                return Err(TestCaseError::fail(format!("release_arm_object: {r:?}")));
            }
            let r = arm.release_arm_object("held");
            judge("release_arm_object (again)", true, &r)?;
            let flat: Vec<f64> = cloud.iter().flatten().copied().collect();
            let r = arm.set_point_cloud(Some(&cloud), a);
            judge(
                "set_point_cloud",
                absurd(&flat) || absurd(&[a]) || a.is_nan() || a <= 0.0,
                &r,
            )?;
            let r = arm.make_plan_joint_positions(&q);
            judge("make_plan_joint_positions", q.len() != 5 || absurd(&q), &r)?;
            let r = arm.make_plan_pose(p, Orientation::Quaternion(quat));
            judge("make_plan_pose", bad_pose, &r)?;
            let r = arm.plan_to(
                &[0.2, 0.0, 0.0, 0.0, 0.0],
                &ferrobot::arm_plan::PlanningOptions {
                    padding: a,
                    ..Default::default()
                },
            );
            judge(
                "plan_to's padding",
                absurd(&[a]) || a.is_nan() || !(0.0..=ferrobot::planning::MAX_PADDING).contains(&a),
                &r,
            )?;
            let _ = arm.get_collision_state();
            arm.remove_all_objects().expect("clear");
            calls.set(calls.get() + 10);
            Ok(())
        })
        .expect("the planning scene refuses hostile values");
    report("planning", calls.get());
    arm.set_joint_positions(&[0.2, 0.0, 0.0, 0.0, 0.0])
        .expect("still plans and moves");
}

#[test]
fn the_base_refuses_hostile_values() {
    let cell = std::cell::RefCell::new(
        Robot::builder("locobot")
            .use_arm(false)
            .build()
            .expect("robot"),
    );
    let calls = std::cell::Cell::new(0usize);
    let strategy = (
        triple(),
        triple(),
        (value(), value(), value()),
        prop::collection::vec(triple(), 0..3),
        (value(), value(), count(), count()),
        (value(), count()),
    );
    runner(2)
        .run(
            &strategy,
            |(goal, delta, (v, w, t), circles, (ox, res, gw, gh), (dt, n))| {
                let bot = cell.borrow_mut();
                let base = bot.base().expect("base");
                let r = base.go_to_absolute_async(goal).map(|m| {
                    let _ = m.cancel();
                });
                judge("go_to_absolute", absurd(&goal), &r)?;
                let r = base.go_to_relative_async(delta).map(|m| {
                    let _ = m.cancel();
                });
                judge("go_to_relative", absurd(&delta), &r)?;
                let r = base.set_vel_async(v * 0.1, w * 0.1, t).map(|m| {
                    let _ = m.cancel();
                });
                judge("set_vel", absurd(&[v, w, t]) || t < 0.0, &r)?;
                // A map with hostile shape, and circles, for the dynamic window.
                let grid = OccupancyGrid {
                    origin: [ox, ox],
                    resolution: res,
                    width: gw,
                    height: gh,
                    occupied: vec![false; gw.min(64) * gh.min(64)],
                };
                let r = grid.check();
                judge(
                    "OccupancyGrid::check",
                    absurd(&[ox, res]) || gw.saturating_mul(gh) > 1 << 24,
                    &r,
                )?;
                let r = OccupancyGrid::new([ox, ox], res, gw, gh);
                judge(
                    "OccupancyGrid::new",
                    absurd(&[ox, res]) || gw.saturating_mul(gh) > 1 << 24,
                    &r,
                )?;
                let hostile_circles = circles.iter().any(|c| absurd(c));
                let opts = GoalOptions {
                    obstacles: circles.clone(),
                    map: Some(grid),
                    ..Default::default()
                };
                let g = [goal[0] * 0.5, goal[1] * 0.5, goal[2]];
                let r = base.go_to_absolute_with(g, opts).map(|m| {
                    let _ = m.cancel();
                });
                judge(
                    "go_to_absolute_with (DWA)",
                    absurd(&g) || hostile_circles,
                    &r,
                )?;
                let r = Obstacles::new(circles.clone(), None)
                    .and_then(|o| NavField::new([0.0, 0.0], [goal[0], goal[1]], &o, 0.2));
                judge(
                    "NavField::new",
                    absurd(&goal[..2]) || hostile_circles,
                    &r.map(|_| ()),
                )?;
                // Trajectories with hostile timing and states.
                let lim = Limits::TRACKING;
                let r = Reference::sharp([0.0; 3], goal, &lim, dt);
                judge(
                    "Reference::sharp",
                    absurd(&goal) || absurd(&[dt]),
                    &r.map(|_| ()),
                )?;
                let r = Reference::smooth([0.0; 3], goal, &lim, dt, v);
                judge(
                    "Reference::smooth",
                    absurd(&goal) || absurd(&[dt, v]),
                    &r.map(|_| ()),
                )?;
                let r = Reference::circle([0.0; 3], v, w, t, dt);
                judge("Reference::circle", absurd(&[v, w, t, dt]), &r.map(|_| ()))?;
                let reference = Reference {
                    dt,
                    states: vec![goal; n.min(50) + 1],
                    controls: vec![[v, w]; n.min(50)],
                };
                let hostile_ref =
                    absurd(&goal) || absurd(&[dt]) || (n.min(50) > 0 && absurd(&[v, w]));
                let r = reference.check();
                judge("Reference::check", hostile_ref, &r)?;
                let r = ilqr([0.0; 3], &reference, [3.0, 3.0, 4.0], 0.2, &lim);
                judge("ilqr", hostile_ref, &r.map(|_| ()))?;
                let r = base.track_trajectory_async(reference, true).map(|m| {
                    let _ = m.cancel();
                });
                judge("track_trajectory", hostile_ref, &r)?;
                let g = WheelGeometry {
                    left_radius: v,
                    right_radius: w,
                    track: t,
                };
                let r = base.set_odometry_geometry(g);
                judge("set_odometry_geometry", absurd(&[v, w, t]), &r)?;
                let run = CalibrationRun {
                    wheels: vec![[v, w], [w, t], [t, v]],
                    start: delta,
                    end: goal,
                };
                let r = estimate(&[run.clone(), run], &WheelGeometry::nominal(0.035, 0.23));
                judge(
                    "odometry_calibration::estimate",
                    absurd(&[v, w, t]) || absurd(&goal) || absurd(&delta),
                    &r.map(|_| ()),
                )?;
                calls.set(calls.get() + 16);
                Ok(())
            },
        )
        .expect("the base refuses hostile values");
    report("base", calls.get());
    let bot = cell.into_inner();
    bot.base()
        .expect("base")
        .go_to_relative([0.2, 0.0, 0.0])
        .expect("drives");
}

#[test]
fn the_ik_solvers_refuse_hostile_targets() {
    let cfg = ferrobot::RobotConfig::bundled("sawyer").expect("sawyer");
    let sawyer = ferrobot::profile::arm_chain(&cfg).expect("chain");
    let locobot =
        ferrobot::profile::arm_chain(&ferrobot::RobotConfig::bundled("locobot").expect("locobot"))
            .expect("chain");
    let lik = LocobotIk::from_chain(&locobot).expect("solver");
    let calls = std::cell::Cell::new(0usize);
    let strategy = (triple(), triple(), vector(4..9));
    let opts = IkOptions {
        timeout: Duration::from_millis(2),
        ..IkOptions::default()
    };
    runner(3)
        .run(&strategy, |(p, rpy, seed)| {
            // The solvers take nalgebra poses: build them from whatever came in.
            let target = Isometry3::from_parts(
                Translation3::new(p[0], p[1], p[2]),
                UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
            );
            // Huge finite angles still make a unit rotation: only a non-finite one is hostile.
            let rot_bad = target.rotation.coords.iter().any(|x| !x.is_finite());
            let s7 = (seed.len() == 7).then_some(&seed[..]);
            let r = NumericalIk.solve(&sawyer, &target, s7, &opts);
            judge(
                "NumericalIk",
                absurd(&p) || rot_bad || s7.is_some_and(absurd),
                &r,
            )?;
            let s5 = (seed.len() == 5).then_some(&seed[..]);
            let r = lik.solve_pitch_roll(&locobot, &Vector3::from(p), rpy[0], rpy[1], s5);
            judge(
                "LocobotIk::solve_pitch_roll",
                absurd(&p) || absurd(&rpy[..2]) || s5.is_some_and(absurd),
                &r,
            )?;
            let r = lik.solve(&locobot, &target, s5, &opts);
            judge(
                "LocobotIk::solve",
                absurd(&p) || rot_bad || s5.is_some_and(absurd),
                &r,
            )?;
            // FK on any vector never panics (it is a formula; the API validates).
            let _ = sawyer.fk(&seed);
            let _ = sawyer.jacobian(&seed);
            let _ = sawyer.fk_velocity(&seed, &seed);
            calls.set(calls.get() + 6);
            Ok(())
        })
        .expect("the IK solvers refuse hostile targets");
    report("ik", calls.get());
}

/// The camera and its perception under hostile pixels, depth ranges, frame names, intrinsics,
/// scenes and start poses. A frame is captured once and reused (a capture renders 640x480);
/// the camera's own calls capture for the first few cases.
#[test]
fn the_camera_refuses_hostile_values() {
    use ferrobot::perception::{DepthRange, Intrinsics};
    let bot = Robot::new("locobot").expect("robot");
    let cam = bot.camera().expect("camera");
    let frame = cam.get_frame().expect("frame");
    let calls = std::cell::Cell::new(0usize);
    let pixel = || prop_oneof![3 => 0i64..480, 1 => any::<i64>(), 1 => -2i64..2];
    let strategy = (
        prop::collection::vec(pixel(), 0..6),
        prop::collection::vec(pixel(), 0..6),
        (value(), value()),
        "[a-z_]{0,12}",
        [value(), value(), value(), value()],
        prop::bool::ANY,
    );
    runner(9)
        .run(&strategy, |(rows, cols, (lo, hi), name, k, in_cam)| {
            let outside = rows.len() != cols.len()
                || rows
                    .iter()
                    .zip(&cols)
                    .any(|(&r, &c)| !(0..480).contains(&r) || !(0..640).contains(&c));
            let r = frame.pixels(&rows, &cols, in_cam);
            judge("Frame::pixels", outside, &r)?;
            if let Ok(p) = &r {
                prop_assert_eq!(p.points.len(), rows.len());
                prop_assert!(p
                    .points
                    .iter()
                    .flatten()
                    .all(|p| p.coords.iter().all(|v| v.is_finite())));
            }
            let range = DepthRange::new(lo, hi);
            judge(
                "DepthRange::new",
                !(lo.is_finite() && hi.is_finite()) || lo < 0.0 || lo >= hi,
                &range,
            )?;
            if let Ok(range) = range {
                let c = frame
                    .cloud(range, in_cam)
                    .expect("a valid range makes a cloud");
                prop_assert!(c
                    .points
                    .iter()
                    .all(|p| p.coords.iter().all(|v| v.is_finite())));
                prop_assert_eq!(c.points.len(), c.colours.len());
            }
            let r = cam.get_link_transform(&name, "base_link");
            judge(
                "get_link_transform",
                bot.config().urdf.links.iter().all(|l| l.name != name),
                &r,
            )?;
            let r = Intrinsics::new(
                640,
                480,
                k[0] * 600.0,
                k[1] * 600.0,
                k[2] * 320.0,
                k[3] * 240.0,
            );
            judge(
                "Intrinsics::new",
                absurd(&k) || k[0] <= 0.0 || k[1] <= 0.0,
                &r,
            )?;
            let r = ferrobot::scene::Scene::load(&ferrobot::scene::SceneSource::from_arg(&name));
            let bundled = ferrobot::scene::BUNDLED.contains(&name.as_str());
            judge("Scene::load", !bundled, &r)?;
            if calls.get() < 60 {
                let r = cam.pix_to_3dpt(&rows, &cols, in_cam);
                judge("Camera::pix_to_3dpt", outside, &r)?;
                let r = cam.get_current_pcd_in(range.unwrap_or(DepthRange::PYROBOT), in_cam);
                judge("Camera::get_current_pcd_in", false, &r)?;
            }
            calls.set(calls.get() + 6);
            Ok(())
        })
        .expect("the camera refuses hostile values");
    // Hostile start poses: refused before anything starts.
    for p in [
        [f64::NAN, 0.0, 0.0],
        [0.0, f64::INFINITY, 0.0],
        [0.0, 0.0, f64::NEG_INFINITY],
        [1e300, 0.0, 0.0],
        [0.0, -f64::MAX, 0.0],
        [0.0, 0.0, 1e9],
    ] {
        let r = Robot::builder("locobot")
            .use_arm(false)
            .start_pose(p)
            .build();
        assert!(r.is_err(), "start pose {p:?} accepted");
    }
    report("camera", calls.get());
    // Still sees after all that.
    assert_eq!(cam.get_rgb().expect("rgb").data.len(), 640 * 480 * 3);
}

/// Subscriptions under hostile queue lengths: zero and beyond `subscription::MAX_QUEUE`
/// refused, with the robot's time passing between cases.
#[test]
fn subscriptions_refuse_hostile_queue_lengths() {
    use ferrobot::subscription::MAX_QUEUE;
    let bot = Robot::new("locobot").expect("robot");
    let cam = bot.camera().expect("camera");
    let calls = std::cell::Cell::new(0usize);
    runner(10)
        .run(&(count(), count()), |(a, b)| {
            let bad = |n: usize| !(1..=MAX_QUEUE).contains(&n);
            let r = bot.subscribe_telemetry(a);
            judge("Robot::subscribe_telemetry", bad(a), &r)?;
            let f = cam.subscribe(b);
            judge("Camera::subscribe", bad(b), &f)?;
            bot.wait(0.04).expect("wait");
            if let Ok(f) = &f {
                prop_assert!(f.len() <= b);
            }
            calls.set(calls.get() + 2);
            Ok(())
        })
        .expect("subscriptions refuse hostile queue lengths");
    report("subscriptions", calls.get());
}

/// Perception's cloud algorithms under hostile clouds and parameters: DBSCAN (the k-d tree
/// one and the exhaustive reference, which must agree whenever both accept), RANSAC plane
/// fitting, segmentation above a table and per-object features. Points with a NaN, infinite
/// or beyond-1e6 coordinate, empty clouds, and parameters out of their documented ranges
/// must be refused.
#[test]
fn perception_refuses_hostile_clouds_and_parameters() {
    use ferrobot::perception::cluster::{MAX_EPS, MAX_MIN_SAMPLES};
    use ferrobot::perception::plane::{MAX_ITERATIONS, MAX_THRESHOLD};
    use ferrobot::perception::{
        features, fit_plane, segment_objects, Clusterer, Dbscan, ExhaustiveDbscan, RansacParams,
        SegmentParams,
    };
    use nalgebra::Point3;
    let calls = std::cell::Cell::new(0usize);
    // Clouds of ordinary points (a few centimetres apart, so that clusters form), half of
    // them with hostile coordinates mixed in.
    let ordinary = || -0.05..0.05f64;
    let coordinate = move || prop_oneof![8 => ordinary(), 1 => value()];
    let cloud = prop_oneof![
        prop::collection::vec([ordinary(), ordinary(), ordinary()], 0..60),
        prop::collection::vec([coordinate(), coordinate(), coordinate()], 0..60),
    ];
    let strategy = (
        cloud,
        (
            prop_oneof![3 => 0.001..0.05f64, 1 => value()],
            prop_oneof![3 => 1usize..10, 1 => count()],
        ),
        (value(), count(), value(), count()),
        (prop::option::of(triple()), value()),
        (value(), value(), value()),
    );
    runner(14)
        .run(
            &strategy,
            |(
                pts,
                (eps, m),
                (threshold, iterations, confidence, min_inliers),
                (up, tilt),
                (h0, h1, margin),
            )| {
                let points: Vec<Point3<f64>> =
                    pts.iter().map(|p| Point3::new(p[0], p[1], p[2])).collect();
                let bad_cloud = points.is_empty() || pts.iter().any(|p| absurd(p));
                let bad_dbscan = !(eps.is_finite() && eps > 0.0 && eps <= MAX_EPS)
                    || m == 0
                    || m > MAX_MIN_SAMPLES;
                let fast = Dbscan::new(eps, m).and_then(|d| d.cluster(&points));
                judge("Dbscan", bad_cloud || bad_dbscan, &fast)?;
                let slow = ExhaustiveDbscan::new(eps, m).and_then(|d| d.cluster(&points));
                judge("ExhaustiveDbscan", bad_cloud || bad_dbscan, &slow)?;
                if let (Ok(a), Ok(b)) = (&fast, &slow) {
                    prop_assert_eq!(a, b);
                    prop_assert_eq!(a.labels.len(), points.len());
                    prop_assert!(a
                        .labels
                        .iter()
                        .all(|&l| l >= -1 && (l as i64) < a.clusters as i64));
                }
                let params = RansacParams {
                    threshold,
                    iterations,
                    confidence,
                    min_inliers,
                    seed: 1,
                    up: up.map(nalgebra::Vector3::from),
                    max_tilt: tilt,
                };
                let bad_up = up.is_some_and(|u| {
                    let n = nalgebra::Vector3::from(u).norm();
                    !(n.is_finite() && n > 1e-12)
                });
                let bad_ransac =
                    !(threshold.is_finite() && threshold > 0.0 && threshold <= MAX_THRESHOLD)
                        || iterations == 0
                        || iterations > MAX_ITERATIONS
                        || !(confidence > 0.0 && confidence <= 1.0)
                        || min_inliers < 3
                        || bad_up
                        || !(0.0..=std::f64::consts::FRAC_PI_2).contains(&tilt);
                let fit = fit_plane(&points, &params);
                judge(
                    "fit_plane",
                    bad_cloud || bad_ransac || points.len() < 3,
                    &fit,
                )?;
                if let Ok(f) = &fit {
                    prop_assert!(f.inliers.len() >= min_inliers);
                    prop_assert!((f.plane.normal.norm() - 1.0).abs() < 1e-9);
                }
                let r = features(&points);
                judge("features", bad_cloud, &r)?;
                let table = fit_plane(&points, &RansacParams::default());
                if let Ok(table) = &table {
                    let seg = SegmentParams {
                        min_height: h0,
                        max_height: h1,
                        over_table: true,
                        margin,
                    };
                    let heights_ok =
                        h0.is_finite() && h0 >= 0.0 && h1.is_finite() && h1 > h0 && h1 <= 10.0;
                    let margin_ok = margin.is_finite() && (0.0..=1.0).contains(&margin);
                    let bad_seg = !(heights_ok && margin_ok);
                    let r = segment_objects(&points, table, &seg, &Dbscan::new(0.02, 3).unwrap());
                    judge("segment_objects", bad_seg, &r)?;
                }
                calls.set(calls.get() + 6);
                Ok(())
            },
        )
        .expect("perception refuses hostile clouds and parameters");
    report("perception", calls.get());
}
