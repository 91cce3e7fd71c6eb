//! The emergency stop in every session state (ISO 13850: it overrides all other functions and
//! operations in all modes), on both LoCoBot profiles, through the lockstep simulator: before
//! any Hello, after a refused Hello, while already stopped, after a watchdog trip, and with a
//! full waypoint queue and a burst of frames ahead of it. In each state the stop is
//! acknowledged, engages, zeroes the base's wheel command within one base cycle (Kobuki 20 ms,
//! Create 2 15 ms) of reaching the firmware, holds every arm joint where it is, and refuses
//! motion until `Resume`.
use crate::common;
use ferrobot_sim::HostSide;

use common::*;
use ferrobot_protocol::*;
use ferrobot_sim::{LockstepSim, SimError, SimHost};

/// How far (rad) an arm joint may move after the stop: the braking from its motion, about
/// `v² / 2a` at the servos' acceleration, plus backlash.
const HOLD_TOL: f32 = 0.03;

fn base_cycle_us(s: &SimHost) -> u64 {
    s.sim.hw.base.as_ref().expect("a base").period_us()
}

/// Run in 0.1 ms steps until the base's wheel command is zero or the simulated clock reaches
/// `deadline` (µs).
fn run_until_wheels_stop(s: &mut SimHost, deadline: u64) {
    while s.sim.now_us() < deadline && s.sim.hw.wheel_command() != (0.0, 0.0) {
        s.run_for(100);
    }
}

/// Drive the base and move the arm slowly (joint 0 towards 1.0 rad over 3 s).
fn drive_and_move(s: &mut SimHost) {
    s.command(&HostMsg::BaseVelocity {
        v: 0.2,
        w: 0.3,
        duration_ms: 10_000,
    })
    .expect("drive accepted");
    s.command(&waypoint(1, 3_000_000, &[1.0]))
        .expect("waypoint accepted");
    s.run_for(400_000);
    assert_ne!(
        s.sim.hw.wheel_command(),
        (0.0, 0.0),
        "the base should drive"
    );
}

/// Send the emergency stop and check what every state must give: an Ack, the stop engaged,
/// the base's wheel command zero within one base cycle, the arm held where it was, motion
/// refused.
fn stop_and_check(s: &mut SimHost, state: &str) {
    let at_stop = true_arm(s);
    let seq = s.send(&HostMsg::EmergencyStop);
    let sent = s.sim.now_us();
    // The frame reaches the firmware after whatever was written ahead of it on the link.
    while !s.sim.fw.estopped() && s.sim.now_us() < sent + 50_000 {
        s.run_for(100);
    }
    assert!(
        s.sim.fw.estopped(),
        "{state}: stop not engaged 50 ms after it was sent"
    );
    let engaged = s.sim.now_us();
    // From there the base has one of its cycles to take the zero command.
    let deadline = engaged + base_cycle_us(s);
    run_until_wheels_stop(s, deadline);
    assert_eq!(
        s.sim.hw.wheel_command(),
        (0.0, 0.0),
        "{state}: the base still has a wheel command {} µs after the stop engaged",
        s.sim.now_us() - engaged
    );
    let ack = s
        .wait_msg(20_000, |m| {
            matches!(m, DeviceMsg::Ack { seq: a } if *a == seq)
                || matches!(m, DeviceMsg::Reject { seq: a, .. } if *a == seq)
        })
        .unwrap_or_else(|e| panic!("{state}: no answer to the stop: {e:?}"));
    assert_eq!(
        ack,
        DeviceMsg::Ack { seq },
        "{state}: stop not acknowledged"
    );
    assert!(s.sim.fw.estopped(), "{state}: stop not engaged");
    // The arm holds: after its braking it stays where it stopped.
    s.run_for(1_000_000);
    let held = true_arm(s);
    assert!(
        max_err(&at_stop, &held) < HOLD_TOL,
        "{state}: arm went from {at_stop:?} to {held:?} after the stop"
    );
    s.run_for(1_000_000);
    let later = true_arm(s);
    assert!(
        max_err(&held, &later) < 0.005,
        "{state}: arm still moving, {held:?} then {later:?}"
    );
    assert_eq!(
        s.sim.hw.base.as_ref().expect("base").drive.speed,
        (0.0, 0.0),
        "{state}: wheels still turning 2 s after the stop"
    );
}

