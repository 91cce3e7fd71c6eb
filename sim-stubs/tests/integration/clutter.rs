//! The `clutter` scene (Sawyer before a caged table): the robot fits at its start and home
//! poses, the table top is reachable from above at several places, and straight joint-space
//! moves between those places run into the cage. Collisions are the world's robot contacts
//! ([`World::robot_contacts`]) with the arm placed by a fresh world.

use std::sync::Arc;

use ferrobot_description::RobotConfig;
use ferrobot_firmware::config;
use ferrobot_kinematics::ik::{IkOptions, IkSolver, NumericalIk};
use ferrobot_kinematics::Chain;
use ferrobot_sim::body::RobotBody;
use ferrobot_sim::scene::{Scene, SceneError};
use ferrobot_sim::world::World;
use ferrobot_sim::{robots, LockstepSim};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// The Sawyer's pedestal height in the scene, m.
const PEDESTAL: f64 = 0.9;

struct Sawyer {
    scene: Scene,
    body: Arc<RobotBody>,
    cfg: RobotConfig,
    chain: Chain,
}

impl Sawyer {
    fn new() -> Self {
        let cfg = RobotConfig::bundled("sawyer").unwrap();
        Sawyer {
            scene: Scene::bundled("clutter").unwrap(),
            body: robots::by_name("sawyer").unwrap().body.unwrap(),
            chain: ferrobot_profile::arm_chain(&cfg).unwrap(),
            cfg,
        }
    }

    /// The servo angles (chain order, rad) for the arm's joint values `q` (rad).
    fn theta(&self, q: &[f64]) -> Vec<f64> {
        self.cfg
            .joints
            .iter()
            .map(|j| {
                let i = self
                    .chain
                    .joints
                    .iter()
                    .position(|c| c.name == j.name.as_str());
                f64::from(j.sign) * i.map_or(0.0, |i| q[i]) + f64::from(j.offset)
            })
            .collect()
    }

    /// What the arm at `q` touches, beyond its base on the pedestal: (link, body) pairs; a
    /// start overlap counts as a contact.
    fn contacts(&self, q: &[f64]) -> Vec<(String, String)> {
        match World::new(&self.scene, Some(&self.body), [0.0; 3], &self.theta(q)) {
            Ok(w) => w
                .robot_contacts()
                .into_iter()
                .filter(|c| !(c.link == "right_arm_base_link" && c.body == "pedestal"))
                .map(|c| (c.link, c.body))
                .collect(),
            Err(SceneError::Overlap { object, link }) => vec![(link, object)],
            Err(e) => panic!("{e}"),
        }
    }

    /// Joint values putting the hand (the flange, `right_hand`) `h` m above the table top at
    /// (x, y) (world, m), pointing down, touching nothing; `None` if no seed finds one.
    fn reach_down(&self, x: f64, y: f64, h: f64) -> Option<Vec<f64>> {
        let top = self.scene.body("table").unwrap().world_bounds().1.z;
        let target = Isometry3::from_parts(
            Translation3::new(x, y, top + h - PEDESTAL),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
        );
        let home = &self.cfg.arm.as_ref().unwrap().home;
        (0..4).find_map(|seed| {
            let opts = IkOptions {
                position_tolerance: 1e-4,
                orientation_tolerance: 1e-3,
                seed,
                ..IkOptions::default()
            };
            let q = NumericalIk
                .solve(&self.chain, &target, Some(home), &opts)
                .ok()?;
            self.contacts(&q).is_empty().then_some(q)
        })
    }

    /// The bodies a straight joint-space move from `a` to `b` touches (checked at 40 points).
    fn line(&self, a: &[f64], b: &[f64]) -> Vec<String> {
        let mut hit = std::collections::BTreeSet::new();
        for k in 1..40 {
            let t = f64::from(k) / 40.0;
            let q: Vec<f64> = a.iter().zip(b).map(|(x, y)| x + (y - x) * t).collect();
            hit.extend(self.contacts(&q).into_iter().map(|(_, b)| b));
        }
        hit.into_iter().collect()
    }
}

#[test]
fn the_sawyer_fits_the_clutter_scene_at_its_start_and_home_poses() {
    let s = Sawyer::new();
    // The simulator starts there (the loader refuses an overlap), and nothing moves.
    let mut sim = LockstepSim::with_scene(
        robots::by_name("sawyer").unwrap(),
        config::by_name("sawyer").unwrap(),
        1,
        Arc::new(s.scene.clone()),
    )
    .expect("the sawyer fits");
    let c = sim.hw.robot_contacts();
    println!("start: {c:?}");
    assert!(
        c.iter()
            .all(|c| c.link == "right_arm_base_link" && c.body == "pedestal"),
        "{c:?}"
    );
    let before = sim.truth().bodies;
    sim.run_for(1_000_000);
    for ((b, p0), p1) in s.scene.bodies.iter().zip(&before).zip(&sim.truth().bodies) {
        let d = (p1.translation.vector - p0.translation.vector).norm();
        assert!(d < 0.0005, "{} moved {d} m", b.id);
    }
    let zero = vec![0.0; s.chain.dof()];
    assert_eq!(s.contacts(&zero), Vec::new());
    let home = s.cfg.arm.as_ref().unwrap().home.clone();
    assert_eq!(s.contacts(&home), Vec::new());
    // Everything on the table is within Sawyer's reach: 1.02 m of its axis.
    for b in &s.scene.bodies {
        let (lo, hi) = b.world_bounds();
        if b.id == "table" || b.id == "pedestal" || b.id == "floor" {
            continue;
        }
        let far = [lo.x, hi.x]
            .iter()
            .flat_map(|x| [lo.y, hi.y].map(|y| x.hypot(y)))
            .fold(0.0, f64::max);
        assert!(far < 1.02, "{} reaches {far} m from the axis", b.id);
    }
}

#[test]
fn the_clutter_table_is_reachable_from_above_but_not_straight_across() {
    let s = Sawyer::new();
    // The hand 12 cm above the table top, pointing down: along the near edge, in the near
    // corners, in the pocket between the rail and the gate, at both sides.
    let spots = [
        ("near edge", 0.38, 0.0),
        ("near left", 0.40, 0.45),
        ("near right", 0.40, -0.45),
        ("pocket", 0.57, 0.05),
        ("left side", 0.70, 0.55),
        ("right side", 0.70, -0.55),
    ];
    let qs: Vec<Vec<f64>> = spots
        .iter()
        .map(|(name, x, y)| {
            s.reach_down(*x, *y, 0.12)
                .unwrap_or_else(|| panic!("{name}: no collision-free reach from above"))
        })
        .collect();
    // Straight joint-space moves between them: how many run into something, and what.
    let mut blocked = 0;
    let mut pairs = 0;
    for i in 0..qs.len() {
        for j in i + 1..qs.len() {
            let hit = s.line(&qs[i], &qs[j]);
            println!("{} -> {}: {hit:?}", spots[i].0, spots[j].0);
            pairs += 1;
            if !hit.is_empty() {
                blocked += 1;
            }
        }
    }
    println!("{blocked} of {pairs} straight moves touch something");
    // Across the table from side to side the straight move meets the cage.
    let across = s.line(&qs[4], &qs[5]);
    assert!(!across.is_empty(), "side to side: {across:?}");
    assert!(blocked * 3 >= pairs, "{blocked} of {pairs}");
}
