//! Lockstep acceptance: the bases through the protocol, against ground truth.

use crate::common;
use common::*;
use ferrobot_protocol::*;
use ferrobot_sim::HostSide;

fn drive_straight(robot: &str) -> (f64, f64, Odometry) {
    let mut s = session(robot);
    s.command(&HostMsg::ResetOdometry).expect("reset");
    let start = s.sim.base_truth().expect("base");
    s.command(&HostMsg::BaseVelocity {
        v: 0.2,
        w: 0.0,
        duration_ms: 2000,
    })
    .expect("accepted");
    s.run_for(3_000_000);
    let end = s.sim.base_truth().expect("base");
    let truth = ((end[0] - start[0]).powi(2) + (end[1] - start[1]).powi(2)).sqrt();
    let odom = s.telemetry.clone().expect("telemetry").odometry;
    // Odometry against ground truth: the pose difference, as a fraction of the distance.
    let gap = ((odom.x as f64 - (end[0] - start[0])).powi(2)
        + (odom.y as f64 - (end[1] - start[1])).powi(2))
    .sqrt();
    (truth, gap, odom)
}

#[test]
fn kobuki_at_0_2_m_s_for_2_s_travels_0_4_m_and_odometry_agrees_with_ground_truth() {
    let (truth, gap, odom) = drive_straight("locobot");
    assert!((truth - 0.4).abs() <= 0.4 * 0.05, "travelled {truth} m");
    assert!(
        gap <= 0.02 * truth,
        "odometry {odom:?} is {gap} m from ground truth over {truth} m"
    );
}

#[test]
fn create2_at_0_2_m_s_for_2_s_travels_0_4_m_and_odometry_agrees_with_ground_truth() {
    let (truth, gap, odom) = drive_straight("locobot_lite");
    assert!((truth - 0.4).abs() <= 0.4 * 0.05, "travelled {truth} m");
    assert!(
        gap <= 0.02 * truth,
        "odometry {odom:?} is {gap} m from ground truth over {truth} m"
    );
}

#[test]
fn rotation_in_place_tracks_heading() {
    let mut s = session("locobot");
    s.command(&HostMsg::ResetOdometry).expect("reset");
    s.command(&HostMsg::BaseVelocity {
        v: 0.0,
        w: 0.5,
        duration_ms: 3000,
    })
    .expect("accepted");
    s.run_for(4_000_000);
    let truth = s.sim.base_truth().expect("base")[2];
    let odom = s.telemetry.clone().expect("telemetry").odometry.theta as f64;
    assert!((truth - 1.5).abs() < 0.1, "turned {truth} rad");
    assert!(
        (odom - truth).abs() < 0.02 * truth.abs(),
        "odometry {odom} vs truth {truth}"
    );
}

#[test]
fn encoder_wrap_around_does_not_disturb_odometry() {
    // 0.7 m/s for 12 s: the Kobuki's 16-bit counters wrap after 65536 ticks (5.6 m).
    let mut s = session("locobot");
    s.command(&HostMsg::ResetOdometry).expect("reset");
    for _ in 0..4 {
        s.command(&HostMsg::BaseVelocity {
            v: 0.7,
            w: 0.0,
            duration_ms: 3000,
        })
        .expect("accepted");
        s.run_for(3_000_000);
    }
    s.run_for(500_000);
    let truth = s.sim.base_truth().expect("base")[0];
    let odom = s.telemetry.clone().expect("telemetry").odometry.x as f64;
    assert!(truth > 7.0, "travelled {truth}");
    assert!(
        (odom - truth).abs() < 0.02 * truth,
        "odometry {odom} vs truth {truth}"
    );
}

#[test]
fn bumper_stops_the_base_and_is_reported() {
    let mut s = session("locobot");
    s.sim.hw.base.as_mut().expect("base").drive.obstacles.push(
        ferrobot_sim::diff_drive::Obstacle {
            x: 0.6,
            y: 0.0,
            r: 0.1,
        },
    );
    s.command(&HostMsg::BaseVelocity {
        v: 0.2,
        w: 0.0,
        duration_ms: 10_000,
    })
    .expect("accepted");
    let t = s
        .wait_telemetry(6_000_000, |t| t.base_flags & base_flags::ANY_BUMPER != 0)
        .expect("bumper seen");
    assert!(t.base_flags & base_flags::BUMPER_CENTER != 0);
    // Within one base cycle (20 ms) plus the line the command is zero at the base.
    s.run_for(60_000);
    assert_eq!(
        s.sim.hw.base.as_ref().expect("base").drive.target,
        (0.0, 0.0)
    );
    let faults = s.take_faults();
    assert!(
        faults.iter().any(|f| f.kind == FaultKind::Bumper),
        "{faults:?}"
    );
    // Forward is refused while the bumper is pressed; backing off is allowed.
    assert_eq!(
        s.command(&HostMsg::BaseVelocity {
            v: 0.1,
            w: 0.0,
            duration_ms: 500
        }),
        Err(ferrobot_sim::SimError::Rejected(RejectReason::BaseSafety))
    );
    s.command(&HostMsg::BaseVelocity {
        v: -0.1,
        w: 0.0,
        duration_ms: 500,
    })
    .expect("backing off");
}

#[test]
fn cliff_on_the_create2_stops_it_and_refuses_motion() {
    let mut s = session("locobot_lite");
    s.command(&HostMsg::BaseVelocity {
        v: 0.2,
        w: 0.0,
        duration_ms: 10_000,
    })
    .expect("accepted");
    s.run_for(500_000);
    s.sim.hw.base.as_mut().expect("base").injected.cliff = 2;
    s.wait_telemetry(200_000, |t| t.base_flags & base_flags::ANY_CLIFF != 0)
        .expect("cliff seen");
    s.run_for(300_000);
    let speed = s.sim.hw.base.as_ref().expect("base").drive.speed;
    assert!(speed.0.abs() < 1e-3 && speed.1.abs() < 1e-3, "{speed:?}");
    assert_eq!(
        s.command(&HostMsg::BaseVelocity {
            v: 0.0,
            w: 0.3,
            duration_ms: 500
        }),
        Err(ferrobot_sim::SimError::Rejected(RejectReason::BaseSafety))
    );
    assert!(s.take_faults().iter().any(|f| f.kind == FaultKind::Cliff));
}