/// With a valid session: motion is refused with `EmergencyStop` until `Resume`, the telemetry
/// shows the flag, and after `Resume` the arm obeys again.
fn refused_until_resume(s: &mut SimHost, state: &str) {
    assert_eq!(
        s.command(&HostMsg::BaseVelocity {
            v: 0.1,
            w: 0.0,
            duration_ms: 500
        }),
        Err(SimError::Rejected(RejectReason::EmergencyStop)),
        "{state}: base motion not refused"
    );
    assert_eq!(
        s.command(&waypoint(1, 300_000, &[0.2])),
        Err(SimError::Rejected(RejectReason::EmergencyStop)),
        "{state}: arm motion not refused"
    );
    let t = s
        .wait_telemetry(100_000, |t| t.faults & fault_flags::ESTOP != 0)
        .unwrap_or_else(|_| panic!("{state}: no ESTOP flag in the telemetry"));
    assert!(t.faults & fault_flags::ESTOP != 0);
    s.command(&HostMsg::Resume).expect("resume");
    assert!(!s.sim.fw.estopped());
    s.command(&HostMsg::SetMode {
        joints: 1,
        mode: JointMode::Position,
    })
    .expect("position mode");
    let q0 = true_arm(s)[0];
    let target = if q0 > 0.0 { q0 - 0.3 } else { q0 + 0.3 };
    s.command(&waypoint(1, 600_000, &[target]))
        .expect("after Resume the arm obeys");
    s.run_for(1_500_000);
    let q = true_arm(s)[0];
    assert!(
        (q - target).abs() < 0.02,
        "{state}: joint 0 at {q} after Resume, target {target}"
    );
}

fn for_both(test: impl Fn(&str)) {
    for robot in ["locobot", "locobot_lite"] {
        test(robot);
    }
}

#[test]
fn the_stop_works_before_any_hello() {
    for_both(|robot| {
        let mut s = SimHost::new(LockstepSim::new(robot, 3).expect("sim"));
        s.run_for(200_000);
        let state = format!("{robot}, before any Hello");
        stop_and_check(&mut s, &state);
        // A session opened afterwards finds the stop engaged.
        s.handshake().expect("hello");
        s.command(&HostMsg::SetTelemetry { period_ms: 10 })
            .expect("telemetry");
        s.wait_telemetry(1_500_000, |t| t.faults & fault_flags::CONFIGURING == 0)
            .expect("servos configured");
        refused_until_resume(&mut s, &state);
    });
}

#[test]
fn the_stop_works_after_a_refused_hello_while_driving() {
    for_both(|robot| {
        let mut s = session(robot);
        drive_and_move(&mut s);
        // A refused Hello is itself a safe state: the base stops within one cycle, the joints
        // hold.
        s.send(&HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH ^ 0x5a5a,
        });
        let sent = s.sim.now_us();
        let DeviceMsg::Hello(info) = s
            .wait_msg(20_000, |m| matches!(m, DeviceMsg::Hello(_)))
            .expect("answer")
        else {
            unreachable!()
        };
        assert!(!info.accepted);
        let deadline = sent + 1_000 + base_cycle_us(&s);
        run_until_wheels_stop(&mut s, deadline);
        assert_eq!(
            s.sim.hw.wheel_command(),
            (0.0, 0.0),
            "{robot}: base drives on after a refused Hello"
        );
        // Other commands are refused in the refused session; the stop is not.
        assert_eq!(
            s.command(&HostMsg::BaseVelocity {
                v: 0.2,
                w: 0.0,
                duration_ms: 1000
            }),
            Err(SimError::Rejected(RejectReason::VersionMismatch))
        );
        let state = format!("{robot}, after a refused Hello");
        stop_and_check(&mut s, &state);
        s.handshake().expect("hello");
        refused_until_resume(&mut s, &state);
    });
}

