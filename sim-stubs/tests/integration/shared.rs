//! Two robots in one world on one clock ([`ferrobot_sim::shared`]): one robot's bumper meets
//! the other, the other does not move, its camera sees the first, both firmwares' clocks are
//! the world's, a robot placed on another is refused, and a run is the same for its seeds.

use std::path::Path;
use std::sync::Arc;

use ferrobot_protocol::*;
use ferrobot_sim::camera::BandedCamera;
use ferrobot_sim::render::RenderedImage;
use ferrobot_sim::scene::{Scene, SceneError};
use ferrobot_sim::shared::SharedHosts;
use ferrobot_sim::HostSide;

/// An empty floor, 6 m square.
const FLOOR: &str = r#"
name = "floor"
[floor]
size = [6.0, 6.0]
"#;

fn floor() -> Arc<Scene> {
    Arc::new(
        Scene::parse(FLOOR, Path::new("floor.toml"), &|p, _| {
            Err(format!("no {p}"))
        })
        .unwrap(),
    )
}

fn locobot() -> ferrobot_description::RobotConfig {
    ferrobot_profile::bundled("locobot").unwrap()
}

/// Two LoCoBots 1.2 m apart facing each other on `floor`, handshaken, configured, telemetry at
/// 100 Hz; A at the origin facing +x, B at x = 1.2 m facing −x.
fn two_facing() -> SharedHosts {
    let cfg = locobot();
    let mut h = SharedHosts::new(floor());
    for (seed, pose) in [(1, [0.0, 0.0, 0.0]), (2, [1.2, 0.0, std::f64::consts::PI])] {
        let i = h
            .join(
                ferrobot_sim::robots::from_description(&cfg),
                ferrobot_profile::firmware_profile(&cfg),
                seed,
                pose,
            )
            .expect("room for it");
        let mut s = h.seat(i).unwrap();
        s.handshake().expect("hello");
        s.command(&HostMsg::SetTelemetry { period_ms: 10 })
            .expect("telemetry");
    }
    for i in 0..2 {
        h.seat(i)
            .unwrap()
            .wait_telemetry(2_000_000, |t| t.faults & fault_flags::CONFIGURING == 0)
            .expect("configured");
    }
    h
}

#[test]
fn a_robot_driving_into_another_is_stopped_by_its_bumper_and_the_other_stays() {
    let mut h = two_facing();
    let b0 = h.sim.station(1).unwrap().base_truth().unwrap();
    let mut a = h.seat(0).unwrap();
    a.command(&HostMsg::BaseVelocity {
        v: 0.2,
        w: 0.0,
        duration_ms: 10_000,
    })
    .expect("accepted");
    let t = a
        .wait_telemetry(8_000_000, |t| t.base_flags & base_flags::ANY_BUMPER != 0)
        .expect("A's bumper meets B");
    assert!(
        t.base_flags & base_flags::BUMPER_CENTER != 0,
        "{:#x}",
        t.base_flags
    );
    a.run_for(1_000_000);
    assert!(a.take_faults().iter().any(|f| f.kind == FaultKind::Bumper));
    let xa = h.sim.station(0).unwrap().base_truth().unwrap()[0];
    let b1 = h.sim.station(1).unwrap().base_truth().unwrap();
    let radius = h
        .sim
        .station(0)
        .unwrap()
        .hw
        .base
        .as_ref()
        .unwrap()
        .drive
        .p
        .body_radius;
    // B's nearest solid at bumper height (0.015-0.105 m) is not its base's ring but its
    // first plate (URDF `plate_1`, a 0.3 m square at 0.10 m, ahead of the base): A stops with
    // its bumper ring against the plate's edge, within 2 mm (the bumper's travel and a step).
    let b = h.sim.truth(1).unwrap();
    let body = h.sim.station(1).unwrap().body().unwrap().clone();
    let plate = body.tree.link_index("plate_1").unwrap();
    let half = match body.shapes[plate][0].shape {
        ferrobot_sim::scene::Shape::Box(e) => e[0] / 2.0,
        ref s => panic!("plate_1 is {s:?}"),
    };
    let reach = (b.links[plate].translation.vector - b.root.translation.vector)
        .xy()
        .norm()
        + half;
    let gap = b0[0] - xa;
    println!(
        "A stopped at x = {xa:.4} m: {gap:.4} m from B's centre (A's radius {radius} m + B's \
         plate reach {reach:.4} m)"
    );
    assert!((gap - radius - reach).abs() < 0.002, "gap {gap}");
    // B was not pushed, and its wheels were never commanded.
    assert_eq!(b0, b1);
    // Both firmwares live on the world's clock.
    let now = h.sim.now_us();
    for i in 0..2 {
        let t = h.seat(i).unwrap().end().telemetry.clone().unwrap();
        let lag = now - t.time_us;
        assert!(
            lag <= 10_000,
            "robot {i}'s telemetry {lag} µs behind the world"
        );
    }
}

