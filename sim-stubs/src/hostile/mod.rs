//! A hostile host for the firmware: seeded random streams of every `HostMsg` variant with
//! hostile field values mixed with ordinary ones ([`Mix`]), interleaved with time, on every
//! robot profile, through the lockstep simulator; [`Checker`] (and beside it
//! [`strict::StrictChecker`]) asserts on the plants' true state that joints under control stay
//! within their limits ([`POS_TOL`], [`SPEED_TOL`], [`SPEED_ABS`], [`BRAKING`], [`GRACE_US`])
//! and wheels within top speed ([`WHEEL_TOL`]), and at the end an emergency stop stops
//! everything and a valid session recovers. `FERROBOT_HOSTILE_MESSAGES` and
//! `FERROBOT_HOSTILE_SEED` set the length and the seeds. Design: `docs/design/sim-stubs.md`,
//! "hostile".

mod checker;
mod stream;
pub mod strict;

pub use checker::*;
pub use stream::{message, mixed_message, model_burst, pointed_message, Mix};

use crate::lockstep::HostSide;
use crate::SimHost;
use ferrobot_firmware::config;
use ferrobot_protocol::*;
use rand::Rng;

/// Run `dt_us` in 1 ms steps, checking after each.
pub fn run(s: &mut SimHost, c: &mut Checker, dt_us: u64, what: &str) {
    let end = s.sim.now_us() + dt_us;
    while s.sim.now_us() < end {
        let step = 1000.min(end - s.sim.now_us());
        s.run_for(step);
        c.check(&s.sim, what);
    }
}

/// Start `robot` (plant seed `seed`), send it `messages` hostile messages drawn from `rng`
/// with time between them, checking throughout; then stop it and recover it (panics if either
/// fails). The checker and the simulated time at the end, µs.
pub fn hostile_stream<R: Rng + ?Sized>(
    rng: &mut R,
    robot: &str,
    seed: u64,
    messages: usize,
) -> (Checker, u64) {
    hostile_stream_of(rng, robot, seed, messages, Mix::Broad)
}

/// [`hostile_stream`] with messages of mix `mix`.
pub fn hostile_stream_of<R: Rng + ?Sized>(
    rng: &mut R,
    robot: &str,
    seed: u64,
    messages: usize,
    mix: Mix,
) -> (Checker, u64) {
    let rng = &mut *rng;
    let mut s = SimHost::start(robot, seed).expect("simulator");
    // The plant's masses differ from the description's (and so from the firmware's gravity
    // model) by up to ±MASS_TOL, seeded: the model is not assumed exact.
    let mut masses = crate::rng::SimRng::new(seed, 4242);
    s.sim
        .hw
        .chain
        .scale_arm_masses(|_| 1.0 + MASS_TOL * (2.0 * masses.uniform() - 1.0));
    let mut c = Checker::new(&s.sim);
    // The host sends the arm's gravity model from the description first, as a host does.
    let honest = crate::robots::arm_model(robot);
    for (index, &link) in (0u8..).zip(&honest) {
        let count = honest.len() as u8;
        s.send(&HostMsg::ArmLink { index, count, link });
    }
    run(&mut s, &mut c, 1_500_000, "configuration");
    stream(rng, &mut s, &mut c, messages, mix, &honest);
    emergency_stop(&mut s, &mut c, robot);
    recover(&mut s, &mut c, robot);
    let t = s.sim.now_us();
    (c, t)
}

/// The stream itself: `messages` messages of mix `mix`, each followed by a random gap.
fn stream<R: Rng + ?Sized>(
    rng: &mut R,
    s: &mut SimHost,
    c: &mut Checker,
    messages: usize,
    mix: Mix,
    honest: &[ArmLink],
) {
    for k in 0..messages {
        // Now and then a whole gravity model, honest or not, link after link.
        let msgs = if rng.random_bool(0.02) {
            model_burst(rng, &s.sim.fw, honest)
        } else {
            vec![mixed_message(rng, &s.sim.fw, mix)]
        };
        let what = format!("after message {k} {msgs:?}");
        for msg in &msgs {
            s.send(msg);
        }
        let gap = match rng.random_range(0..20) {
            0 => rng.random_range(100_000..600_000),
            1..=4 => rng.random_range(10_000..50_000),
            _ => rng.random_range(0..5_000),
        };
        run(s, c, gap, &what);
        s.inbox.clear();
    }
}

