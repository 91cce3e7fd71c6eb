//! Lockstep acceptance: LoCoBot arm targets through the protocol, in position and current
//! mode; the gripper state machine with and without an object.

use crate::common;
use common::*;
use ferrobot_protocol::*;
use ferrobot_sim::HostSide;

const TARGETS: [[f32; 5]; 3] = [
    [0.3, 0.5, -0.4, 0.2, 0.1],
    [-0.8, 0.9, 0.3, -1.0, -1.2],
    [1.2, -0.6, 1.1, 0.8, 0.6],
];

#[test]
fn arm_reaches_targets_in_position_mode_within_0_01_rad() {
    let mut s = session("locobot");
    for target in TARGETS {
        s.command(&waypoint(ARM, 2_000_000, &target))
            .expect("accepted");
        s.run_for(3_500_000);
        let truth = true_arm(&s);
        let measured = measured_arm(&s);
        assert!(
            max_err(&truth, &target) < 0.01,
            "target {target:?}, servos at {truth:?}"
        );
        assert!(
            max_err(&measured, &target) < 0.01,
            "target {target:?}, measured {measured:?}"
        );
    }
}

#[test]
fn arm_reaches_targets_in_current_mode_within_0_02_rad() {
    let mut s = session("locobot");
    s.command(&HostMsg::SetMode {
        joints: ARM,
        mode: JointMode::Current,
    })
    .expect("current mode");
    s.run_for(200_000);
    for target in TARGETS {
        s.command(&waypoint(ARM, 2_000_000, &target))
            .expect("accepted");
        s.run_for(4_000_000);
        let truth = true_arm(&s);
        assert!(
            max_err(&truth, &target) < 0.02,
            "target {target:?}, servos at {truth:?}"
        );
    }
    // The servos really ran in current mode (XM430: 0) and PWM mode (XL430 wrist: 16).
    assert_eq!(
        s.sim
            .hw
            .chain
            .servo(1)
            .expect("servo")
            .get(ferrobot_protocol::dxl::addr::OPERATING_MODE, 1),
        0
    );
    assert_eq!(
        s.sim
            .hw
            .chain
            .servo(6)
            .expect("servo")
            .get(ferrobot_protocol::dxl::addr::OPERATING_MODE, 1),
        16
    );
}

#[test]
fn velocity_limit_is_enforced_whatever_the_host_sends() {
    let mut s = session("locobot");
    // Ask joint_1 to jump 1.5 rad in 10 ms: 150 rad/s; its limit is 1 rad/s.
    s.command(&waypoint(1, 10_000, &[1.5])).expect("accepted");
    let mut peak = 0.0f32;
    for _ in 0..200 {
        s.run_for(10_000);
        peak = peak.max(
            s.telemetry.as_ref().expect("telemetry").joints[0]
                .velocity
                .abs(),
        );
    }
    assert!(peak < 1.0 * 1.15, "peak joint speed {peak} rad/s");
    assert!((true_arm(&s)[0] - 1.5).abs() < 0.01);
    let faults = s.take_faults();
    assert!(
        faults
            .iter()
            .any(|f| f.kind == FaultKind::LimitClamped && f.joint == Some(0)),
        "{faults:?}"
    );
}

#[test]
fn out_of_limit_and_malformed_commands_are_rejected() {
    let mut s = session("locobot");
    s.run_for(2_000_000);
    let before = true_arm(&s);
    let reject = |s: &mut ferrobot_sim::SimHost, m: HostMsg| match s.command(&m) {
        Err(ferrobot_sim::SimError::Rejected(r)) => r,
        other => panic!("{m:?} gave {other:?}"),
    };
    assert_eq!(
        reject(&mut s, waypoint(1, 1000, &[2.0])),
        RejectReason::OutOfLimits
    );
    assert_eq!(
        reject(&mut s, waypoint(0b11, 1000, &[0.1])),
        RejectReason::CountMismatch
    );
    assert_eq!(
        reject(&mut s, waypoint(1, 1000, &[f32::NAN])),
        RejectReason::NotFinite
    );
    assert_eq!(
        reject(&mut s, waypoint(1 << 12, 1000, &[0.1])),
        RejectReason::UnknownJoint
    );
    assert_eq!(
        reject(
            &mut s,
            HostMsg::JointCommand {
                joints: 1,
                values: [0.1].into_iter().collect()
            }
        ),
        RejectReason::WrongMode
    );
    // Nothing moved.
    s.run_for(500_000);
    assert!(
        max_err(&true_arm(&s), &before) < 0.005,
        "{before:?} -> {:?}",
        true_arm(&s)
    );
}

/// Opens the gripper, puts an object 40 % of the way in (the fingers stop at 2300 ticks) and
/// starts closing on it.
fn close_on_an_object(s: &mut ferrobot_sim::lockstep::SimHost) {
    s.command(&HostMsg::Gripper(GripperCommand::Open))
        .expect("open");
    s.wait_telemetry(2_000_000, |t| t.gripper == GripperState::Open)
        .expect("opens");
    let at = ferrobot_protocol::dxl::units::tick_to_rad(2300) as f64;
    s.sim.hw.chain.servo_mut(7).expect("gripper").obstacle = Some((at, true));
    s.command(&HostMsg::Gripper(GripperCommand::Close))
        .expect("close");
}

