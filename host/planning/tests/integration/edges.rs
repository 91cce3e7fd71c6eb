//! Proven edges against exact distances that must never be too large.

use std::sync::Arc;

use ferrobot_description::RobotConfig;
use ferrobot_planning::{CheckOptions, Checker, CollisionModel, PlanningScene};

/// A LoCoBot edge whose elbow box grazes the camera mast's box (both nearly parallel) for 0.7 %
/// of its length, 0.09 mm deep. parry's cuboid–cuboid distance said 2.7 cm a little before the
/// contact (it is 0.2 mm), so conservative advancement stepped over it and "proved" the edge;
/// FCL (`plan_peer.py check`) found the contact in an exported path.
#[test]
fn an_edge_grazing_a_fixed_link_is_not_proven() {
    let c = crate::locobot_alone();
    let a = [0.48181393, -0.57703693, 0.2663449, 0.38923935, 0.26541771];
    let b = [0.32535412, -0.33525868, 0.0118354, 0.10592515, 0.39710595];
    let at = |t: f64| -> Vec<f64> { a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect() };
    assert!(c.is_free(&a) && c.is_free(&b));
    let touching = c.contact(&at(0.2233)).expect("the elbow touches the mast");
    assert_eq!(
        (touching.a.as_str(), touching.b.as_str()),
        ("elbow_link", "cam_mount")
    );
    assert!(!c.motion_proven(&a, &b));
    // 0.2 mm from the mast: not 2 cm clear.
    assert!(c.near_world(&at(0.205), 0.001));
}

/// A LoCoBot edge on which the elbow touches the camera mast 1.5 µm deep, for 0.05 mm of its
/// 0.72 m of motion: shorter than `min_step`, so stepping `min_step` with contact checks alone
/// (as the checker did below `min_step` of clearance) stepped over it; FCL found it in an
/// exported path. Steps near contact now need the clearances at both ends to cover them.
#[test]
fn a_contact_shorter_than_min_step_is_not_stepped_over() {
    let c = crate::locobot_alone();
    let a = [
        -0.9596562766769012,
        -0.9364069903152136,
        1.2529021401964529,
        -1.1660013381586636,
        -1.256280984874232,
    ];
    let b = [
        -0.4462602862963767,
        -0.5214767713804918,
        0.9718089959412842,
        -1.0422980335527063,
        -0.893607127945518,
    ];
    assert!(c.is_free(&a) && c.is_free(&b));
    assert!(!c.motion_proven(&a, &b));
    // The same edge shortened so that it ends before the contact is proven.
    let short: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + (y - x) * 0.99).collect();
    assert!(c.motion_proven(&a, &short));
}

/// Over random edges of a LoCoBot among boxes, a cylinder, a sphere and a capsule (so both
/// the separating-axis bound and GJK decide), every edge the planners' check accepts is free
/// at states 1 mm of link motion apart; and the check is not vacuous: it accepts most free
/// edges and some edges touch.
#[test]
fn accepted_edges_are_free_at_1_mm() {
    use ferrobot_planning::Shape;
    use nalgebra::Isometry3;
    let mut scene = PlanningScene::new();
    let objects = [
        ("table", Shape::Box([0.45, 0.8, 0.1]), [0.5, 0.0, 0.05]),
        (
            "post",
            Shape::Cylinder {
                radius: 0.02,
                length: 0.3,
            },
            [0.33, 0.1, 0.25],
        ),
        ("ball", Shape::Sphere(0.04), [0.3, -0.15, 0.2]),
        (
            "bar",
            Shape::Capsule {
                radius: 0.015,
                length: 0.2,
            },
            [0.25, 0.0, 0.35],
        ),
    ];
    for (id, shape, [x, y, z]) in objects {
        scene
            .add_object(id, shape, Isometry3::translation(x, y, z))
            .expect("object");
    }
    random_edges("locobot", &scene, 1.2, 0, 8);
}

/// The same for Sawyer alone, whose seven links fold onto each other: accepted edges never
/// pass through a contact of two moving links (their relative speed counts only the joints
/// that move one and not the other; `checker::tests` checks that bound directly). Its links
/// are cylinders, so no grazing edges are made here.
#[test]
fn accepted_edges_never_fold_the_arm_into_itself() {
    random_edges("sawyer", &PlanningScene::new(), 3.0, 10, 0);
}

