//! The vectorised collision engine (src/lanes/): spheres placed for many configurations at
//! once agree with the `f64` kinematics and, bit for bit, with the scalar path.

use ferrobot_description::RobotConfig;
use ferrobot_planning::lanes::{Frame, Lane, SphereProgram, Wide, WIDTH};
use ferrobot_planning::CollisionModel;
use nalgebra::Point3;
use rand::{Rng, SeedableRng};

/// For 512 random configurations of each bundled robot: every sphere's centre within 2 µm
/// of the `f64` forward kinematics (of the same configuration rounded to `f32`), and each
/// lane of the vector path equal to the scalar path's bits.
#[test]
fn spheres_in_lanes_agree_with_the_kinematics_and_the_scalar_path() {
    for robot in ["locobot", "locobot_lite", "sawyer"] {
        let cfg = RobotConfig::bundled(robot).expect(robot);
        let model = CollisionModel::from_config(&cfg).expect("model");
        let program = SphereProgram::new(&model).expect("program");
        assert!(program.spheres().len() > 10, "{robot}");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut frames, mut centres) = (Vec::<Frame<Wide>>::new(), Vec::new());
        let (mut one_frames, mut one) = (Vec::<Frame<f32>>::new(), Vec::new());
        let mut worst = 0.0f64;
        for _ in 0..512 / WIDTH {
            let qs: Vec<Vec<f32>> = (0..WIDTH)
                .map(|_| {
                    let q = model
                        .limits()
                        .iter()
                        .map(|&(lo, hi)| rng.random_range(lo..hi));
                    q.map(|x| x as f32).collect()
                })
                .collect();
            let lanes: Vec<Wide> = (0..program.dof())
                .map(|j| Wide::load(&qs.iter().map(|q| q[j]).collect::<Vec<_>>()))
                .collect();
            program.place(&lanes, &mut frames, &mut centres);
            for (k, q) in qs.iter().enumerate() {
                program.place(q, &mut one_frames, &mut one);
                let q64: Vec<f64> = q.iter().map(|&x| f64::from(x)).collect();
                let poses = model.link_poses(&q64);
                for (i, s) in program.spheres().iter().enumerate() {
                    for a in 0..3 {
                        assert_eq!(
                            centres[i][a].0[k].to_bits(),
                            one[i][a].to_bits(),
                            "{robot}: sphere {i}, axis {a}, lane {k}"
                        );
                    }
                    let c = s.centre.map(f64::from);
                    let truth = poses[program.link_of_step(s.step)] * Point3::new(c[0], c[1], c[2]);
                    let got = Point3::new(one[i][0], one[i][1], one[i][2]).cast::<f64>();
                    worst = worst.max((truth - got).norm());
                }
            }
        }
        assert!(worst < 2e-6, "{robot}: {worst} m");
        eprintln!(
            "{robot}: {} spheres on {} links, worst {worst:.2e} m",
            program.spheres().len(),
            program.steps()
        );
    }
}

