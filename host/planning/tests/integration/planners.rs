//! The planners on a LoCoBot behind a post and a table: every returned path is free when
//! re-checked at states 1 mm of link motion apart, and Informed RRT* never
//! returns a longer path than RRT-Connect's first one (it starts from it).

use std::sync::Arc;

use ferrobot_description::RobotConfig;
use ferrobot_planning::{
    bench, CheckOptions, Checker, CollisionModel, InformedRrtStar, PlanOptions, Planner,
    PlanningScene, RrtConnect, Shape,
};
use nalgebra::Isometry3;

fn scene() -> PlanningScene {
    let mut s = PlanningScene::new();
    s.add_object(
        "table",
        Shape::Box([0.45, 0.8, 0.1]),
        Isometry3::translation(0.5, 0.0, 0.05),
    )
    .expect("table");
    s.add_object(
        "post",
        Shape::Cylinder {
            radius: 0.02,
            length: 0.3,
        },
        Isometry3::translation(0.35, 0.0, 0.25),
    )
    .expect("post");
    s
}

#[test]
fn paths_are_free_at_1_mm_and_informed_is_no_longer() {
    let cfg = RobotConfig::bundled("locobot").expect("robot");
    let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
    let scene = scene();
    let checker = Checker::new(model, &scene, CheckOptions::default()).expect("checker");
    let problems = bench::generate(&checker, 4, 3, 0.05, None)
        .expect("problems")
        .problems;
    let opts = PlanOptions {
        improve_for: std::time::Duration::from_millis(50),
        // Generous: these problems take milliseconds, and the test is about paths, not
        // time (a busy machine must not fail it).
        time_limit: std::time::Duration::from_secs(30),
        ..PlanOptions::default()
    };
    for (i, p) in problems.iter().enumerate() {
        let fast = RrtConnect
            .plan(&checker, &p.start, &p.goal, &opts)
            .unwrap_or_else(|e| panic!("problem {i}: {e}"));
        let better = InformedRrtStar
            .plan(&checker, &p.start, &p.goal, &opts)
            .unwrap_or_else(|e| panic!("problem {i}: {e}"));
        for plan in [&fast, &better] {
            assert_eq!(plan.path.first(), Some(&p.start));
            assert_eq!(plan.path.last(), Some(&p.goal));
            for w in plan.path.windows(2) {
                assert!(
                    checker.motion_sampled(&w[0], &w[1], 0.001),
                    "problem {i}: an edge collides at 1 mm"
                );
            }
        }
        assert!(
            better.length() <= fast.length() + 1e-9,
            "problem {i}: informed {} rad, RRT-Connect {} rad",
            better.length(),
            fast.length()
        );
    }
}

/// Generated problems can be required to reach a hub: with time to do so every candidate is
/// kept (the table and post cut nothing off), with no time only ends the hub sees straight
/// are kept, and a hub
/// in collision (home, in the post) is refused.
#[test]
fn problems_reach_the_hub() {
    let cfg = RobotConfig::bundled("locobot").expect("robot");
    let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
    let checker = Checker::new(model, &scene(), CheckOptions::default()).expect("checker");
    // Home reaches into the post; a free configuration instead.
    let home = cfg.arm.as_ref().expect("arm").home.clone();
    assert!(!checker.is_free(&home));
    let home = {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let limits = checker.model().limits().to_vec();
        std::iter::repeat_with(|| {
            limits
                .iter()
                .map(|&(lo, hi)| rng.random_range(lo..=hi))
                .collect::<Vec<f64>>()
        })
        .find(|q| checker.is_free(q))
        .expect("a free configuration")
    };
    let reach = |s: f64| bench::Reach {
        hub: home.clone(),
        within: std::time::Duration::from_secs_f64(s),
    };
    let set = bench::generate(&checker, 3, 5, 0.05, Some(&reach(30.0))).expect("problems");
    assert_eq!((set.problems.len(), set.unreached), (3, 0));
    // No time to search: only ends the hub sees straight are kept.
    let hasty = bench::generate(&checker, 2, 5, 0.05, Some(&reach(1e-9))).expect("problems");
    assert!(hasty.unreached > 0);
    for p in &hasty.problems {
        assert!(checker.motion_free(&home, &p.start) && checker.motion_free(&home, &p.goal));
    }
    let mut inside = reach(30.0);
    inside.hub = cfg.arm.as_ref().expect("arm").home.clone();
    assert!(bench::generate(&checker, 1, 5, 0.05, Some(&inside)).is_err());
}

/// Seven waypoints evenly spaced from `a` to `b` (rad).
fn seven_waypoints(a: &[f64], b: &[f64]) -> Vec<Vec<f64>> {
    (0..=6)
        .map(|k| {
            a.iter()
                .zip(b)
                .map(|(x, y)| x + (y - x) * f64::from(k) / 6.0)
                .collect()
        })
        .collect()
}

/// `path` shortcut with `opts` (sampler seed 1), and how many edges that checked.
fn shortcut_counted(
    checker: &Checker,
    path: &[Vec<f64>],
    opts: &PlanOptions,
) -> (Vec<Vec<f64>>, u64) {
    use rand::SeedableRng;
    use std::sync::atomic::Ordering;
    let before = checker.counters().edges.load(Ordering::Relaxed);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let out = ferrobot_planning::planner::shortcut(
        checker,
        path.to_vec(),
        opts,
        &mut rng,
        std::time::Instant::now(),
    );
    (
        out,
        checker.counters().edges.load(Ordering::Relaxed) - before,
    )
}

