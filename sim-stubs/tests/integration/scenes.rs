//! Scene files: the bundled scenes say what the issue asks of them, and hostile files are
//! typed errors that name the file, the key and the problem.

use std::collections::BTreeSet;
use std::path::Path;

use ferrobot_sim::scene::{Scene, SceneError, SceneSource, Shape, BUNDLED};

fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::parse(text, Path::new("test.toml"), &|p, _| {
        Err(format!("no file {p:?} in this test"))
    })
}

fn invalid_key(text: &str) -> String {
    match parse(text) {
        Err(SceneError::Invalid { key, problem, file }) => {
            assert_eq!(file, Path::new("test.toml"));
            assert!(!problem.is_empty());
            key
        }
        other => panic!("expected an invalid-scene error, got {other:?}"),
    }
}

#[test]
fn every_bundled_scene_loads() {
    for name in BUNDLED {
        let s = Scene::bundled(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(s.name, name);
        assert!(
            s.bodies.iter().any(|b| b.id == "floor"),
            "{name} has a floor"
        );
    }
}

#[test]
fn the_tabletop_has_eight_graspable_objects_of_two_to_eight_centimetres() {
    let s = Scene::bundled("tabletop").unwrap();
    let table = s.body("table").unwrap();
    let (lo, hi) = table.world_bounds();
    let graspable: Vec<_> = s.bodies.iter().filter(|b| !b.fixed).collect();
    assert!(graspable.len() >= 8, "{} objects", graspable.len());
    let mut kinds = std::collections::BTreeSet::new();
    let mut colours = Vec::new();
    for b in &graspable {
        let (blo, bhi) = b.world_bounds();
        let ext = bhi - blo;
        let largest = ext.amax();
        assert!(
            (0.02 - 1e-9..=0.08 + 1e-9).contains(&largest),
            "{}: largest extent {largest} m",
            b.id
        );
        // On the table: inside its top's outline, resting on its top (within 1 mm).
        let c = b.pose.translation.vector;
        assert!(
            c.x > lo.x && c.x < hi.x && c.y > lo.y && c.y < hi.y,
            "{} on the table",
            b.id
        );
        assert!(
            (blo.z - hi.z).abs() < 1e-3,
            "{} rests on the table: {}",
            b.id,
            blo.z
        );
        kinds.insert(b.shape.kind());
        colours.push(b.colour);
    }
    assert_eq!(kinds.len(), 5, "every shape kind: {kinds:?}");
    for (i, a) in colours.iter().enumerate() {
        for b in &colours[i + 1..] {
            let d: f32 = a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum();
            assert!(d > 0.05, "distinct colours {a:?} {b:?}");
        }
    }
}

#[test]
fn the_apartment_has_three_rooms_and_forty_square_metres() {
    let s = Scene::bundled("apartment").unwrap();
    let walls: Vec<_> = s
        .bodies
        .iter()
        .filter(|b| b.id.starts_with("wall"))
        .collect();
    let mut lo = nalgebra::Point3::new(f64::MAX, f64::MAX, 0.0);
    let mut hi = -lo;
    for w in &walls {
        let (a, b) = w.world_bounds();
        lo = lo.inf(&a);
        hi = hi.sup(&b);
    }
    let inner = (hi.x - lo.x - 0.2) * (hi.y - lo.y - 0.2);
    assert!(inner >= 40.0, "{inner} m^2");
    // Doors: lintels above openings, at 2 m, at least 0.9 m wide.
    let lintels: Vec<_> = walls
        .iter()
        .filter(|w| w.world_bounds().0.z > 1.9)
        .collect();
    assert!(lintels.len() >= 3, "{} doors", lintels.len());
    for l in lintels {
        if let Shape::Box(sz) = l.shape {
            assert!(sz[0] >= 0.9 - 1e-9, "door {} m wide", sz[0]);
        }
    }
    // Textured floor and walls (features for SLAM).
    assert!(s.body("floor").unwrap().texture.is_some());
    assert!(walls.iter().all(|w| w.texture.is_some()));
}

#[test]
fn the_clutter_scene_has_posts_bars_at_several_heights_and_objects_on_its_table() {
    let s = Scene::bundled("clutter").unwrap();
    assert_eq!(s.robot_height, 0.9);
    let (lo, hi) = s.body("table").unwrap().world_bounds();
    let on_table = |b: &&ferrobot_sim::scene::Body| {
        let c = b.pose.translation.vector;
        c.x > lo.x && c.x < hi.x && c.y > lo.y && c.y < hi.y && b.world_bounds().0.z >= hi.z - 1e-9
    };
    // Thin vertical posts standing on the table top.
    let posts: Vec<_> = s
        .bodies
        .iter()
        .filter(|b| b.fixed && matches!(b.shape, Shape::Cylinder { radius, .. } if radius <= 0.02))
        .collect();
    assert!(posts.len() >= 6, "{} posts", posts.len());
    for p in &posts {
        assert!(on_table(p), "{} stands on the table", p.id);
        assert!(
            (p.world_bounds().0.z - hi.z).abs() < 1e-9,
            "{} on the top",
            p.id
        );
    }
    // Horizontal bars (long thin boxes) over the table at three or more heights.
    let mut heights = BTreeSet::new();
    for b in s.bodies.iter().filter(|b| b.fixed && b.id != "table") {
        if let Shape::Box(sz) = b.shape {
            let mut e = sz;
            e.sort_by(f64::total_cmp);
            if e[1] <= 0.05 && e[2] >= 0.2 && on_table(&b) {
                heights.insert((b.pose.translation.z * 100.0).round() as i64);
            }
        }
    }
    assert!(heights.len() >= 3, "bars at {heights:?} cm");
    // Movable boxes and spheres resting on the top (within 1 mm).
    let objects: Vec<_> = s.bodies.iter().filter(|b| !b.fixed).collect();
    assert!(objects.len() >= 3, "{} objects", objects.len());
    for b in objects {
        assert!(on_table(&b), "{} on the table", b.id);
        assert!((b.world_bounds().0.z - hi.z).abs() < 1e-3, "{} rests", b.id);
    }
}

#[test]
fn hostile_scene_files_name_the_key_and_the_problem() {
    let ok = "name = \"t\"\n";
    assert!(parse(ok).is_ok());
    assert_eq!(invalid_key("name = \"t\"\nbogus = 1\n"), "bogus");
    assert_eq!(
        invalid_key("name = \"t\"\n[robot]\npose = [0, 0]\n"),
        "robot.pose"
    );
    assert_eq!(
        invalid_key("name = \"t\"\n[robot]\npose = [nan, 0, 0]\n"),
        "robot.pose"
    );
    let obj =
        |body: &str| format!("name = \"t\"\n[[object]]\nid = \"a\"\ncolour = [1, 0, 0]\n{body}");
    assert_eq!(
        invalid_key(&obj(
            "shape = \"box\"\nsize = [0.1, 0.1]\nposition = [0, 0, 0]\nmass = 1\n"
        )),
        "object[0].size"
    );
    assert_eq!(
        invalid_key(&obj(
            "shape = \"box\"\nsize = [0.1, -0.1, 0.1]\nposition = [0, 0, 0]\nmass = 1\n"
        )),
        "object[0].size"
    );
    assert_eq!(
        invalid_key(&obj(
            "shape = \"cone\"\nsize = [0.1]\nposition = [0, 0, 0]\nmass = 1\n"
        )),
        "object[0].shape"
    );
    assert_eq!(
        invalid_key(&obj(
            "shape = \"sphere\"\nsize = [0.1]\nposition = [0, 0, 1e300]\nmass = 1\n"
        )),
        "object[0].position"
    );
    assert_eq!(
        invalid_key(&obj(
            "shape = \"sphere\"\nsize = [0.1]\nposition = [0, 0, 0]\n"
        )),
        "object[0].mass"
    );
    assert_eq!(
        invalid_key(&obj(
            "shape = \"sphere\"\nsize = [0.1]\nposition = [0, 0, 0]\nmass = inf\n"
        )),
        "object[0].mass"
    );
    assert_eq!(
        invalid_key(&obj(
            "shape = \"sphere\"\nsize = [0.1]\nposition = [0, 0, 0]\nmass = 1\nquaternion = [0, 0, 0, 2]\n"
        )),
        "object[0].quaternion"
    );
    assert_eq!(
        invalid_key(&obj(
            "shape = \"mesh\"\nmesh = \"x.obj\"\nposition = [0, 0, 0]\nmass = 1\n"
        )),
        "object[0].mesh"
    );
    assert_eq!(
        invalid_key(
            "name = \"t\"\n[[wall]]\nfrom = [0, 0]\nto = [2, 0]\ndoors = [{ at = 1.5, width = 0.9, height = 2 }]\n"
        ),
        "wall[0].doors[0].width"
    );
    assert_eq!(
        invalid_key(
            "name = \"t\"\n[floor]\nsize = [1, 1]\ntexture = { pattern = \"zebra\", scale = 1 }\n"
        ),
        "floor.texture.pattern"
    );
    // Twice the same id.
    let twice = format!(
        "{}[[object]]\nid = \"a\"\ncolour = [1, 0, 0]\nshape = \"sphere\"\nsize = [0.1]\nposition = [0, 0, 0]\nmass = 1\n",
        obj("shape = \"sphere\"\nsize = [0.1]\nposition = [0, 0, 0]\nmass = 1\n")
    );
    assert_eq!(invalid_key(&twice), "object.id");
}

#[test]
fn unknown_scenes_and_unreadable_files_are_typed_errors() {
    match Scene::load(&SceneSource::from_arg("kitchen_of_dreams")) {
        Err(SceneError::Unknown { name, known }) => {
            assert_eq!(name, "kitchen_of_dreams");
            assert!(known.contains("tabletop"));
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        Scene::load(&SceneSource::from_arg("/nonexistent/x.toml")),
        Err(SceneError::Unknown { .. })
    ));
    assert!(matches!(
        Scene::load(&SceneSource::File("/dev/zero".into())),
        Err(SceneError::Invalid { .. })
    ));
    assert!(matches!(
        Scene::load(&SceneSource::File("/tmp".into())),
        Err(SceneError::Invalid { .. })
    ));
}

#[test]
fn a_scene_file_reads_its_meshes_beside_it() {
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    std::fs::write(
        dir.join("tri.obj"),
        "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("s.toml"),
        "name = \"s\"\n[[object]]\nid = \"t\"\nshape = \"mesh\"\nmesh = \"tri.obj\"\nscale = 2.0\nposition = [0, 0, 0.5]\nmass = 0.1\ncolour = [0, 1, 0]\n",
    )
    .unwrap();
    let s = Scene::load(&SceneSource::File(dir.join("s.toml"))).unwrap();
    let t = s.body("t").unwrap();
    assert_eq!(t.shape.kind(), "mesh");
    let v = t.shape.volume();
    assert!((v - 0.2f64.powi(3) / 6.0).abs() < 1e-9, "{v}");
}

/// A number as TOML writes it (`nan`, `inf`, `-inf` included).
fn toml_num(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 {
            "inf".into()
        } else {
            "-inf".into()
        }
    } else {
        format!("{v:?}")
    }
}

