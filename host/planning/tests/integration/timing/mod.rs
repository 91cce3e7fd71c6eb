//! Time-optimal trajectory timing (`ferrobot_planning::timing`): the limits at every sample,
//! the analytic profile of a straight segment, the end points, the geometry of the blends,
//! the gain from blending, degenerate and hostile inputs; random paths in [`random`].

use ferrobot_planning::joint_space::dist;
use ferrobot_planning::timing::{time_optimal, Limits, TimingOptions, Trajectory};
use ferrobot_planning::Error;

mod random;

/// Sampling period of the checks, s.
const DT: f64 = 1e-3;
/// Allowed relative excess of a joint velocity over its limit: rounding only (the profile is
/// kept under the velocity limit curve at its knots and, on the arcs, along the chords
/// between them).
const VEL_TOL: f64 = 1e-6;
/// Allowed relative excess of a joint acceleration over its limit: 1e-6 of rounding plus
/// 1e-3 of integration slack. The path acceleration is constant between knots and checked
/// against the limits at both ends of each step; on an arc a step turns the tangent by at most
/// 0.005 rad, so in between the limits drift by a second-order amount. Measured over 30 000
/// random paths (time steps 1e-5 to 0.1 s): at most 1.5e-5 (velocity: 5e-8); the slack leaves
/// 60× margin.
const ACC_TOL: f64 = 1e-6 + 1e-3;

fn opts(max_deviation: f64) -> TimingOptions {
    TimingOptions {
        max_deviation,
        ..TimingOptions::default()
    }
}

/// Every sample every [`DT`] (and the end) within the limits; returns the largest ratios
/// |q̇|/v and |q̈|/a seen.
fn assert_within_limits(traj: &Trajectory, limits: &Limits) -> (f64, f64) {
    let (mut worst_v, mut worst_a) = (0.0f64, 0.0f64);
    for p in traj.samples(DT) {
        for i in 0..traj.dof() {
            let rv = p.velocity[i].abs() / limits.velocity[i];
            let ra = p.acceleration[i].abs() / limits.acceleration[i];
            assert!(
                rv <= 1.0 + VEL_TOL,
                "joint {i} at t = {} s: velocity {} rad/s over the limit {} (ratio {rv}, allowed 1 + {VEL_TOL})",
                p.time,
                p.velocity[i],
                limits.velocity[i]
            );
            assert!(
                ra <= 1.0 + ACC_TOL,
                "joint {i} at t = {} s: acceleration {} rad/s² over the limit {} (ratio {ra}, allowed 1 + {ACC_TOL})",
                p.time,
                p.acceleration[i],
                limits.acceleration[i]
            );
            worst_v = worst_v.max(rv);
            worst_a = worst_a.max(ra);
        }
    }
    (worst_v, worst_a)
}

/// Starts and ends at rest exactly on the first and last waypoints.
fn assert_rest_to_rest(traj: &Trajectory, path: &[Vec<f64>]) {
    let (a, b) = (traj.sample(0.0), traj.sample(traj.duration()));
    assert_eq!(
        a.position, path[0],
        "the start is the first waypoint exactly"
    );
    assert_eq!(
        b.position,
        path[path.len() - 1],
        "the end is the last waypoint exactly"
    );
    assert!(a.velocity.iter().all(|&v| v == 0.0), "at rest at the start");
    assert!(b.velocity.iter().all(|&v| v == 0.0), "at rest at the end");
    assert_eq!(b.time, traj.duration());
}

