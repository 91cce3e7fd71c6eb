//! Time-optimal trajectory timing (`ferrobot_planning::timing`).

use ferrobot_planning::timing::{time_optimal, Limits, TimingOptions, Trajectory};

fn report(traj: &Trajectory, lim: &Limits) -> (f64, f64) {
    let (mut mv, mut ma) = (0.0f64, 0.0f64);
    for p in traj.samples(1e-3) {
        for i in 0..traj.dof() {
            mv = mv.max(p.velocity[i].abs() / lim.velocity[i]);
            ma = ma.max(p.acceleration[i].abs() / lim.acceleration[i]);
        }
    }
    (mv, ma)
}

#[test]
fn scratch() {
    let lim = Limits {
        velocity: vec![1.0, 2.0, 1.5],
        acceleration: vec![2.0, 3.0, 1.0],
    };
    let path = vec![vec![0.0, 0.0, 0.0], vec![1.0, 0.5, -0.3]];
    let t = time_optimal(&path, &lim, &TimingOptions::default()).unwrap();
    println!("straight {} {:?}", t.duration(), report(&t, &lim));
    let path = vec![
        vec![0.0, 0.0, 0.0],
        vec![1.0, 0.5, -0.3],
        vec![0.0, 1.0, 0.5],
        vec![1.0, 1.5, 0.0],
        vec![0.2, 2.0, 1.0],
    ];
    for md in [0.0, 0.01, 0.05, 0.2, 1.0] {
        let t = time_optimal(
            &path,
            &lim,
            &TimingOptions {
                max_deviation: md,
                ..Default::default()
            },
        )
        .unwrap();
        println!(
            "zigzag md {md}: {} {:?} len {}",
            t.duration(),
            report(&t, &lim),
            t.path_length()
        );
    }
}