/// Seeded random edits of a valid scene file: one or two of its 26 numbers replaced by a
/// hostile value (NaN, ±inf, ±1e300, ±f64::MAX, 5e6, or an ordinary value). Parsing never
/// panics; an absurd number (not finite, or beyond 1e5 in magnitude) anywhere is refused
/// naming a key; an accepted scene holds only finite, bounded numbers (poses within 1e4 m,
/// sizes positive and bounded, unit quaternions, colours in 0-1).
#[test]
fn hostile_numbers_anywhere_are_refused_or_sane() {
    use proptest::prelude::*;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    // A valid scene's numbers, in the order of the template below.
    let base: [f64; 26] = [
        0.3, 0.2, 0.1, // object size
        0.5, 0.0, 0.1, 0.0, // robot pose, height
        6.0, 6.0, 0.5, 0.5, 0.5, 0.8, // floor size, colour, friction
        -2.0, 2.0, 2.0, 2.0, 2.4, 0.1, // wall from, to, height, thickness
        2.0, 0.9, 2.0, // door at, width, height
        1.0, 1.0, 0.15, // object position
        0.0,  // (unused slot: rpy below reuses the first numbers)
    ];
    let hostile = prop::sample::select(vec![
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e300,
        -1e300,
        f64::MAX,
        -f64::MAX,
        5e6,
        -5e6,
        0.0,
        -0.3,
        1e-310,
        0.7,
    ]);
    let cfg = Config {
        cases: 400,
        failure_persistence: None,
        ..Config::default()
    };
    let mut runner =
        TestRunner::new_with_rng(cfg, TestRng::from_seed(RngAlgorithm::ChaCha, &[11; 32]));
    let strategy = (
        prop::collection::vec((0usize..26, hostile), 0..3),
        prop::sample::select(vec!["box", "cylinder", "sphere", "capsule"]),
    );
    let accepted = std::cell::Cell::new(0usize);
    let keys = std::cell::RefCell::new(std::collections::BTreeSet::new());
    runner
        .run(&strategy, |(edits, shape)| {
            let mut v = base;
            for &(slot, x) in &edits {
                v[slot] = x;
            }
            // Size slots a shape does not have are not in the file.
            let used = |slot: usize| match shape {
                "box" => true,
                "sphere" => slot > 0 && slot != 1 && slot != 2 || slot == 0,
                _ => slot != 2,
            };
            let absurd = edits
                .iter()
                .any(|&(slot, x)| used(slot) && (!x.is_finite() || x.abs() > 1e5));
            let n: Vec<String> = v.iter().map(|&x| toml_num(x)).collect();
            let size = match shape {
                "box" => format!("[{}, {}, {}]", n[0], n[1], n[2]),
                "sphere" => format!("[{}]", n[0]),
                _ => format!("[{}, {}]", n[0], n[1]),
            };
            let text = format!(
                "name = \"h\"\n[robot]\npose = [{}, {}, {}]\nheight = {}\n\
                 [floor]\nsize = [{}, {}]\ncolour = [{}, {}, {}]\nfriction = {}\n\
                 [[wall]]\nfrom = [{}, {}]\nto = [{}, {}]\nheight = {}\nthickness = {}\n\
                 colour = [0.5, 0.5, 0.5]\ndoors = [{{ at = {}, width = {}, height = {} }}]\n\
                 [[object]]\nid = \"o\"\nshape = \"{shape}\"\nsize = {size}\n\
                 position = [{}, {}, {}]\nrpy = [{}, 0.0, 0.2]\nmass = 0.5\nfriction = 0.5\n\
                 colour = [0.2, 0.3, 0.4]\n",
                n[3],
                n[4],
                n[5],
                n[6],
                n[7],
                n[8],
                n[9],
                n[10],
                n[11],
                n[12],
                n[13],
                n[14],
                n[15],
                n[16],
                n[17],
                n[18],
                n[19],
                n[20],
                n[21],
                n[22],
                n[23],
                n[24],
                n[25]
            );
            match parse(&text) {
                Ok(scene) => {
                    accepted.set(accepted.get() + 1);
                    prop_assert!(!absurd, "accepted an absurd number: {edits:?}");
                    prop_assert!(scene
                        .robot_pose
                        .iter()
                        .all(|x| x.is_finite() && x.abs() <= 1e4));
                    prop_assert!(scene.robot_height.is_finite() && scene.robot_height >= 0.0);
                    for b in &scene.bodies {
                        let t = b.pose.translation.vector;
                        prop_assert!(
                            t.iter().all(|x| x.is_finite() && x.abs() <= 1e4),
                            "{}: {t:?}",
                            b.id
                        );
                        prop_assert!((b.pose.rotation.coords.norm() - 1.0).abs() < 1e-9);
                        let h = b.shape.half_extents();
                        prop_assert!(
                            h.iter().all(|x| x.is_finite() && *x > 0.0 && *x <= 1e4),
                            "{}: {h:?}",
                            b.id
                        );
                        prop_assert!(b.mass.is_finite() && b.mass >= 0.0 && b.mass <= 1e6);
                        prop_assert!(b.friction.is_finite() && b.friction >= 0.0);
                        prop_assert!(b.colour.iter().all(|c| (0.0..=1.0).contains(c)));
                    }
                }
                Err(SceneError::Invalid { key, problem, .. }) => {
                    prop_assert!(
                        !edits.is_empty(),
                        "the valid scene was refused: {key}: {problem}"
                    );
                    prop_assert!(!key.is_empty() && !problem.is_empty());
                    keys.borrow_mut().insert(key);
                }
                Err(e) => prop_assert!(false, "unexpected error {e}"),
            }
            Ok(())
        })
        .expect("hostile scene numbers are refused or sane");
    // Both sides were exercised: files accepted, refusals at many different keys.
    println!(
        "accepted {} of 400; refused at {:?}",
        accepted.get(),
        keys.borrow()
    );
    assert!(accepted.get() >= 40, "{}", accepted.get());
    assert!(keys.borrow().len() >= 12, "{:?}", keys.borrow());
}