/// Distance from `p` to the polyline through `path`.
fn dist_to_polyline(path: &[Vec<f64>], p: &[f64]) -> f64 {
    if path.len() == 1 {
        return dist(&path[0], p);
    }
    path.windows(2)
        .map(|w| {
            let (a, b) = (&w[0], &w[1]);
            let ab: Vec<f64> = a.iter().zip(b).map(|(x, y)| y - x).collect();
            let len2: f64 = ab.iter().map(|x| x * x).sum();
            let f = if len2 > 0.0 {
                (a.iter()
                    .zip(p)
                    .zip(&ab)
                    .map(|((x, y), d)| (y - x) * d)
                    .sum::<f64>()
                    / len2)
                    .clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q: Vec<f64> = a.iter().zip(&ab).map(|(x, d)| x + f * d).collect();
            dist(&q, p)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Rest-to-rest time along a straight line of length `len` with path speed and acceleration
/// limits `v` and `a`: a trapezoid, or a triangle when too short to reach `v`.
fn trapezoid_time(len: f64, v: f64, a: f64) -> f64 {
    if len <= v * v / a {
        2.0 * (len / a).sqrt()
    } else {
        len / v + v / a
    }
}

/// Path speed and acceleration limits along the straight line from `a` to `b`.
fn line_limits(a: &[f64], b: &[f64], limits: &Limits) -> (f64, f64, f64) {
    let len = dist(a, b);
    let (mut v, mut acc) = (f64::INFINITY, f64::INFINITY);
    for i in 0..a.len() {
        let t = ((b[i] - a[i]) / len).abs();
        if t > 0.0 {
            v = v.min(limits.velocity[i] / t);
            acc = acc.min(limits.acceleration[i] / t);
        }
    }
    (len, v, acc)
}

/// Stopping at every corner: the sum of the segments' trapezoids (a repeated waypoint adds
/// nothing: there is no motion to time, and its line of zero length has no direction to
/// bound the speed by).
fn naive_time(path: &[Vec<f64>], limits: &Limits) -> f64 {
    path.windows(2)
        .filter(|w| w[0] != w[1])
        .map(|w| {
            let (len, v, a) = line_limits(&w[0], &w[1], limits);
            trapezoid_time(len, v, a)
        })
        .sum()
}

fn zigzag() -> (Vec<Vec<f64>>, Limits) {
    let path = vec![
        vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        vec![1.0, 0.5, -0.3, 0.2, 0.8, -0.4],
        vec![0.1, 1.0, 0.4, -0.5, 0.2, 0.3],
        vec![1.2, 1.4, -0.2, 0.1, -0.6, 0.9],
        vec![0.3, 2.0, 0.6, 0.7, 0.1, 0.2],
        vec![1.5, 2.3, 0.0, 0.0, 0.9, -0.5],
    ];
    let limits = Limits {
        velocity: vec![1.0, 1.5, 2.0, 1.2, 2.5, 3.0],
        acceleration: vec![2.0, 3.0, 4.0, 2.5, 6.0, 8.0],
    };
    (path, limits)
}

#[test]
fn straight_segment_is_the_trapezoid_of_the_slowest_joint() {
    // Joint 0 moves farthest for its limits: it is the slowest for speed and acceleration.
    let path = vec![vec![0.0, 0.5, -1.0], vec![3.0, 1.5, -1.5]];
    let limits = Limits {
        velocity: vec![1.0, 2.0, 1.5],
        acceleration: vec![2.0, 3.0, 2.0],
    };
    let traj = time_optimal(&path, &limits, &opts(0.05)).unwrap();
    // Joint 0: 3 rad at 1 rad/s and 2 rad/s²: 0.5 s up, 2.5 s cruising, 0.5 s down.
    let expected = trapezoid_time(3.0, 1.0, 2.0);
    assert!((expected - 3.5).abs() < 1e-12);
    assert!(
        (traj.duration() - expected).abs() < 1e-3,
        "duration {} s, trapezoid {expected} s (tolerance 1e-3 s)",
        traj.duration()
    );
    // The profile itself, against the textbook trapezoid of joint 0 (the others are scaled).
    for k in 0..=350 {
        let t = k as f64 * 0.01;
        let q0 = if t < 0.5 {
            t * t
        } else if t < 3.0 {
            0.25 + (t - 0.5)
        } else {
            3.0 - (3.5 - t).max(0.0).powi(2)
        };
        let p = traj.sample(t);
        assert!(
            (p.position[0] - q0).abs() < 1e-6,
            "t = {t}: q0 = {}, trapezoid {q0} (tolerance 1e-6 rad)",
            p.position[0]
        );
        let f = q0 / 3.0;
        assert!((p.position[1] - (0.5 + f)).abs() < 1e-6, "joint 1 scaled");
        assert!(
            (p.position[2] - (-1.0 - 0.5 * f)).abs() < 1e-6,
            "joint 2 scaled"
        );
    }
    let peak = traj.sample(1.75);
    assert!(
        (peak.velocity[0] - 1.0).abs() < 1e-9,
        "cruising at joint 0's limit, got {} rad/s",
        peak.velocity[0]
    );
    assert!((traj.sample(0.25).acceleration[0] - 2.0).abs() < 1e-9);
    assert!((traj.sample(3.25).acceleration[0] + 2.0).abs() < 1e-9);
    assert_within_limits(&traj, &limits);
    assert_rest_to_rest(&traj, &path);
}

#[test]
fn straight_segment_limited_by_different_joints_is_the_path_trapezoid() {
    // Joint 0 bounds the speed, joint 1 the acceleration.
    let path = vec![vec![0.0, 0.0], vec![2.0, 2.0]];
    let limits = Limits {
        velocity: vec![0.5, 3.0],
        acceleration: vec![5.0, 1.0],
    };
    let traj = time_optimal(&path, &limits, &TimingOptions::default()).unwrap();
    let (len, v, a) = line_limits(&path[0], &path[1], &limits);
    let expected = trapezoid_time(len, v, a);
    assert!(
        (traj.duration() - expected).abs() < 1e-3,
        "duration {} s, trapezoid {expected} s (tolerance 1e-3 s)",
        traj.duration()
    );
    let (worst_v, worst_a) = assert_within_limits(&traj, &limits);
    assert!(
        worst_v > 1.0 - 1e-9,
        "joint 0 reaches its speed limit (ratio {worst_v})"
    );
    assert!(
        worst_a > 1.0 - 1e-9,
        "joint 1 reaches its acceleration limit (ratio {worst_a})"
    );
}

#[test]
fn short_segment_is_a_triangle() {
    let path = vec![vec![0.0, 0.0, 0.0], vec![0.2, -0.1, 0.05]];
    let limits = Limits::uniform(3, 1.0, 2.0);
    let traj = time_optimal(&path, &limits, &TimingOptions::default()).unwrap();
    let (len, v, a) = line_limits(&path[0], &path[1], &limits);
    assert!(len < v * v / a, "too short to reach full speed");
    let expected = 2.0 * (len / a).sqrt();
    assert!(
        (traj.duration() - expected).abs() < 1e-3,
        "duration {} s, triangle {expected} s (tolerance 1e-3 s)",
        traj.duration()
    );
    // Peak path speed at half time: sqrt(len a), below the speed limit.
    let mid = traj.sample(0.5 * traj.duration());
    let speed = mid.velocity.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!(
        (speed - (len * a).sqrt()).abs() < 1e-6 && speed < v,
        "peak speed {speed} rad/s, triangle {} rad/s (tolerance 1e-6)",
        (len * a).sqrt()
    );
    assert_within_limits(&traj, &limits);
    assert_rest_to_rest(&traj, &path);
}

#[test]
fn one_joint_follows_the_textbook_profile() {
    let path = vec![vec![-1.0], vec![1.0]];
    let limits = Limits::uniform(1, 1.0, 2.0);
    let traj = time_optimal(&path, &limits, &TimingOptions::default()).unwrap();
    // 2 rad: 0.5 s up to 1 rad/s (0.25 rad), 1.5 s cruising, 0.5 s down.
    assert!((traj.duration() - 2.5).abs() < 1e-9, "{}", traj.duration());
    for (t, q, v) in [
        (0.25, -1.0 + 0.0625, 0.5),
        (1.25, 0.0, 1.0),
        (2.25, 1.0 - 0.0625, 0.5),
    ] {
        let p = traj.sample(t);
        assert!(
            (p.position[0] - q).abs() < 1e-9 && (p.velocity[0] - v).abs() < 1e-9,
            "t = {t}: {p:?} (expected q {q}, v {v}, tolerance 1e-9)"
        );
    }
}

#[test]
fn starts_and_ends_at_rest_on_the_exact_waypoints() {
    let (path, limits) = zigzag();
    for md in [0.0, 0.01, 0.05, 0.3, 1.0] {
        let traj = time_optimal(&path, &limits, &opts(md)).unwrap();
        assert_rest_to_rest(&traj, &path);
        // Times are clamped.
        assert_eq!(traj.sample(-1.0).position, path[0]);
        assert_eq!(traj.sample(f64::NEG_INFINITY).position, path[0]);
        assert_eq!(traj.sample(traj.duration() + 5.0).position, path[5]);
        assert_eq!(traj.sample(f64::INFINITY).position, path[5]);
        assert_eq!(traj.path_position(0.0), path[0]);
        assert_eq!(traj.path_position(traj.path_length()), path[5]);
    }
}

#[test]
fn limits_hold_at_every_sample_of_blended_paths() {
    let (path, limits) = zigzag();
    for md in [0.0, 0.001, 0.02, 0.05, 0.2, 1.0] {
        let traj = time_optimal(&path, &limits, &opts(md)).unwrap();
        let (v, a) = assert_within_limits(&traj, &limits);
        // Time-optimal: some joint is at a limit somewhere.
        assert!(
            v > 1.0 - 1e-6 || a > 1.0 - 1e-3,
            "max_deviation {md}: nothing at its limit (velocity ratio {v}, acceleration {a})"
        );
    }
}

#[test]
fn blended_path_stays_within_max_deviation_and_passes_each_waypoint() {
    let (path, limits) = zigzag();
    for md in [0.01, 0.05, 0.2] {
        let traj = time_optimal(&path, &limits, &opts(md)).unwrap();
        // The geometric path, densely.
        let n = (traj.path_length() / 1e-3).ceil() as usize;
        let mut closest = vec![f64::INFINITY; path.len()];
        for k in 0..=n {
            let q = traj.path_position(k as f64 * traj.path_length() / n as f64);
            let d = dist_to_polyline(&path, &q);
            assert!(
                d <= md + 1e-9,
                "path point {q:?} is {d} rad from the polyline, max {md}"
            );
            for (c, w) in closest.iter_mut().zip(&path) {
                *c = c.min(dist(w, &q));
            }
        }
        for (i, c) in closest.iter().enumerate() {
            assert!(
                *c <= md + 1e-3,
                "the path passes waypoint {i} no nearer than {c} rad (max {md} + 1e-3 of sampling)"
            );
        }
        // The trajectory's samples: on the same tube, near each waypoint.
        let max_speed: f64 = limits.velocity.iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut closest = vec![f64::INFINITY; path.len()];
        for p in traj.samples(DT) {
            let d = dist_to_polyline(&path, &p.position);
            assert!(
                d <= md + 1e-9,
                "sample at {} s is {d} rad from the polyline, max {md}",
                p.time
            );
            for (c, w) in closest.iter_mut().zip(&path) {
                *c = c.min(dist(w, &p.position));
            }
        }
        for (i, c) in closest.iter().enumerate() {
            assert!(
                *c <= md + 0.5 * max_speed * DT + 1e-9,
                "the samples pass waypoint {i} no nearer than {c} rad"
            );
        }
    }
}

#[test]
fn blending_is_faster_than_stopping_at_every_corner() {
    let (path, limits) = zigzag();
    let naive = naive_time(&path, &limits);
    let stop = time_optimal(&path, &limits, &opts(0.0)).unwrap();
    assert!(
        (stop.duration() - naive).abs() < 1e-3,
        "max_deviation 0: {} s, the trapezoids add up to {naive} s (tolerance 1e-3 s)",
        stop.duration()
    );
    let mut previous = stop.duration();
    for md in [0.02, 0.05, 0.2] {
        let blended = time_optimal(&path, &limits, &opts(md)).unwrap();
        assert!(
            blended.duration() < previous - 0.01,
            "max_deviation {md}: {} s, not shorter than {previous} s (by 0.01 s)",
            blended.duration()
        );
        previous = blended.duration();
    }
}

#[test]
fn without_blending_the_motion_stops_on_every_corner() {
    let (path, limits) = zigzag();
    let traj = time_optimal(&path, &limits, &opts(0.0)).unwrap();
    let mut t = 0.0;
    for w in path.windows(2) {
        let (len, v, a) = line_limits(&w[0], &w[1], &limits);
        t += trapezoid_time(len, v, a);
        let p = traj.sample(t);
        assert!(
            dist(&p.position, &w[1]) < 1e-6,
            "at {t} s: {:?}, the corner is {:?} (tolerance 1e-6 rad)",
            p.position,
            w[1]
        );
        assert!(
            p.velocity.iter().all(|v| v.abs() < 1e-3),
            "at rest on the corner: {:?}",
            p.velocity
        );
    }
}

#[test]
fn repeated_and_collinear_waypoints_go_straight_through() {
    let a = vec![0.0, 1.0, -0.5];
    let b = vec![2.0, 0.0, 0.5];
    let on = |f: f64| -> Vec<f64> { a.iter().zip(&b).map(|(x, y)| x + f * (y - x)).collect() };
    let limits = Limits::uniform(3, 1.0, 1.5);
    let straight = time_optimal(&[a.clone(), b.clone()], &limits, &opts(0.05)).unwrap();
    let path = vec![
        a.clone(),
        a.clone(),
        on(0.25),
        on(0.25),
        on(0.6),
        on(0.9),
        b.clone(),
        b.clone(),
    ];
    for md in [0.0, 0.05] {
        let traj = time_optimal(&path, &limits, &opts(md)).unwrap();
        assert!(
            (traj.duration() - straight.duration()).abs() < 1e-9,
            "max_deviation {md}: {} s, the straight line takes {} s",
            traj.duration(),
            straight.duration()
        );
        assert_rest_to_rest(&traj, &path);
        assert!((traj.path_length() - dist(&a, &b)).abs() < 1e-12);
    }
}

#[test]
fn a_single_point_is_a_trajectory_of_zero_duration() {
    let limits = Limits::uniform(3, 1.0, 1.0);
    for path in [vec![vec![0.1, 0.2, 0.3]], vec![vec![0.1, 0.2, 0.3]; 4]] {
        let traj = time_optimal(&path, &limits, &opts(0.05)).unwrap();
        assert_eq!(traj.duration(), 0.0);
        assert_eq!(traj.path_length(), 0.0);
        assert_eq!(traj.dof(), 3);
        let p = traj.sample(1.0);
        assert_eq!(p.position, path[0]);
        assert_eq!(p.velocity, vec![0.0; 3]);
        assert_eq!(p.acceleration, vec![0.0; 3]);
        let all = traj.samples(DT);
        assert_eq!(all.len(), 1, "the start is the end");
        assert_eq!(all[0].time, 0.0);
        assert_eq!(traj.path_position(3.0), path[0]);
    }
}

#[test]
fn joints_that_do_not_move_stay_exactly_still() {
    let path = vec![
        vec![0.0, 0.7, 0.0, -0.2],
        vec![1.0, 0.7, 0.5, -0.2],
        vec![0.2, 0.7, 1.2, -0.2],
        vec![1.1, 0.7, 0.3, -0.2],
    ];
    let limits = Limits {
        velocity: vec![1.0, 0.1, 1.5, 0.2],
        acceleration: vec![2.0, 0.1, 3.0, 0.3],
    };
    let traj = time_optimal(&path, &limits, &opts(0.1)).unwrap();
    for p in traj.samples(DT) {
        for i in [1, 3] {
            assert_eq!(p.position[i], path[0][i], "joint {i} at {} s", p.time);
            assert_eq!(p.velocity[i], 0.0);
            assert_eq!(p.acceleration[i], 0.0);
        }
    }
    assert_within_limits(&traj, &limits);
}

#[test]
fn turning_back_stops_at_the_turn() {
    let a = vec![0.0, 0.0];
    let b = vec![1.0, 0.5];
    let path = vec![a.clone(), b.clone(), a.clone()];
    let limits = Limits::uniform(2, 1.0, 2.0);
    let traj = time_optimal(&path, &limits, &opts(0.1)).unwrap();
    let (len, v, acc) = line_limits(&a, &b, &limits);
    let one_way = trapezoid_time(len, v, acc);
    assert!(
        (traj.duration() - 2.0 * one_way).abs() < 1e-9,
        "{} s, twice {one_way} s",
        traj.duration()
    );
    let turn = traj.sample(one_way);
    assert!(dist(&turn.position, &b) < 1e-9, "{:?}", turn.position);
    assert!(turn.velocity.iter().all(|v| v.abs() < 1e-9));
    assert_within_limits(&traj, &limits);
}

#[test]
fn positions_velocities_and_accelerations_agree() {
    let (path, limits) = zigzag();
    let traj = time_optimal(&path, &limits, &opts(0.05)).unwrap();
    let h = 1e-6;
    let (mut checked, mut off) = (0, 0);
    let mut t = h;
    while t < traj.duration() - h {
        let (a, p, b) = (traj.sample(t - h), traj.sample(t), traj.sample(t + h));
        for i in 0..traj.dof() {
            let v = (b.position[i] - a.position[i]) / (2.0 * h);
            assert!(
                (v - p.velocity[i]).abs() < 1e-6 * (1.0 + limits.velocity[i]),
                "t = {t}, joint {i}: velocity {} rad/s, positions say {v}",
                p.velocity[i]
            );
            // The path acceleration jumps at the knots of the profile: a difference across
            // one is no test, so count the disagreements instead.
            let acc = (b.velocity[i] - a.velocity[i]) / (2.0 * h);
            checked += 1;
            if (acc - p.acceleration[i]).abs() > 1e-3 * limits.acceleration[i] {
                off += 1;
            }
        }
        t += 0.0137;
    }
    assert!(
        off * 100 < checked,
        "{off} of {checked} accelerations disagree with the velocities by more than 0.1 %"
    );
}

#[test]
fn a_finer_time_step_changes_the_duration_little() {
    let (path, limits) = zigzag();
    let coarse = time_optimal(&path, &limits, &opts(0.05)).unwrap();
    let fine = time_optimal(
        &path,
        &limits,
        &TimingOptions {
            max_deviation: 0.05,
            time_step: 1e-4,
        },
    )
    .unwrap();
    let (c, f) = (coarse.duration(), fine.duration());
    assert!(
        (c - f).abs() < 1e-3 * f,
        "time step 1 ms: {c} s, 0.1 ms: {f} s (tolerance 0.1 %)"
    );
}

/// An independent timing of `traj`'s blended path: first-order collocation on `n` intervals
/// (the reachability method of TOPP-RA: a backward pass of the largest squared speed from
/// which the end stays reachable, then a greedy forward pass), with the path's tangent and
/// curvature by finite differences of [`Trajectory::path_position`]. It tends to the optimum
/// as `n` grows.
fn grid_time(traj: &Trajectory, limits: &Limits, n: usize) -> f64 {
    let len = traj.path_length();
    let ds = len / n as f64;
    let h = 0.25 * ds;
    let dof = traj.dof();
    let derivatives: Vec<(Vec<f64>, Vec<f64>)> = (0..=n)
        .map(|i| {
            let s = i as f64 * ds;
            let (a, b) = ((s - h).max(0.0), (s + h).min(len));
            let (qa, q, qb) = (
                traj.path_position(a),
                traj.path_position(s),
                traj.path_position(b),
            );
            let t = (0..dof).map(|j| (qb[j] - qa[j]) / (b - a)).collect();
            let c = if a < s && s < b {
                (0..dof)
                    .map(|j| (qb[j] - 2.0 * q[j] + qa[j]) / (h * h))
                    .collect()
            } else {
                vec![0.0; dof]
            };
            (t, c)
        })
        .collect();
    // Path accelerations allowed at grid point `i` with squared speed `x`.
    let range = |i: usize, x: f64| -> Option<(f64, f64)> {
        let (t, c) = &derivatives[i];
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for j in 0..dof {
            let a = limits.acceleration[j];
            if t[j] * t[j] * x > limits.velocity[j] * limits.velocity[j] {
                return None;
            }
            if t[j].abs() < 1e-9 {
                if (c[j] * x).abs() > a {
                    return None;
                }
                continue;
            }
            let (p, q) = ((-a - c[j] * x) / t[j], (a - c[j] * x) / t[j]);
            let (l, u) = if t[j] > 0.0 { (p, q) } else { (q, p) };
            lo = lo.max(l);
            hi = hi.min(u);
        }
        (lo <= hi).then_some((lo, hi))
    };
    let mut top = vec![0.0; n + 1];
    for i in (0..n).rev() {
        let next = top[i + 1];
        let ok = |x: f64| {
            range(i, x)
                .is_some_and(|(lo, hi)| lo.max(-x / (2.0 * ds)) <= hi.min((next - x) / (2.0 * ds)))
        };
        let (t, _) = &derivatives[i];
        let mut bad = (0..dof)
            .filter(|&j| t[j] != 0.0)
            .map(|j| (limits.velocity[j] / t[j]).powi(2))
            .fold(f64::INFINITY, f64::min)
            * 1.000001;
        let mut good = 0.0;
        for _ in 0..60 {
            let mid = 0.5 * (good + bad);
            if ok(mid) {
                good = mid;
            } else {
                bad = mid;
            }
        }
        top[i] = good;
    }
    let (mut x, mut time) = (0.0f64, 0.0);
    for i in 0..n {
        let hi = range(i, x).map_or(0.0, |r| r.1);
        let x1 = (x + 2.0 * ds * hi).clamp(0.0, top[i + 1]);
        time += 2.0 * ds / (x.sqrt() + x1.sqrt());
        x = x1;
    }
    time
}

#[test]
fn duration_matches_an_independent_grid_solution() {
    // (Blended paths only: the grid knows nothing of stopping at a sharp corner.)
    let (path, limits) = zigzag();
    for md in [0.01, 0.02, 0.05, 0.2, 1.0] {
        let traj = time_optimal(&path, &limits, &opts(md)).unwrap();
        let grid = grid_time(&traj, &limits, 20_000);
        println!("max_deviation {md}: {} s, grid {grid} s", traj.duration());
        assert!(
            (traj.duration() - grid).abs() < 2e-3 * grid,
            "max_deviation {md}: {} s, the grid solution {grid} s (tolerance 0.2 %)",
            traj.duration()
        );
    }
}

#[test]
fn samples_come_every_dt_and_at_the_end() {
    let (path, limits) = zigzag();
    let traj = time_optimal(&path, &limits, &opts(0.05)).unwrap();
    let all = traj.samples(0.1);
    let n = (traj.duration() / 0.1).ceil() as usize;
    assert_eq!(all.len(), n + 1);
    for (k, p) in all[..n].iter().enumerate() {
        assert_eq!(p.time, k as f64 * 0.1);
    }
    assert_eq!(all[n].time, traj.duration());
    for dt in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let two = traj.samples(dt);
        assert_eq!(two.len(), 2, "dt {dt}: the two ends");
        assert_eq!(two[0].time, 0.0);
        assert_eq!(two[1].time, traj.duration());
    }
    assert_eq!(traj.samples(1e3).len(), 2);
    // Absurdly small: widened to at most a million samples.
    let many = traj.samples(1e-300);
    assert!(many.len() <= 1_000_001, "{}", many.len());
    assert_eq!(many[many.len() - 1].time, traj.duration());
    assert_eq!(traj.sample(f64::NAN).time, 0.0);
    assert_eq!(traj.path_position(f64::NAN), path[0]);
    assert_eq!(traj.path_position(-3.0), path[0]);
    assert_eq!(traj.path_position(f64::INFINITY), path[5]);
}

#[test]
fn hostile_inputs_are_errors() {
    let good_path = vec![vec![0.0, 0.0], vec![1.0, 1.0], vec![0.0, 2.0]];
    let good = Limits::uniform(2, 1.0, 1.0);
    let o = TimingOptions::default();
    let invalid = |path: &[Vec<f64>], limits: &Limits, opts: &TimingOptions| match time_optimal(
        path, limits, opts,
    ) {
        Err(Error::Invalid { .. }) => {}
        other => panic!("{path:?} {limits:?} {opts:?}: expected Error::Invalid, got {other:?}"),
    };
    invalid(&[], &good, &o);
    invalid(&[vec![], vec![]], &Limits::uniform(0, 1.0, 1.0), &o);
    invalid(&[vec![0.0, 0.0], vec![1.0]], &good, &o);
    for bad in [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e300,
        -1e300,
        1e4,
    ] {
        invalid(&[vec![0.0, 0.0], vec![bad, 1.0]], &good, &o);
    }
    for bad in [f64::NAN, f64::INFINITY, 0.0, -0.0, -1.0, 1e300, 1e-300] {
        let mut l = good.clone();
        l.velocity[1] = bad;
        invalid(&good_path, &l, &o);
        let mut l = good.clone();
        l.acceleration[0] = bad;
        invalid(&good_path, &l, &o);
    }
    invalid(&good_path, &Limits::uniform(3, 1.0, 1.0), &o);
    invalid(
        &good_path,
        &Limits {
            velocity: vec![1.0, 1.0],
            acceleration: vec![1.0],
        },
        &o,
    );
    for md in [f64::NAN, -0.1, 1.5, f64::INFINITY] {
        invalid(&good_path, &good, &opts(md));
    }
    for ts in [0.0, 1e-9, 0.5, f64::NAN, -1e-3, f64::INFINITY] {
        invalid(
            &good_path,
            &good,
            &TimingOptions {
                max_deviation: 0.05,
                time_step: ts,
            },
        );
    }
}

#[test]
fn extreme_but_valid_inputs_finish() {
    // The largest positions and the slowest limits: refused for taking too many steps or
    // timed, but quickly and without panicking.
    let path = vec![
        vec![-1000.0, 1000.0],
        vec![1000.0, 999.0],
        vec![-1000.0, -1000.0],
    ];
    for (v, a, md) in [
        (1e-6, 1e-6, 1.0),
        (1e6, 1e6, 1.0),
        (1e-6, 1e6, 0.5),
        (1e6, 1e-6, 0.0),
    ] {
        match time_optimal(&path, &Limits::uniform(2, v, a), &opts(md)) {
            Ok(traj) => {
                assert!(traj.duration().is_finite() && traj.duration() > 0.0);
                assert_rest_to_rest(&traj, &path);
            }
            Err(Error::Invalid { .. }) => {}
            Err(e) => panic!("unexpected {e}"),
        }
    }
    // Nearly repeated and nearly reversing waypoints.
    let path = vec![
        vec![0.0, 0.0, 0.0],
        vec![1.0, 0.0, 0.0],
        vec![1.0 + 1e-8, 1e-8, 0.0],
        vec![0.0, 1e-7, 0.0],
        vec![0.0, 1e-7, 1e-9],
        vec![0.5, 0.5, 0.5],
    ];
    let limits = Limits::uniform(3, 1.0, 2.0);
    let traj = time_optimal(&path, &limits, &opts(0.05)).unwrap();
    assert_rest_to_rest(&traj, &path);
    assert_within_limits(&traj, &limits);
}

#[test]
fn timing_a_20_waypoint_7_dof_path() {
    // Release timing is measured by `cargo run --release -p ferrobot-planning --example
    // timing_perf`; here it is only printed (debug build).
    let path: Vec<Vec<f64>> = (0..20)
        .map(|k| {
            (0..7)
                .map(|i| ((k * 7 + i) as f64 * 1.618).sin() * 2.0)
                .collect()
        })
        .collect();
    let limits = Limits {
        velocity: vec![2.0, 2.0, 2.5, 2.5, 3.0, 3.0, 3.0],
        acceleration: vec![4.0, 4.0, 5.0, 5.0, 8.0, 8.0, 8.0],
    };
    let start = std::time::Instant::now();
    let traj = time_optimal(&path, &limits, &TimingOptions::default()).unwrap();
    println!(
        "20 waypoints, 7 DOF: timed in {:.2} ms (this build), trajectory {:.2} s",
        start.elapsed().as_secs_f64() * 1e3,
        traj.duration()
    );
    assert_within_limits(&traj, &limits);
    assert_rest_to_rest(&traj, &path);
}