#[test]
fn the_stop_works_while_driving_and_when_already_stopped() {
    for_both(|robot| {
        let mut s = session(robot);
        drive_and_move(&mut s);
        stop_and_check(&mut s, &format!("{robot}, while driving"));
        // Again, already stopped: acknowledged and still engaged; one Resume releases it.
        stop_and_check(&mut s, &format!("{robot}, already stopped"));
        refused_until_resume(&mut s, &format!("{robot}, already stopped"));
    });
}

#[test]
fn the_stop_works_after_a_watchdog_trip() {
    for_both(|robot| {
        let mut s = session(robot);
        s.command(&HostMsg::SetWatchdog { period_ms: 200 })
            .expect("watchdog");
        drive_and_move(&mut s);
        s.keepalive = false;
        s.run_for(300_000);
        assert_eq!(
            s.sim.hw.wheel_command(),
            (0.0, 0.0),
            "{robot}: watchdog did not trip"
        );
        s.wait_telemetry(50_000, |t| t.faults & fault_flags::WATCHDOG != 0)
            .expect("watchdog flag");
        s.keepalive = true;
        let state = format!("{robot}, after a watchdog trip");
        stop_and_check(&mut s, &state);
        refused_until_resume(&mut s, &state);
    });
}

#[test]
fn the_stop_works_behind_a_full_queue_and_a_burst_of_frames() {
    for_both(|robot| {
        let mut s = session(robot);
        drive_and_move(&mut s);
        // Fill joint 1's waypoint queue until the firmware refuses more.
        let mut full = false;
        for k in 0..64 {
            let q = if k % 2 == 0 { 0.3 } else { 0.5 };
            match s.command(&waypoint(0b10, 400_000, &[q])) {
                Ok(()) => {}
                Err(SimError::Rejected(RejectReason::QueueFull)) => {
                    full = true;
                    break;
                }
                Err(e) => panic!("{robot}: waypoint {k}: {e:?}"),
            }
        }
        assert!(full, "{robot}: the queue never filled");
        // A burst of 40 frames written at once, the stop last.
        let mut burst = Vec::new();
        for _ in 0..40 {
            let mut buf = [0u8; MAX_WIRE];
            let n = encode_frame(
                900,
                &HostMsg::BaseVelocity {
                    v: 0.25,
                    w: -0.2,
                    duration_ms: 5000,
                },
                &mut buf,
            )
            .expect("frame");
            burst.extend_from_slice(&buf[..n]);
        }
        s.send_raw(&burst);
        let state = format!("{robot}, behind a full queue and a burst");
        stop_and_check(&mut s, &state);
        refused_until_resume(&mut s, &state);
    });
}

#[test]
fn the_stop_holds_joints_in_torque_modes_where_they_are() {
    for_both(|robot| {
        let mut s = session(robot);
        // Shoulder and elbow in PWM and current mode with no drive: gravity takes them.
        for (mask, mode) in [(0b10, JointMode::Pwm), (0b100, JointMode::Current)] {
            s.command(&HostMsg::SetMode { joints: mask, mode })
                .expect("mode");
        }
        s.command(&HostMsg::JointCommand {
            joints: 0b110,
            values: [0.0, 0.0].into_iter().collect(),
        })
        .expect("zero drive");
        s.run_for(150_000);
        let state = format!("{robot}, joints in torque modes");
        stop_and_check(&mut s, &state);
        for j in [1, 2] {
            assert_eq!(
                s.sim.fw.joints()[j].mode,
                JointMode::Position,
                "{state}: joint {j} not held in position mode"
            );
        }
    });
}