/// The world's signed distances in lanes: each lane the scalar path's bits, and within 2 µm of
/// the closed forms in `f64` (a box, a cylinder, a sphere and a capsule, turned and moved);
/// a convex hull's never more than its true distance.
#[test]
fn world_distances_in_lanes_agree_with_closed_forms_and_the_scalar_path() {
    use ferrobot_planning::lanes::Environment;
    use ferrobot_planning::Shape;
    use nalgebra::{Isometry3, Vector3};
    let pose = Isometry3::new(Vector3::new(0.4, -0.2, 0.3), Vector3::new(0.3, -0.5, 0.8));
    let cube: Vec<Point3<f64>> = (0..8)
        .map(|i| {
            Point3::new(
                if i & 1 == 0 { -0.1 } else { 0.1 },
                if i & 2 == 0 { -0.15 } else { 0.15 },
                if i & 4 == 0 { -0.05 } else { 0.05 },
            )
        })
        .collect();
    // Each shape and its distance from a point in its own frame.
    type Exact = fn(&Point3<f64>) -> f64;
    let boxed: Exact = |p| {
        let q = Vector3::new(p.x.abs() - 0.1, p.y.abs() - 0.15, p.z.abs() - 0.05);
        q.map(|v| v.max(0.0)).norm() + q.max().min(0.0)
    };
    let shapes: [(Shape, Exact); 5] = [
        (Shape::Box([0.2, 0.3, 0.1]), boxed),
        (
            Shape::Cylinder {
                radius: 0.1,
                length: 0.4,
            },
            |p| {
                let (dr, dz) = ((p.x * p.x + p.y * p.y).sqrt() - 0.1, p.z.abs() - 0.2);
                (dr.max(0.0).powi(2) + dz.max(0.0).powi(2)).sqrt() + dr.max(dz).min(0.0)
            },
        ),
        (Shape::Sphere(0.12), |p| p.coords.norm() - 0.12),
        (
            Shape::Capsule {
                radius: 0.05,
                length: 0.3,
            },
            |p| {
                let z = p.z - p.z.clamp(-0.15, 0.15);
                (p.x * p.x + p.y * p.y + z * z).sqrt() - 0.05
            },
        ),
        (Shape::Hull(cube), boxed),
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for (shape, exact) in shapes {
        let mut env = Environment::default();
        env.push("it", &shape, &pose);
        let hull = matches!(shape, Shape::Hull(_));
        assert_eq!(env.exact(), !hull);
        for _ in 0..256 {
            let ps: Vec<[f32; 3]> = (0..WIDTH)
                .map(|_| [0; 3].map(|_| rng.random_range(-0.5f32..0.9)))
                .collect();
            let lanes: [Wide; 3] =
                std::array::from_fn(|a| Wide::load(&ps.iter().map(|p| p[a]).collect::<Vec<_>>()));
            let d = env.distance(&lanes).0;
            for (k, p) in ps.iter().enumerate() {
                let one = env.distance(p);
                assert_eq!(one.to_bits(), d[k].to_bits(), "{shape:?}");
                let local = pose.inverse() * Point3::new(p[0], p[1], p[2]).cast::<f64>();
                let truth = exact(&local);
                assert!(
                    (f64::from(one) - truth).abs() < 2e-6,
                    "{shape:?} at {p:?}: {one} vs {truth}"
                );
            }
        }
    }
}

/// The checker's sphere-level checks in lanes, on each bundled robot among a table, a box and
/// a pole, with 1 cm of padding: a configuration they find clear the checker finds free
/// (they are a proof, never a guess), each lane equals the scalar path, and on the LoCoBots
/// they are conclusive for most free configurations.
#[test]
fn lane_checks_are_sound_against_the_checker() {
    use ferrobot_planning::checker::LaneScratch;
    use ferrobot_planning::{CheckOptions, Checker, PlanningScene, Shape};
    use nalgebra::Isometry3;
    use std::sync::Arc;
    let mut scene = PlanningScene::new();
    let at = |x, y, z| Isometry3::translation(x, y, z);
    scene
        .add_object("table", Shape::Box([0.5, 0.8, 0.05]), at(0.45, 0.0, 0.1))
        .unwrap();
    scene
        .add_object("box", Shape::Box([0.1, 0.1, 0.15]), at(0.35, 0.15, 0.2))
        .unwrap();
    let pole = Shape::Cylinder {
        radius: 0.03,
        length: 0.8,
    };
    scene.add_object("pole", pole, at(0.3, -0.25, 0.4)).unwrap();
    let opts = CheckOptions {
        padding: 0.01,
        ..CheckOptions::default()
    };
    for robot in ["locobot", "locobot_lite", "sawyer"] {
        let cfg = RobotConfig::bundled(robot).expect(robot);
        let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
        let checker = Checker::new(model.clone(), &scene, opts).expect("checker");
        let lanes = checker.lane_checks().expect("lanes").expect("no voxels");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (mut wide, mut one) = (
            LaneScratch::<Wide>::default(),
            LaneScratch::<f32>::default(),
        );
        let (mut free, mut proven) = (0, 0);
        for _ in 0..2048 / WIDTH {
            let qs: Vec<Vec<f32>> = (0..WIDTH)
                .map(|_| {
                    let q = model
                        .limits()
                        .iter()
                        .map(|&(lo, hi)| rng.random_range(lo..hi));
                    q.map(|x| x as f32).collect()
                })
                .collect();
            let q: Vec<Wide> = (0..model.dof())
                .map(|j| Wide::load(&qs.iter().map(|q| q[j]).collect::<Vec<_>>()))
                .collect();
            let clear = lanes.clearance(&q, &mut wide).0;
            for (k, q) in qs.iter().enumerate() {
                let alone = lanes.clearance(q, &mut one);
                assert_eq!(alone.to_bits(), clear[k].to_bits(), "{robot}");
                let q64: Vec<f64> = q.iter().map(|&x| f64::from(x)).collect();
                let is_free = checker.is_free(&q64);
                assert!(
                    alone <= 0.0 || is_free,
                    "{robot}: {q:?} clear by {alone} m, not free"
                );
                free += usize::from(is_free);
                proven += usize::from(alone > 0.0);
            }
        }
        eprintln!("{robot}: {free} of 2048 free, {proven} proven by the spheres alone");
        assert!(free > 200, "{robot}: {free}");
        // The Sawyer's spheres of `right_l1` and `head` overlap in every configuration (by
        // about 5 cm: both covers are coarse where their meshes meet), so its spheres alone
        // prove nothing yet; the LoCoBots' prove most free configurations.
        if robot != "sawyer" {
            assert!(proven * 2 > free, "{robot}: {proven} of {free}");
        }
    }
}

/// Edges proven in lanes, on the LoCoBot and the Sawyer among the same objects: every edge
/// they call free has no contact at states 1 mm of robot-point motion apart (the checker's
/// sampled re-check, independent of the proof), the scalar path and the baseline's lanes
/// answer as the vector path (AVX2 where the CPU has it), and they agree with the checker's own advancement on at least 95 % of the edges.
#[test]
fn edges_proven_in_lanes_are_free_and_agree_with_the_checker() {
    use ferrobot_planning::{CheckOptions, Checker, PlanningScene, Shape};
    use nalgebra::Isometry3;
    use std::sync::Arc;
    let mut scene = PlanningScene::new();
    let at = |x, y, z| Isometry3::translation(x, y, z);
    scene
        .add_object("table", Shape::Box([0.5, 0.8, 0.05]), at(0.45, 0.0, 0.1))
        .unwrap();
    scene
        .add_object("box", Shape::Box([0.1, 0.1, 0.15]), at(0.35, 0.15, 0.2))
        .unwrap();
    for robot in ["locobot", "sawyer"] {
        let cfg = RobotConfig::bundled(robot).expect(robot);
        let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
        let checker =
            Checker::new(model.clone(), &scene, CheckOptions::default()).expect("checker");
        let lanes = checker.lane_checks().expect("lanes").expect("no voxels");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut free_state = || loop {
            let q: Vec<f64> = model
                .limits()
                .iter()
                .map(|&(lo, hi)| rng.random_range(lo..hi))
                .collect();
            if checker.is_free(&q) {
                return q;
            }
        };
        let (mut agree, mut proven, edges) = (0, 0, 200);
        for i in 0..edges {
            let a = free_state();
            // Short and long edges: towards another free state, a quarter or all of the way.
            let far = free_state();
            let f = if i % 2 == 0 { 0.25 } else { 1.0 };
            let b: Vec<f64> = a.iter().zip(&far).map(|(x, y)| x + (y - x) * f).collect();
            let in_lanes = checker.motion_free_in_lanes(&lanes, &a, &b);
            let scalar = checker.motion_free_in_lanes_scalar(&lanes, &a, &b);
            assert_eq!(in_lanes, scalar, "{robot}: {a:?} -> {b:?}");
            // AVX2 where the CPU has it, the baseline's SSE2 halves otherwise: the same.
            let baseline = checker.motion_free_in_baseline_lanes(&lanes, &a, &b);
            assert_eq!(in_lanes, baseline, "{robot}: {a:?} -> {b:?}");
            if in_lanes {
                proven += 1;
                assert!(
                    checker.motion_sampled(&a, &b, 0.001),
                    "{robot}: {a:?} -> {b:?}"
                );
            }
            agree += usize::from(in_lanes == checker.advanced(&a, &b));
        }
        eprintln!(
            "{robot}: {proven} of {edges} edges free in lanes, {agree} agree with the checker"
        );
        assert!(agree * 100 >= edges * 95, "{robot}: {agree} of {edges}");
        assert!(proven > 0, "{robot}");
    }
}

/// A Sawyer whose every collision shape is a sphere (each cylinder and box of the bundled
/// model replaced by a sphere at its centre, of the cylinder's radius or 5 cm): a spherized
/// model, as VAMP's robots are; its configuration, and the scratch directory holding its files
/// (removed when dropped).
fn spherized_sawyer() -> (RobotConfig, tempfile::TempDir) {
    let robots = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../description/robots");
    let urdf = std::fs::read_to_string(robots.join("sawyer.urdf")).expect("the Sawyer's URDF");
    let mut out = String::new();
    let mut rest = urdf.as_str();
    while let Some(at) = rest.find("<cylinder radius=\"") {
        out.push_str(&rest[..at]);
        let tail = &rest[at + "<cylinder radius=\"".len()..];
        let radius = &tail[..tail.find('"').expect("radius")];
        out.push_str(&format!("<sphere radius=\"{radius}\"/>"));
        rest = &tail[tail.find("/>").expect("cylinder's end") + 2..];
    }
    out.push_str(rest);
    let mut spheres = String::new();
    let mut rest = out.as_str();
    while let Some(at) = rest.find("<box ") {
        spheres.push_str(&rest[..at]);
        spheres.push_str("<sphere radius=\"0.05\"/>");
        let tail = &rest[at..];
        rest = &tail[tail.find("/>").expect("box's end") + 2..];
    }
    spheres.push_str(rest);
    let out = spheres;
    for other in ["<cylinder", "<mesh", "<box", "<capsule"] {
        assert!(!out.contains(other), "every shape a sphere: {other}");
    }
    let dir = tempfile::TempDir::new().expect("scratch");
    std::fs::write(dir.path().join("sawyer.urdf"), out).expect("URDF");
    let toml = dir.path().join("sawyer.toml");
    std::fs::copy(robots.join("sawyer.toml"), &toml).expect("description");
    let cfg = RobotConfig::from_file(&toml).expect("the spherized Sawyer");
    (cfg, dir)
}

/// The planner on each engine. Checkers prove edges by advancement on the bundled robots
/// (spheres that cover meshes and cylinders) and in lanes on a spherized one. RRT-Connect with
/// shortcutting on the vector path and on the scalar path returns the same path, bit for bit,
/// for each seed, on the LoCoBot (its spheres inconclusive near its own parts, so the walk's
/// exact stage runs) and on the spherized Sawyer; every path passes the advancement's check
/// edge by edge and the 1 mm sampled re-check.
#[test]
fn plans_are_the_same_on_the_vector_and_the_scalar_path() {
    use ferrobot_planning::checker::Engine;
    use ferrobot_planning::planner::{PlanOptions, Planner, RrtConnect};
    use ferrobot_planning::{CheckOptions, Checker, PlanningScene, Shape};
    use nalgebra::Isometry3;
    use std::sync::Arc;
    let mut scene = PlanningScene::new();
    let at = |x, y, z| Isometry3::translation(x, y, z);
    scene
        .add_object("table", Shape::Box([0.5, 0.8, 0.05]), at(0.45, 0.0, 0.1))
        .unwrap();
    scene
        .add_object("box", Shape::Box([0.1, 0.1, 0.25]), at(0.35, 0.0, 0.25))
        .unwrap();
    let (spherized, _files) = spherized_sawyer();
    let robots = [
        (
            RobotConfig::bundled("locobot").unwrap(),
            Engine::Advancement,
        ),
        (RobotConfig::bundled("sawyer").unwrap(), Engine::Advancement),
        (spherized, Engine::Lanes),
    ];
    for (cfg, engine) in robots {
        let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
        let robot = format!("{} ({engine:?})", cfg.name);
        let mut vector = Checker::new(model.clone(), &scene, CheckOptions::default()).unwrap();
        assert_eq!(vector.engine(), engine, "{robot}");
        if cfg.name == "sawyer" && engine == Engine::Advancement {
            continue;
        }
        vector.set_engine(Engine::Lanes).unwrap();
        let mut scalar = Checker::new(model.clone(), &scene, CheckOptions::default()).unwrap();
        scalar.set_engine(Engine::Scalar).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut free_state = || loop {
            let q: Vec<f64> = model
                .limits()
                .iter()
                .map(|&(lo, hi)| rng.random_range(lo..hi))
                .collect();
            if vector.is_free(&q) {
                return q;
            }
        };
        let mut planned = 0;
        for seed in 0..12 {
            let (start, goal) = (free_state(), free_state());
            let opts = PlanOptions {
                seed,
                smoothing: 2,
                ..PlanOptions::default()
            };
            let (v, s) = (
                RrtConnect.plan(&vector, &start, &goal, &opts),
                RrtConnect.plan(&scalar, &start, &goal, &opts),
            );
            let (Ok(v), Ok(s)) = (v, s) else {
                continue;
            };
            planned += 1;
            assert_eq!(v.path, s.path, "{robot}, seed {seed}");
            for w in v.path.windows(2) {
                assert!(vector.advanced(&w[0], &w[1]), "{robot}, seed {seed}: {w:?}");
                assert!(
                    vector.motion_sampled(&w[0], &w[1], 0.001),
                    "{robot}, seed {seed}"
                );
            }
        }
        assert!(planned >= 10, "{robot}: {planned} of 12 planned");
    }
}