/// Shortcutting checks only shortcuts that save at least `shortcut_min_gain`: on a straight
/// path with a 1 mrad kink, a gain of 0.01 rad checks no shortcut edge (only the final pass's
/// few), none checks dozens; both end on the straight path. Hostile gains are refused.
#[test]
fn shortcuts_that_save_too_little_are_not_checked() {
    let checker = crate::locobot_alone();
    let (a, b) = ([0.0, 0.2, 0.3, 0.1, 0.0], [0.6, 0.2, 0.3, 0.1, 0.0]);
    let mut path = seven_waypoints(&a, &b);
    // A kink of 1 mrad sideways at the middle: a shortcut saves about 3e-6 rad.
    path[3][1] += 0.001;
    let straight = ferrobot_planning::planner::path_length(&[a.to_vec(), b.to_vec()]);
    let edges = |min_gain: f64| {
        let opts = PlanOptions {
            shortcut_min_gain: min_gain,
            time_limit: std::time::Duration::from_secs(30),
            ..PlanOptions::default()
        };
        let (out, checked) = shortcut_counted(&checker, &path, &opts);
        let len = ferrobot_planning::planner::path_length(&out);
        assert!(
            (len - straight).abs() < 1e-9,
            "{min_gain}: {len} rad, straight {straight}"
        );
        checked
    };
    let (skipping, checking) = (edges(0.01), edges(0.0));
    assert!(
        skipping <= 6,
        "{skipping} edges checked with a gain of 0.01 rad"
    );
    assert!(checking >= 30, "only {checking} edges checked with no gain");
    for bad in [f64::NAN, -0.01, f64::INFINITY, 1e9] {
        let opts = PlanOptions {
            shortcut_min_gain: bad,
            ..PlanOptions::default()
        };
        let err = RrtConnect
            .plan(&checker, &a, &b, &opts)
            .expect_err("a hostile gain is refused");
        assert!(err.to_string().contains("shortcut_min_gain"), "{err}");
    }
}

/// Shortcutting's last pass goes from each waypoint it keeps to the farthest one it sees: on a
/// free path of seven waypoints, with no random shortcuts, one edge is checked (dropping one
/// waypoint at a time checked five) and the path becomes that edge. Empty and one-edge paths
/// come back unchanged.
#[test]
fn the_last_pass_goes_to_the_farthest_waypoint_seen() {
    let checker = crate::locobot_alone();
    let mut path = seven_waypoints(&[0.0, 0.2, 0.3, 0.1, 0.0], &[0.6, -0.2, 0.3, 0.4, 0.2]);
    // Every other waypoint 0.01 rad off in every joint: no two edges in line.
    for q in path.iter_mut().skip(1).step_by(2) {
        q.iter_mut().for_each(|v| *v += 0.01);
    }
    let opts = PlanOptions {
        shortcuts: 0,
        time_limit: std::time::Duration::from_secs(30),
        ..PlanOptions::default()
    };
    let (out, checked) = shortcut_counted(&checker, &path, &opts);
    assert_eq!(out, [path[0].clone(), path[6].clone()]);
    assert_eq!(checked, 1, "{checked} edges checked");
    // Paths too short to shorten come back as they are, with nothing checked.
    for short in [&path[..0], &path[..1], &path[..2]] {
        assert_eq!(
            shortcut_counted(&checker, short, &opts),
            (short.to_vec(), 0)
        );
    }
}

/// Every option out of its range is refused with an error naming it, by both planners, before
/// any planning: time limits, ranges, gains, shortcut counts and Informed RRT*'s improvement
/// time (`Duration::MAX` once overflowed the deadline's sum and panicked).
#[test]
fn options_out_of_range_are_refused_by_both_planners() {
    use std::time::Duration;
    let checker = crate::locobot_alone();
    let (a, b) = ([0.0, 0.2, 0.3, 0.1, 0.0], [0.6, 0.2, 0.3, 0.1, 0.0]);
    let bad: Vec<(&str, PlanOptions)> = vec![
        (
            "time limit",
            PlanOptions {
                time_limit: Duration::ZERO,
                ..PlanOptions::default()
            },
        ),
        (
            "time limit",
            PlanOptions {
                time_limit: Duration::MAX,
                ..PlanOptions::default()
            },
        ),
        (
            "range",
            PlanOptions {
                range: Some(f64::NAN),
                ..PlanOptions::default()
            },
        ),
        (
            "shortcut attempts",
            PlanOptions {
                shortcuts: usize::MAX,
                ..PlanOptions::default()
            },
        ),
        (
            "improve_for",
            PlanOptions {
                improve_for: Duration::MAX,
                ..PlanOptions::default()
            },
        ),
        (
            "improve_for",
            PlanOptions {
                improve_for: Duration::from_secs(601),
                ..PlanOptions::default()
            },
        ),
    ];
    for (what, opts) in &bad {
        for planner in [&RrtConnect as &dyn Planner, &InformedRrtStar] {
            let err = planner.plan(&checker, &a, &b, opts).expect_err("refused");
            assert!(err.to_string().contains(what), "{}: {err}", planner.name());
        }
    }
    // The largest improvement time allowed plans (and stops at the time limit).
    let opts = PlanOptions {
        improve_for: Duration::from_secs(600),
        time_limit: Duration::from_millis(200),
        ..PlanOptions::default()
    };
    let plan = InformedRrtStar
        .plan(&checker, &a, &b, &opts)
        .expect("plans");
    assert!(plan.time < Duration::from_secs(5), "{:?}", plan.time);
}
