//! Teach mode and the arm's gravity model on the LoCoBot, in the lockstep simulator: the model
//! the host sends is trusted only once the arm bears it out, a wrong one never, a payload
//! refutes it; with the plant's masses 20 % off the description, a hand moves the arm and it
//! stays within 0.02 rad of where it was left for 10 s, and a hand pushing it into a limit
//! does not take it past (both hostile-stream checkers watching).

use ferrobot_protocol::*;
use ferrobot_sim::hostile::{strict::StrictChecker, Checker};
use ferrobot_sim::HostSide;
use ferrobot_sim::SimHost;

use crate::common::{max_err, session_with, session_without_model, true_arm, waypoint, ARM};

/// How far the arm may move from where the hand left it over [`LEFT_FOR_US`], rad.
const STAYS_WITHIN: f32 = 0.02;
/// How long it is watched after the hand lets go, µs.
const LEFT_FOR_US: u64 = 10_000_000;

/// A loaded pose: shoulder and elbow forward, the wrist level.
const LOADED: [f32; 5] = [0.3, 0.6, 0.3, 0.4, 0.0];

/// Both checkers, run every millisecond for `dt_us`.
struct Watch {
    loose: Checker,
    strict: StrictChecker,
}

impl Watch {
    fn new(s: &SimHost) -> Self {
        Self {
            loose: Checker::new(&s.sim),
            strict: StrictChecker::new(s.sim.fw.profile().clone()),
        }
    }

    fn run(&mut self, s: &mut SimHost, dt_us: u64, what: &str) {
        let end = s.sim.now_us() + dt_us;
        while s.sim.now_us() < end {
            s.run_for(1000);
            self.loose.check(&s.sim, what);
            self.strict.check(&s.sim, what);
        }
    }

    fn assert_clean(&self) {
        assert!(
            self.loose.violations.is_empty() && self.strict.violations.is_empty(),
            "limits crossed:\n{}\n{}",
            self.loose.violations.join("\n"),
            self.strict.violations.join("\n")
        );
    }
}

fn kinds(s: &mut SimHost) -> Vec<FaultKind> {
    s.take_faults().into_iter().map(|f| f.kind).collect()
}

/// The arm at [`LOADED`], its model confirmed, in teach mode.
fn teaching(scale: f64) -> SimHost {
    let mut s = session_with("locobot", 7, scale);
    s.command(&waypoint(ARM, 2_000_000, &LOADED))
        .expect("to the loaded pose");
    s.run_for(2_600_000);
    assert!(
        kinds(&mut s).contains(&FaultKind::ModelConfirmed),
        "masses ×{scale}: the model was not confirmed"
    );
    s.command(&HostMsg::SetMode {
        joints: ARM,
        mode: JointMode::Teach,
    })
    .expect("teach mode");
    s
}

#[test]
fn a_hand_moves_the_arm_in_teach_mode_and_it_stays_where_it_is_left_with_masses_20_percent_off() {
    for scale in [0.8, 1.2] {
        let mut s = teaching(scale);
        let mut watch = Watch::new(&s);
        // Left alone, it stays.
        let start = true_arm(&s);
        watch.run(&mut s, 1_000_000, "teach mode, no hand");
        let idle = max_err(&true_arm(&s), &start);
        // A hand turns the yaw, lifts the shoulder and bends the wrist down for 1.2 s, then
        // lets go over half a second, as a hand does.
        let hand = [0.5, -1.0, 0.0, 0.6, 0.0];
        for (j, &t) in hand.iter().enumerate() {
            s.sim.hw.chain.set_hand_torque(j, t);
        }
        watch.run(&mut s, 1_200_000, "teach mode, a hand pushing");
        for k in (0..50).rev() {
            for (j, &t) in hand.iter().enumerate() {
                s.sim.hw.chain.set_hand_torque(j, t * k as f64 / 50.0);
            }
            watch.run(&mut s, 10_000, "teach mode, a hand letting go");
        }
        let left = true_arm(&s);
        let moved = max_err(&left, &start);
        let mut worst = 0.0f32;
        let end = s.sim.now_us() + LEFT_FOR_US;
        while s.sim.now_us() < end {
            watch.run(&mut s, 10_000, "teach mode, let go");
            worst = worst.max(max_err(&true_arm(&s), &left));
        }
        eprintln!(
            "masses ×{scale}: idle drift {idle:.4} rad, the hand moved it {moved:.3} rad, then \
             {worst:.4} rad from where it was left over 10 s"
        );
        assert!(
            idle < STAYS_WITHIN,
            "masses ×{scale}: drifted {idle} rad alone"
        );
        assert!(
            moved > 0.2,
            "masses ×{scale}: the hand moved it only {moved} rad"
        );
        assert!(
            worst < STAYS_WITHIN,
            "masses ×{scale}: {worst} rad from where it was left"
        );
        watch.assert_clean();
    }
}