/// The apartment's floor plan (PyRobot's 2 cm cells and 0.1–0.8 m band): walls, furniture and
/// movable objects where the scene puts them, the doors and the robot's start free; the sofa's
/// back (0.45–0.85 m) counts, the floor does not; bad resolutions and bands are refused.
#[test]
fn the_apartment_floor_plan_holds_its_walls_furniture_and_doors() {
    use ferrobot_sim::floor_plan::OBSTACLE_BAND;
    let scene = Scene::bundled("apartment").expect("apartment");
    let plan = scene.floor_plan(0.02, OBSTACLE_BAND, false).expect("plan");
    assert_eq!((plan.width, plan.height), (420, 320));
    let at = |plan: &ferrobot_sim::floor_plan::FloorPlan, x: f64, y: f64| {
        let i = ((x - plan.origin[0]) / plan.resolution).floor() as usize;
        let j = ((y - plan.origin[1]) / plan.resolution).floor() as usize;
        plan.occupied[j * plan.width + i]
    };
    for (x, y, what) in [
        (0.0, -2.5, "inner wall"),
        (-2.2, 2.5, "sofa"),
        (-2.2, 2.9, "sofa back"),
        (2.9, 2.15, "bed"),
        (-0.4, 2.6, "plant pot"),
        (1.4, 0.6, "laundry basket"),
        (-3.99, 0.0, "outer wall"),
    ] {
        assert!(at(&plan, x, y), "{what} at ({x}, {y}) not occupied");
    }
    for (x, y, what) in [
        (-3.0, -2.0, "robot start"),
        (0.0, -2.0, "lower door"),
        (0.0, 1.2, "upper door"),
        (2.5, 0.0, "bedroom door"),
        (-1.0, 0.5, "living room floor"),
    ] {
        assert!(!at(&plan, x, y), "{what} at ({x}, {y}) occupied");
    }
    // The wall is 10 cm thick, x in [−0.05, 0.05]: cell centres at ±0.05, ±0.03, ±0.01 lie in
    // it (its faces included), six cells across.
    let across = (0..20)
        .filter(|k| at(&plan, -0.2 + 0.02 * *k as f64 + 0.01, -2.6))
        .count();
    assert_eq!(across, 6);
    let fixed = scene.floor_plan(0.02, OBSTACLE_BAND, true).expect("plan");
    assert!(
        !at(&fixed, 1.4, 0.6),
        "the basket moves: not in the fixed plan"
    );
    // The ball (radius 0.1 m at 0.1 m) reaches 0.2 m: inside the band; above 0.25 m it is not.
    assert!(at(&plan, -1.0, -1.0));
    let high = scene.floor_plan(0.02, [0.25, 0.8], false).expect("plan");
    assert!(!at(&high, -1.0, -1.0));
    for (r, band) in [
        (0.0, OBSTACLE_BAND),
        (f64::NAN, OBSTACLE_BAND),
        (0.02, [0.8, 0.1]),
        (0.02, [f64::NAN, 1.0]),
    ] {
        let e = scene.floor_plan(r, band, false).expect_err("bad");
        assert!(e.to_string().contains("floor plan"), "{e}");
    }
}
