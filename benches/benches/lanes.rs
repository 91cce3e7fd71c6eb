//! The vectorised collision engine's sphere placement (ferrobot-planning's `lanes`). Run:
//! `cargo bench -p ferrobot-benches --bench lanes`.
//!
//! For the LoCoBot's and the Sawyer's arms: every moving sphere's centre placed for 8 random
//! configurations within the limits, in one call of the vector path (`Wide`) and in 8 calls
//! of the scalar path (`f32`); and, with it, each sphere's distance to a tabletop scene's
//! objects. Time per configuration is the figure to read: the vector path over the scalar's
//! is what the lanes buy.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use ferrobot::planning::lanes::{Environment, Frame, Lane, SphereProgram, Wide, WIDTH};
use ferrobot::planning::{CollisionModel, Shape};
use ferrobot::RobotConfig;
use nalgebra::Isometry3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The model and program of `robot`, and 8 configurations in lanes and one by one.
fn setup(robot: &str) -> (SphereProgram, Vec<Wide>, Vec<Vec<f32>>) {
    let cfg = RobotConfig::bundled(robot).expect("robot");
    let model = CollisionModel::from_config(&cfg).expect("model");
    let program = SphereProgram::new(&model).expect("program");
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let qs: Vec<Vec<f32>> = (0..WIDTH)
        .map(|_| {
            let q = model
                .limits()
                .iter()
                .map(|&(lo, hi)| rng.random_range(lo..hi));
            q.map(|x| x as f32).collect()
        })
        .collect();
    let lanes = (0..program.dof())
        .map(|j| Wide::load(&qs.iter().map(|q| q[j]).collect::<Vec<_>>()))
        .collect();
    (program, lanes, qs)
}

/// A table, a box and a cylinder on it, and a wall behind, in front of the robot.
fn tabletop() -> Environment {
    let mut env = Environment::default();
    let at = |x, y, z| Isometry3::translation(x, y, z);
    env.push("table", &Shape::Box([0.6, 1.0, 0.05]), &at(0.55, 0.0, 0.2));
    env.push("box", &Shape::Box([0.08, 0.08, 0.12]), &at(0.45, 0.1, 0.29));
    let can = Shape::Cylinder {
        radius: 0.04,
        length: 0.15,
    };
    env.push("can", &can, &at(0.5, -0.15, 0.3));
    env.push("wall", &Shape::Box([0.05, 2.0, 1.5]), &at(1.0, 0.0, 0.75));
    env
}

/// Each sphere's smallest distance to `env`, summed (so that nothing is optimised away).
fn clearances<L: Lane>(program: &SphereProgram, env: &Environment, centres: &[[L; 3]]) -> L {
    let mut sum = L::splat(0.0);
    for (s, c) in program.spheres().iter().zip(centres) {
        sum = sum + (env.distance(c) - L::splat(s.radius));
    }
    sum
}

fn bench(c: &mut Criterion) {
    let env = tabletop();
    for robot in ["locobot", "sawyer"] {
        let (program, lanes, qs) = setup(robot);
        let mut g = c.benchmark_group(format!("lanes/{robot}"));
        let (mut frames, mut centres) = (Vec::<Frame<Wide>>::new(), Vec::new());
        g.bench_function("place 8 configurations, vector", |b| {
            b.iter(|| {
                program.place(black_box(&lanes), &mut frames, &mut centres);
                black_box(&centres);
            })
        });
        let (mut one_frames, mut one) = (Vec::<Frame<f32>>::new(), Vec::new());
        g.bench_function("place 8 configurations, scalar", |b| {
            b.iter(|| {
                for q in &qs {
                    program.place(black_box(q), &mut one_frames, &mut one);
                    black_box(&one);
                }
            })
        });
        g.bench_function("place and clear 8 configurations, vector", |b| {
            b.iter(|| {
                program.place(black_box(&lanes), &mut frames, &mut centres);
                black_box(clearances(&program, &env, &centres))
            })
        });
        g.bench_function("place and clear 8 configurations, scalar", |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for q in &qs {
                    program.place(black_box(q), &mut one_frames, &mut one);
                    sum += clearances(&program, &env, &one);
                }
                black_box(sum)
            })
        });
        g.finish();
    }
}

/// The edge checks over the same 400 edges between random free states of `robot` in the
/// tabletop (half of them a quarter of the way to the other state): the checker's
/// advancement and the lanes' proof (with the advancement where the spheres do not prove),
/// total time of each, their ratio, and how often they agree. Printed as a table.
fn edges_table(robot: &str) {
    use ferrobot::planning::{CheckOptions, Checker, PlanningScene};
    use std::sync::Arc;
    use std::time::Instant;
    let mut scene = PlanningScene::new();
    let at = |x, y, z| Isometry3::translation(x, y, z);
    scene
        .add_object("table", Shape::Box([0.6, 1.0, 0.05]), at(0.55, 0.0, 0.2))
        .unwrap();
    scene
        .add_object("box", Shape::Box([0.08, 0.08, 0.12]), at(0.45, 0.1, 0.29))
        .unwrap();
    let can = Shape::Cylinder {
        radius: 0.04,
        length: 0.15,
    };
    scene.add_object("can", can, at(0.5, -0.15, 0.3)).unwrap();
    let cfg = RobotConfig::bundled(robot).expect("robot");
    let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
    let checker = Checker::new(model.clone(), &scene, CheckOptions::default()).expect("checker");
    let lanes = checker.lane_checks().expect("lanes").expect("no voxels");
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let mut free = || loop {
        let q: Vec<f64> = model
            .limits()
            .iter()
            .map(|&(lo, hi)| rng.random_range(lo..hi))
            .collect();
        if checker.is_free(&q) {
            return q;
        }
    };
    let edges: Vec<(Vec<f64>, Vec<f64>)> = (0..400)
        .map(|i| {
            let (a, far) = (free(), free());
            let f = if i % 2 == 0 { 0.25 } else { 1.0 };
            let b = a.iter().zip(&far).map(|(x, y)| x + (y - x) * f).collect();
            (a, b)
        })
        .collect();
    let time = |f: &dyn Fn(&[f64], &[f64]) -> bool| {
        let t = Instant::now();
        let out: Vec<bool> = edges.iter().map(|(a, b)| f(a, b)).collect();
        (t.elapsed().as_secs_f64(), out)
    };
    let (today, a) = time(&|a, b| checker.advanced(a, b));
    let (vector, b) = time(&|x, y| checker.motion_free_in_lanes(&lanes, x, y));
    let (scalar, c) = time(&|x, y| checker.motion_free_in_lanes_scalar(&lanes, x, y));
    assert_eq!(b, c, "the scalar path answers as the vector path");
    let agree = a.iter().zip(&b).filter(|(x, y)| x == y).count();
    let free_today = a.iter().filter(|&&x| x).count();
    let per = |t: f64| t / edges.len() as f64 * 1e6;
    println!(
        "| {robot} | {:?} | {} | {free_today} | {:.1} µs | {:.1} µs | {:.1} µs | {:.2}× | {agree} |",
        checker.engine(),
        edges.len(),
        per(today),
        per(vector),
        per(scalar),
        today / vector,
    );
}

fn tables(_: &mut Criterion) {
    println!("\n| robot | default engine | edges | free (advancement) | advancement, per edge | lanes, per edge | scalar lanes, per edge | advancement / lanes | agree |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for robot in ["locobot", "sawyer"] {
        edges_table(robot);
    }
}

criterion_group!(benches, bench, tables);
criterion_main!(benches);