#[test]
fn a_hand_cannot_push_the_arm_past_its_limits_in_teach_mode() {
    let mut s = teaching(1.2);
    let mut watch = Watch::new(&s);
    // Hard into the elbow's upper limit and the yaw's lower one, at twice the load.
    s.sim.hw.chain.set_hand_torque(2, 2.0);
    s.sim.hw.chain.set_hand_torque(0, -1.5);
    watch.run(
        &mut s,
        6_000_000,
        "teach mode, a hand pushing into the limits",
    );
    let lim = |j: usize| s.sim.fw.profile().joints[j].limits;
    let q = true_arm(&s);
    eprintln!("pushed to {q:?}");
    // It went there (compliant), and no further.
    assert!(
        q[2] > lim(2).max - 0.1,
        "elbow at {} of {}",
        q[2],
        lim(2).max
    );
    assert!(q[0] < lim(0).min + 0.1, "yaw at {} of {}", q[0], lim(0).min);
    watch.assert_clean();
}

#[test]
fn a_wrong_model_is_never_trusted_and_a_payload_refutes_a_right_one() {
    // Twice the masses: sent, never confirmed, and teach mode refused.
    let mut s = session_with("locobot", 7, 1.0);
    s.command(&waypoint(ARM, 2_000_000, &LOADED)).expect("pose");
    s.run_for(2_600_000);
    s.take_faults();
    let model = ferrobot_sim::robots::arm_model("locobot");
    let count = model.len() as u8;
    for (index, link) in (0u8..).zip(&model) {
        let link = ArmLink {
            mass: 2.0 * link.mass,
            ..*link
        };
        s.command(&HostMsg::ArmLink { index, count, link })
            .expect("in range");
    }
    s.run_for(1_000_000);
    assert!(!kinds(&mut s).contains(&FaultKind::ModelConfirmed));
    // The right one, trusted before, stays trusted: teach mode may be set.
    let teach = HostMsg::SetMode {
        joints: ARM,
        mode: JointMode::Teach,
    };
    s.command(&teach).expect("the right model still trusted");
    s.command(&HostMsg::SetMode {
        joints: ARM,
        mode: JointMode::Position,
    })
    .expect("position mode");
    // The right one: confirmed.
    for (index, &link) in (0u8..).zip(&model) {
        s.command(&HostMsg::ArmLink { index, count, link })
            .expect("the model");
    }
    s.run_for(500_000);
    assert!(kinds(&mut s).contains(&FaultKind::ModelConfirmed));
    // A payload in the gripper, half a kilogram the model does not know: refuted, and the
    // arm hands its load over without moving.
    let held = true_arm(&s);
    s.sim
        .hw
        .chain
        .scale_arm_masses(|i| if i == 4 { 5.0 } else { 1.0 });
    let mut worst = 0.0f32;
    for _ in 0..150 {
        s.run_for(10_000);
        worst = worst.max(max_err(&true_arm(&s), &held));
    }
    let faults = s.take_faults();
    let refuted = faults.iter().find(|f| f.kind == FaultKind::ModelRefuted);
    eprintln!("payload: {worst:.4} rad from where it was held; {refuted:?}");
    assert!(refuted.is_some(), "{faults:?}");
    assert!(s.command(&teach).is_err());
    assert!(worst < 0.05, "the arm moved {worst} rad");
}

#[test]
fn hostile_gravity_models_are_refused_and_leave_no_half_model() {
    let mut s = session_without_model("locobot");
    let model = ferrobot_sim::robots::arm_model("locobot");
    let good = model[1];
    let count = model.len() as u8;
    let gripper = s
        .sim
        .fw
        .profile()
        .joints
        .iter()
        .position(|j| j.kind == JointKind::Gripper)
        .expect("a gripper") as u8;
    let refused = |l: ArmLink| HostMsg::ArmLink {
        index: 0,
        count,
        link: l,
    };
    for (what, l) in [
        (
            "a NaN mass",
            ArmLink {
                mass: f32::NAN,
                ..good
            },
        ),
        ("a negative mass", ArmLink { mass: -1.0, ..good }),
        (
            "a tonne",
            ArmLink {
                mass: 1000.0,
                ..good
            },
        ),
        (
            "a centre of mass 3 m away",
            ArmLink {
                com: [3.0, 0.0, 0.0],
                ..good
            },
        ),
        (
            "a zero axis",
            ArmLink {
                axis: [0.0; 3],
                ..good
            },
        ),
        (
            "an infinite angle",
            ArmLink {
                rpy: [f32::INFINITY, 0.0, 0.0],
                ..good
            },
        ),
        (
            "the gripper's row",
            ArmLink {
                joint: gripper,
                ..good
            },
        ),
        (
            "the camera's tilt",
            ArmLink {
                joint: gripper + 2,
                ..good
            },
        ),
        ("no such row", ArmLink { joint: 200, ..good }),
    ] {
        assert!(s.command(&refused(l)).is_err(), "{what} was accepted");
    }
    // Too many links, out of order, a row twice: refused, and the model stays whole or none.
    let msg = |index: u8, count: u8, link: ArmLink| HostMsg::ArmLink { index, count, link };
    assert!(s.command(&msg(0, 9, good)).is_err());
    assert!(s.command(&msg(1, count, good)).is_err());
    s.command(&msg(0, count, model[0])).expect("first link");
    assert!(s.command(&msg(1, count, model[0])).is_err(), "a row twice");
    assert!(
        s.command(&msg(2, count, model[2])).is_err(),
        "after a refusal"
    );
    s.command(&waypoint(ARM, 2_000_000, &LOADED)).expect("pose");
    s.run_for(3_000_000);
    let teach = HostMsg::SetMode {
        joints: ARM,
        mode: JointMode::Teach,
    };
    assert!(s.command(&teach).is_err(), "teach mode on half a model");
}