#[test]
fn gripper_closes_fully_without_an_object_and_holds_one() {
    let mut s = session("locobot");
    s.command(&HostMsg::Gripper(GripperCommand::Open))
        .expect("open");
    s.wait_telemetry(2_000_000, |t| t.gripper == GripperState::Open)
        .expect("opens");
    assert!(
        (gripper_ticks(&s) - 2800).abs() <= 30,
        "{}",
        gripper_ticks(&s)
    );

    s.command(&HostMsg::Gripper(GripperCommand::Close))
        .expect("close");
    let t = s
        .wait_telemetry(3_000_000, |t| {
            matches!(t.gripper, GripperState::Closed | GripperState::Holding)
        })
        .expect("closes");
    assert_eq!(t.gripper, GripperState::Closed);
    assert!(gripper_ticks(&s) < 1800);

    close_on_an_object(&mut s);
    let t = s
        .wait_telemetry(3_000_000, |t| {
            matches!(t.gripper, GripperState::Closed | GripperState::Holding)
        })
        .expect("closes");
    assert_eq!(t.gripper, GripperState::Holding);
    let g = gripper_ticks(&s);
    assert!((2250..2350).contains(&g), "fingers at {g}");
    // Holding does not overload the servo.
    s.run_for(5_000_000);
    assert_eq!(
        s.sim.hw.chain.servo(7).expect("gripper").hardware_error(),
        0
    );
    assert_eq!(
        s.telemetry.as_ref().expect("telemetry").gripper,
        GripperState::Holding
    );
}

#[test]
fn velocity_and_pwm_modes_move_the_joint_and_stop_at_its_limits() {
    let mut s = session("locobot");
    // Velocity mode: joint_1 at 0.4 rad/s for 1 s.
    s.command(&HostMsg::SetMode {
        joints: 1,
        mode: JointMode::Velocity,
    })
    .expect("velocity mode");
    s.run_for(50_000);
    s.command(&HostMsg::JointCommand {
        joints: 1,
        values: [0.4].into_iter().collect(),
    })
    .expect("accepted");
    // The servo's velocity PI (factory gains) winds up within a few hundred ms; then measure.
    s.run_for(500_000);
    let q0 = true_arm(&s)[0];
    s.run_for(500_000);
    let speed = (true_arm(&s)[0] - q0) / 0.5;
    assert!(
        (speed - 0.4).abs() < 0.4 * 0.05,
        "steady speed {speed} rad/s, asked 0.4"
    );
    // Asked for 5 rad/s: the firmware holds it to the joint's 1 rad/s and stops at +1.57.
    s.command(&HostMsg::JointCommand {
        joints: 1,
        values: [5.0].into_iter().collect(),
    })
    .expect("accepted");
    s.run_for(3_000_000);
    let q = true_arm(&s)[0];
    assert!(q <= 1.57 + 0.01 && q > 1.5, "joint_1 at {q}");
    // PWM mode on the pan servo: it turns, and stops at its limit.
    s.command(&HostMsg::SetMode {
        joints: 1 << 6,
        mode: JointMode::Pwm,
    })
    .expect("pwm mode");
    s.run_for(50_000);
    s.command(&HostMsg::JointCommand {
        joints: 1 << 6,
        values: [-0.3].into_iter().collect(),
    })
    .expect("accepted");
    s.run_for(4_000_000);
    let pan = s.telemetry.as_ref().expect("telemetry").joints[6].position;
    assert!((-2.71..=-2.6).contains(&pan), "pan at {pan}, limit -2.7");
}

/// The emergency stop stops the gripper in every state: closing on nothing (it kept closing at
/// full PWM, a pinch), opening, and closing on an object, which it keeps holding.
#[test]
fn the_emergency_stop_stops_the_gripper_and_keeps_what_it_holds() {
    let mut s = session("locobot");
    let stop_mid = |s: &mut ferrobot_sim::lockstep::SimHost,
                    cmd: GripperCommand,
                    after_us: u64|
     -> (i32, i32) {
        s.command(&HostMsg::Gripper(cmd)).expect("gripper");
        s.run_for(after_us);
        s.command(&HostMsg::EmergencyStop).expect("stop");
        // Let the servo brake (a few ticks), then it must stay put.
        s.run_for(150_000);
        let at_stop = gripper_ticks(s);
        s.run_for(1_000_000);
        let later = gripper_ticks(s);
        s.command(&HostMsg::Resume).expect("resume");
        (at_stop, later)
    };
    for (cmd, from) in [
        (GripperCommand::Close, GripperCommand::Open),
        (GripperCommand::Open, GripperCommand::Close),
    ] {
        s.command(&HostMsg::Gripper(from)).expect("from");
        s.run_for(2_500_000);
        let start = gripper_ticks(&s);
        let (at_stop, later) = stop_mid(&mut s, cmd, 150_000);
        assert!(
            (later - at_stop).abs() <= 20,
            "{cmd:?} from {start}: {at_stop} at the stop, {later} a second later"
        );
        assert!(
            (at_stop - start).abs() >= 40
                && (later
                    - if cmd == GripperCommand::Close {
                        1800
                    } else {
                        2800
                    })
                .abs()
                    > 100,
            "{cmd:?}: it had not moved, or it finished: {start} -> {at_stop} -> {later}"
        );
    }
    // Holding an object: still held after the stop.
    close_on_an_object(&mut s);
    s.wait_telemetry(3_000_000, |t| t.gripper == GripperState::Holding)
        .expect("holds");
    s.command(&HostMsg::EmergencyStop).expect("stop");
    s.run_for(1_000_000);
    let g = gripper_ticks(&s);
    assert!((2250..2350).contains(&g), "fingers at {g}");
    assert_eq!(
        s.telemetry.as_ref().expect("telemetry").gripper,
        GripperState::Holding
    );
}