/// 600 random edges between free states of `robot` in `scene`, each joint moving up to
/// `span` (rad); at least `min_self` of them must touch first between two moving links, and
/// at least `min_grazes` grazing edges between boxes must be made and refused.
fn random_edges(robot: &str, scene: &PlanningScene, span: f64, min_self: usize, min_grazes: usize) {
    use ferrobot_planning::Shape;
    use rand::{Rng, SeedableRng};
    let cfg = RobotConfig::bundled(robot).expect("robot");
    let model = Arc::new(CollisionModel::from_config(&cfg).expect("model"));
    let c = Checker::new(model, scene, CheckOptions::default()).expect("checker");
    let limits = c.model().limits().to_vec();
    let links = c.moving_links();
    // Bodies whose contacts with each other are decided exactly: box links, and objects that
    // are boxes, spheres or capsules (objects never touch each other here).
    let boxes: Vec<String> = c
        .model()
        .links()
        .iter()
        .filter(|l| {
            !l.shapes.is_empty() && l.shapes.iter().all(|(_, s)| matches!(s, Shape::Box(_)))
        })
        .map(|l| l.name.clone())
        .chain(
            scene
                .objects()
                // Against box links, spheres and capsules are decided exactly too.
                .filter(|o| {
                    matches!(
                        o.shape,
                        Shape::Box(_) | Shape::Sphere(_) | Shape::Capsule { .. }
                    )
                })
                .map(|o| o.id.clone()),
        )
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (mut accepted, mut touching, mut self_touching, mut tried) = (0, 0, 0, 0);
    let mut grazed = 0;
    while tried < 600 {
        let a: Vec<f64> = limits
            .iter()
            .map(|&(lo, hi)| rng.random_range(lo..=hi))
            .collect();
        if !c.is_free(&a) {
            continue;
        }
        let b: Vec<f64> = a
            .iter()
            .zip(&limits)
            .map(|(x, &(lo, hi))| (x + rng.random_range(-span..span)).clamp(lo, hi))
            .collect();
        if !c.is_free(&b) {
            continue;
        }
        tried += 1;
        let sampled = c.motion_sampled(&a, &b, 0.001);
        if c.motion_free(&a, &b) {
            accepted += 1;
            assert!(
                sampled,
                "{robot}: accepted edge {a:?} -> {b:?} touches at 1 mm"
            );
        }
        if !sampled {
            touching += 1;
            let first = (0..=400).find_map(|k| {
                let t = f64::from(k) / 400.0;
                let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect();
                c.contact(&q)
            });
            let own = first
                .as_ref()
                .is_some_and(|ct| links.contains(&ct.a) && links.contains(&ct.b));
            self_touching += usize::from(own);
            // Grazing edges, where a check that steps too far misses the contact: bend the
            // edge's end away until it is just free, and keep an end that touches. Only
            // where contacts are decided exactly (box links against boxes, spheres and
            // capsules): GJK may call shapes a fraction of a millimetre apart touching, on
            // the safe side, which would make a graze that is not one.
            let exact = first
                .as_ref()
                .is_some_and(|ct| boxes.contains(&ct.a) && boxes.contains(&ct.b));
            if exact && grazed < 8 {
                if let Some(end) = graze(&c, &a, &b, &limits, &mut rng) {
                    grazed += 1;
                    assert!(
                        !c.motion_free(&a, &end),
                        "{robot}: an edge that grazes a contact, {a:?} -> {end:?}, was accepted"
                    );
                }
            }
        }
    }
    assert!(
        grazed >= min_grazes,
        "{robot}: only {grazed} grazing edges made"
    );
    let free = tried - touching;
    assert!(
        touching > 30,
        "{robot}: only {touching} of {tried} edges touch"
    );
    assert!(
        self_touching >= min_self,
        "{robot}: only {self_touching} edges touch between moving links"
    );
    assert!(
        accepted as f64 >= 0.95 * free as f64,
        "{robot}: {accepted} of {free} free edges accepted"
    );
}

/// An end near `b` such that the edge from `a` barely touches something: by bisection on a
/// random bend of the end (states checked 0.1 mm apart) to where the edge comes free, then
/// 1e-3 of the bend (at most 0.5 mrad per joint) back into contact, so that the contact is
/// real (about a millimetre deep or less), not a sliver of `f32` rounding. `None` when no bend
/// of up to 0.5 rad per joint frees the edge.
fn graze(
    c: &Checker,
    a: &[f64],
    b: &[f64],
    limits: &[(f64, f64)],
    rng: &mut rand_chacha::ChaCha8Rng,
) -> Option<Vec<f64>> {
    use rand::Rng;
    let end = |bend: &[f64], s: f64| -> Vec<f64> {
        b.iter()
            .zip(bend)
            .zip(limits)
            .map(|((x, d), &(lo, hi))| (x + d * s).clamp(lo, hi))
            .collect()
    };
    let free = |q: &[f64]| c.is_free(q) && c.motion_sampled(a, q, 0.0001);
    for _ in 0..20 {
        let bend: Vec<f64> = b.iter().map(|_| rng.random_range(-0.5..0.5)).collect();
        if !free(&end(&bend, 1.0)) {
            continue;
        }
        let (mut lo, mut hi) = (0.0, 1.0);
        while hi - lo > 1e-6 {
            let mid = (lo + hi) / 2.0;
            if free(&end(&bend, mid)) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let touching = end(&bend, (lo - 5e-3).max(0.0));
        return (c.is_free(&touching) && !c.motion_sampled(a, &touching, 0.0001))
            .then_some(touching);
    }
    None
}