#[test]
fn each_robots_camera_sees_the_other() {
    let cfg = locobot();
    let section = cfg.camera.clone().unwrap();
    let h = two_facing();
    let body = h.sim.station(1).unwrap().body().unwrap().clone();
    let mut cam = BandedCamera::new(h.sim.scene(), &body, &section, 1, false).unwrap();
    let mut img = RenderedImage::new(section.width, section.height);
    let truth = h.sim.truth(1).unwrap();
    assert_eq!(truth.others.len(), 1);
    cam.capture_into(&truth, &mut img);
    let seen: Vec<usize> = (0..img.labels.len())
        .filter(|&p| {
            cam.label_name(img.labels[p])
                .is_some_and(|n| n.starts_with("robots/0/"))
        })
        .collect();
    // A fills a good part of B's view 1.2 m away, and its nearest pixel is about as far as
    // its front (1.2 m less A's radius and B's camera's set-back) within 0.25 m.
    println!("B sees A in {} pixels", seen.len());
    assert!(seen.len() > 2000, "{} pixels of A", seen.len());
    let nearest = seen
        .iter()
        .map(|&p| img.depth[p])
        .filter(|d| *d > 0.0)
        .fold(f32::INFINITY, f32::min);
    println!("nearest pixel of A at {nearest} m");
    assert!((0.6..1.2).contains(&nearest), "nearest {nearest}");
    // Without A in the world (a truth without the others), none of it.
    let mut alone = truth.clone();
    alone.others.clear();
    cam.capture_into(&alone, &mut img);
    assert!(!img
        .labels
        .iter()
        .any(|l| cam.label_name(*l).is_some_and(|n| n.starts_with("robots/"))));
}

#[test]
fn a_robot_placed_on_another_is_refused_and_nothing_changes() {
    let cfg = locobot();
    let mut h = two_facing();
    let before = h.sim.truth(0).unwrap();
    let e = h
        .join(
            ferrobot_sim::robots::from_description(&cfg),
            ferrobot_profile::firmware_profile(&cfg),
            3,
            [0.1, 0.0, 0.0],
        )
        .unwrap_err();
    match &e {
        SceneError::Overlap { object, link } => {
            assert!(object.starts_with("robot 0's link"), "{object}");
            assert!(!link.is_empty());
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(h.sim.robots(), 2);
    assert!(h.seat(2).is_none());
    h.seat(0).unwrap().run_for(100_000);
    assert_eq!(h.sim.truth(0).unwrap().root, before.root);
}

#[test]
fn a_shared_world_runs_the_same_for_the_same_seeds() {
    let run = || {
        let mut h = two_facing();
        for (i, v) in [(0, 0.15), (1, 0.1)] {
            h.seat(i)
                .unwrap()
                .command(&HostMsg::BaseVelocity {
                    v,
                    w: 0.3,
                    duration_ms: 3_000,
                })
                .expect("accepted");
        }
        h.seat(1).unwrap().run_for(3_000_000);
        // The others' bodies are each run's own; their links are compared.
        let mut t = [h.sim.truth(0).unwrap(), h.sim.truth(1).unwrap()];
        let others: Vec<_> = t
            .iter_mut()
            .map(|t| t.others.pop().unwrap().links)
            .collect();
        (t, others)
    };
    let (a, b) = (run(), run());
    assert_eq!(a, b);
    assert!(a.0[0].root.translation.vector.norm() > 0.1, "A moved");
    assert_eq!(a.1[0], a.0[1].links, "A sees B where B is");
}