/// The end: an emergency stop in whatever state the stream left, engaged and acknowledged,
/// the base's wheels commanded to 0 within a base cycle, every controlled joint at rest.
fn emergency_stop(s: &mut SimHost, c: &mut Checker, robot: &str) {
    // The end: an emergency stop in whatever state the stream left.
    let seq = s.send(&HostMsg::EmergencyStop);
    let stop_at = s.sim.now_us();
    run(s, c, 1000, "emergency stop");
    assert!(s.sim.fw.estopped(), "the emergency stop was not engaged");
    let acked = s
        .inbox
        .iter()
        .any(|f| matches!(f, DeviceMsg::Ack { seq: a } if *a == seq));
    assert!(acked, "the emergency stop was not acknowledged");
    if s.sim.hw.base.is_some() {
        // One base cycle (Kobuki 20 ms, Create 2 15 ms) for the command to reach the wheels.
        let deadline = stop_at + 20_000;
        while s.sim.now_us() < deadline && s.sim.hw.wheel_command() != (0.0, 0.0) {
            run(s, c, 1000, "emergency stop");
        }
        assert_eq!(
            s.sim.hw.wheel_command(),
            (0.0, 0.0),
            "{robot}: base still commanded"
        );
    }
    run(s, c, 800_000, "after the emergency stop");
    for (j, cfg) in s.sim.fw.profile().joints.iter().enumerate() {
        let controlled =
            cfg.kind != JointKind::Gripper && s.sim.fw.joints()[j].mode != JointMode::Off;
        if let (true, Some(servo)) = (controlled, s.sim.hw.chain.servo(cfg.servo_id)) {
            assert!(
                servo.omega.abs() < 0.05,
                "{robot}: joint {j} still moving at {} rad/s after the emergency stop: {:?} mode, \
                 servo at {:.4} rad (mode {}, torque {}, error {}, goal position {}, goal current \
                 {}, goal PWM {}), limits {:?}, servo status {:?}",
                servo.omega,
                s.sim.fw.joints()[j].mode,
                servo.theta,
                servo.get(dxl::addr::OPERATING_MODE, 1),
                servo.torque_enabled(),
                servo.hardware_error(),
                servo.get(dxl::addr::GOAL_POSITION, 4) as i32,
                servo.get(dxl::addr::GOAL_CURRENT, 2) as i16,
                servo.get(dxl::addr::GOAL_PWM, 2) as i16,
                cfg.limits,
                s.sim
                    .fw
                    .bus()
                    .servos
                    .iter()
                    .find(|b| b.id == cfg.servo_id)
                    .map(|b| (b.status, b.mode, b.torque, b.ops))
            );
        }
    }
}

/// Recovery: a valid session, Resume, every joint off, the default joint table, then joint 0
/// in position mode and a waypoint it reaches.
fn recover(s: &mut SimHost, c: &mut Checker, robot: &str) {
    // Recovery: a valid session, Resume, every joint off, the default joint table, then
    // joint 0 in position mode and a waypoint.
    s.handshake().expect("hello");
    s.command(&HostMsg::Resume).expect("resume");
    s.command(&HostMsg::SetMode {
        joints: u16::MAX,
        mode: JointMode::Off,
    })
    .expect("off");
    for (i, row) in config::by_name(robot)
        .expect("profile")
        .joints
        .iter()
        .enumerate()
    {
        s.command(&HostMsg::ConfigureJoint {
            index: i as u8,
            config: row.clone(),
        })
        .expect("default joint row");
        // Clears any overload the stream left latched.
        s.command(&HostMsg::RebootJoint { joint: i as u8 })
            .expect("reboot");
    }
    s.command(&HostMsg::SetLoopPeriod { period_us: 1000 })
        .expect("loop period");
    s.command(&HostMsg::SetWatchdog { period_ms: 500 })
        .expect("watchdog");
    s.command(&HostMsg::SetMode {
        joints: 0b1,
        mode: JointMode::Position,
    })
    .expect("position");
    run(s, c, 600_000, "recovery");
    s.command(&HostMsg::Waypoint {
        joints: 0b1,
        duration_us: 1_000_000,
        points: [JointPoint::at_rest(0.4)].into_iter().collect(),
    })
    .expect("waypoint accepted");
    run(s, c, 2_500_000, "recovery waypoint");
    let cfg = &s.sim.fw.profile().joints[0];
    let q = cfg.sign as f64
        * (s.sim.hw.chain.servo(cfg.servo_id).expect("servo").theta - cfg.offset as f64);
    assert!(
        (q - 0.4).abs() < 0.02,
        "{robot}: joint 0 at {q} after the recovery waypoint"
    );
}
