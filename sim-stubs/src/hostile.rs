//! A hostile host for the firmware: seeded random streams of every `HostMsg` variant with
//! hostile field values (±0, subnormals, ±1e38, ±f32::MAX, NaN, ±inf, integer extremes, random
//! masks and indices) mixed with ordinary ones, interleaved with time, on every robot profile,
//! through the lockstep simulator. Throughout, on the plants' true state:
//!
//! * every joint under control (not switched off by the host, not being configured, not the
//!   gripper, which its own state machine drives against its stops) stays within its
//!   configured position limits (tolerance [`POS_TOL`]) and within its velocity limit
//!   (tolerance [`SPEED_TOL`] of the limit plus [`SPEED_ABS`]), unless it is pressed against a
//!   mechanical stop (limits set beyond the joint's mechanical range). A joint that was limp (off,
//!   rebooting, being configured) goes where gravity takes it, and a joint that new limits
//!   left outside is outside through no motion of its own: from there it may run on for its
//!   stopping distance (at [`BRAKING`]) and, once taken under control or switched to another
//!   mode, for [`GRACE_US`]; then it may only come back and slow down;
//! * the wheels stay within the base's top speed ([`WHEEL_TOL`]);
//! * nothing panics.
//!
//! At the end an emergency stop, sent in whatever session state the stream left, stops the
//! base within one base cycle and brings every joint to rest; after a valid Hello and Resume
//! the arm obeys a waypoint again. `FERROBOT_HOSTILE_MESSAGES` sets the messages per profile
//! (CI: 20,000) and `FERROBOT_HOSTILE_SEED` shifts the seeds (CI: 0), for longer searches.

use crate::{LockstepSim, SimHost};
use ferrobot_firmware::config;
use ferrobot_protocol::*;
use rand::Rng;

/// Position tolerance beyond a limit, rad.
pub const POS_TOL: f64 = 0.06;
/// Relative speed tolerance over a velocity limit.
pub const SPEED_TOL: f64 = 0.25;
/// Absolute speed tolerance, rad/s (encoder and dynamics noise).
pub const SPEED_ABS: f64 = 0.25;
/// A joint the checker lets brake first (a limp one taken under control, one that new limits
/// left outside) may still run on for its stopping distance at this deceleration, rad/s²,
/// before it must come back.
pub const BRAKING: f64 = 200.0;

fn stopping(v: f64) -> f64 {
    v * v / (2.0 * BRAKING)
}
/// How long (µs) a joint taken under control (switched on, or switched to another mode) may
/// still run on as it was: its servo changes mode and its first goals go out.
pub const GRACE_US: u64 = 5_000;
/// How far (relative) the plant's link masses may differ from the description's.
pub const MASS_TOL: f64 = 0.2;
/// Relative tolerance over the base's top wheel speed.
pub const WHEEL_TOL: f64 = 0.05;

fn hostile_f32<R: Rng + ?Sized>(rng: &mut R) -> f32 {
    const SPECIAL: [f32; 14] = [
        0.0,
        -0.0,
        1e-45,
        -1e-45,
        f32::MIN_POSITIVE,
        1e38,
        -1e38,
        f32::MAX,
        f32::MIN,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1e6,
        -1e6,
    ];
    match rng.random_range(0..10) {
        0..=3 => SPECIAL[rng.random_range(0..SPECIAL.len())],
        4..=7 => rng.random_range(-3.0..3.0),
        _ => rng.random_range(-30.0..30.0),
    }
}

/// `ordinary`, or (half the time) a hostile special value.
fn special_or<R: Rng + ?Sized>(rng: &mut R, ordinary: f32) -> f32 {
    if rng.random_bool(0.5) {
        ordinary
    } else {
        hostile_f32(rng)
    }
}

/// A value that is usually ordinary (in `lo..hi`) and sometimes hostile.
fn value<R: Rng + ?Sized>(rng: &mut R, lo: f32, hi: f32) -> f32 {
    if rng.random_bool(0.8) {
        rng.random_range(lo..=hi)
    } else {
        hostile_f32(rng)
    }
}

fn hostile_u16<R: Rng + ?Sized>(rng: &mut R, ordinary: std::ops::Range<u16>) -> u16 {
    match rng.random_range(0..6) {
        0 => 0,
        1 => u16::MAX,
        2 => rng.random(),
        _ => rng.random_range(ordinary),
    }
}

fn mask<R: Rng + ?Sized>(rng: &mut R, n: usize) -> u16 {
    match rng.random_range(0..8) {
        0 => u16::MAX,
        1 => rng.random(),
        2 => 1 << rng.random_range(0..16),
        _ => rng.random::<u16>() & ((1 << n) - 1),
    }
}

fn index<R: Rng + ?Sized>(rng: &mut R, n: usize) -> u8 {
    if rng.random_bool(0.9) {
        rng.random_range(0..n as u8)
    } else {
        rng.random()
    }
}

fn mode<R: Rng + ?Sized>(rng: &mut R) -> JointMode {
    [
        JointMode::Off,
        JointMode::Position,
        JointMode::Position,
        JointMode::Velocity,
        JointMode::Current,
        JointMode::Pwm,
    ][rng.random_range(0..6)]
}

/// How many values a message for the joints of mask `m` (of `n` joints) carries: usually one
/// per selected joint, sometimes any count up to [`MAX_JOINTS`].
fn value_count<R: Rng + ?Sized>(rng: &mut R, m: u16, n: usize) -> usize {
    if rng.random_bool(0.9) {
        (m as u32 & ((1 << n) - 1)).count_ones() as usize
    } else {
        rng.random_range(0..=MAX_JOINTS)
    }
}

/// One message of the stream for firmware `fw`'s current joint table.
pub fn message<R: Rng + ?Sized>(rng: &mut R, fw: &ferrobot_firmware::Firmware) -> HostMsg {
    let joints = &fw.profile().joints;
    let n = joints.len();
    let k = rng.random_range(0..100);
    match k {
        0 => HostMsg::Hello {
            protocol_version: if rng.random_bool(0.5) {
                PROTOCOL_VERSION
            } else {
                rng.random()
            },
            schema_hash: rng.random(),
        },
        1..=2 => HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH,
        },
        3 => HostMsg::GetJoint {
            index: index(rng, n),
        },
        4 => {
            let i = index(rng, n + 1);
            let mut config = joints
                .get(rng.random_range(0..n))
                .cloned()
                .expect("a joint");
            // Commissioning values: hostile ones (refused), or ordinary ones that keep the
            // joint's limits within its mechanical range (a limit the joint cannot physically
            // reach cannot be kept).
            match rng.random_range(0..6) {
                0 => config.limits.min = special_or(rng, config.limits.min + 0.2),
                1 => {
                    let v = rng.random_range(0.05..2.0);
                    config.limits.velocity = special_or(rng, v)
                }
                2 => {
                    let o = rng.random_range(-0.1..0.1);
                    config.offset = special_or(rng, o)
                }
                3 => config.pid.kp = hostile_f32(rng),
                4 => config.sign = rng.random(),
                _ => {}
            }
            HostMsg::ConfigureJoint { index: i, config }
        }
        5..=6 => HostMsg::SetPid {
            joint: index(rng, n),
            gains: PidGains {
                kp: value(rng, 0.0, 60.0),
                ki: value(rng, 0.0, 40.0),
                kd: value(rng, 0.0, 3.0),
                i_limit: value(rng, 0.0, 2.0),
            },
        },
        7..=9 => {
            let j = index(rng, n);
            let base = joints
                .get(j as usize)
                .map(|c| c.limits)
                .unwrap_or(joints[0].limits);
            let a = value(rng, base.min, base.max);
            let b = value(rng, base.min, base.max);
            HostMsg::SetLimits {
                joint: j,
                limits: JointLimits {
                    min: a.min(b),
                    max: a.max(b),
                    velocity: value(rng, 0.05, 2.0),
                    effort: value(rng, 0.0, base.effort),
                },
            }
        }
        10..=17 => HostMsg::SetMode {
            joints: mask(rng, n),
            mode: mode(rng),
        },
        18..=35 => {
            let m = mask(rng, n);
            let count = value_count(rng, m, n);
            let points = (0..count)
                .map(|_| JointPoint {
                    position: value(rng, -1.6, 1.6),
                    velocity: value(rng, -2.0, 2.0),
                    effort: value(rng, -2.0, 2.0),
                })
                .collect();
            HostMsg::Waypoint {
                joints: m,
                duration_us: match rng.random_range(0..6) {
                    0 => 0,
                    1 => u32::MAX,
                    _ => rng.random_range(0..2_000_000),
                },
                points,
            }
        }
        36..=38 => HostMsg::ClearQueue {
            joints: mask(rng, n),
        },
        39..=60 => {
            let m = mask(rng, n);
            let count = value_count(rng, m, n);
            HostMsg::JointCommand {
                joints: m,
                values: (0..count).map(|_| value(rng, -3.0, 3.0)).collect(),
            }
        }
        61..=70 => HostMsg::BaseVelocity {
            v: value(rng, -0.8, 0.8),
            w: value(rng, -3.0, 3.0),
            duration_ms: hostile_u16(rng, 0..3000),
        },
        71 => HostMsg::ResetOdometry,
        72..=74 => HostMsg::Gripper(if rng.random_bool(0.5) {
            GripperCommand::Open
        } else {
            GripperCommand::Close
        }),
        75..=76 => HostMsg::SetWatchdog {
            period_ms: hostile_u16(rng, 1..2500),
        },
        77..=80 => HostMsg::Heartbeat,
        81..=82 => HostMsg::EmergencyStop,
        83..=86 => HostMsg::Resume,
        87 => HostMsg::SetTelemetry {
            period_ms: hostile_u16(rng, 0..100),
        },
        88 => HostMsg::SetLoopPeriod {
            period_us: match rng.random_range(0..4) {
                0 => 0,
                1 => u32::MAX,
                _ => rng.random_range(200..2_000),
            },
        },
        89..=90 => HostMsg::RebootJoint {
            joint: index(rng, n),
        },
        91 => HostMsg::GetDiagnostics,
        92..=93 => HostMsg::SetBaseGeometry {
            left_radius: value(rng, 0.03, 0.04),
            right_radius: value(rng, 0.03, 0.04),
            track: value(rng, 0.2, 0.26),
        },
        _ => HostMsg::Heartbeat,
    }
}

/// What the checker remembers of a joint.
#[derive(Clone)]
struct Watch {
    row: Option<JointConfig>,
    /// How far outside its limits the joint may still be (it may only come back).
    outside: f64,
    /// How fast it may still move, beyond its limit (it may only slow down).
    speed: f64,
    /// The last sample: time (µs) and output angle (rad).
    last: Option<(u64, f64)>,
    /// Until when (µs) a joint just taken under control may still speed up: its servo is
    /// switched on and its first goals go out.
    grace_until: u64,
    /// Whether the joint was under control at the last sample, and in which mode.
    was_controlled: bool,
    mode: JointMode,
}

impl Watch {
    /// A joint the checker has not seen move yet, with joint-table row `row`.
    fn new(row: Option<JointConfig>) -> Self {
        Watch {
            row,
            outside: 0.0,
            speed: 0.0,
            last: None,
            grace_until: 0,
            was_controlled: false,
            mode: JointMode::Off,
        }
    }
}

/// Checks the invariants on the plants' true state; returns violations found.
pub struct Checker {
    watch: Vec<Watch>,
    /// What was violated, where and when.
    pub violations: Vec<String>,
    /// Checks made.
    pub samples: u64,
    /// Worst excess seen on controlled joints: beyond a position limit (rad), and speed over
    /// the velocity limit (rad/s), with where each happened.
    pub worst: (f64, f64),
    /// Where the worst excesses happened.
    pub worst_at: (String, String),
}

fn outside(q: f64, l: &JointLimits) -> f64 {
    (l.min as f64 - q).max(q - l.max as f64).max(0.0)
}

impl Checker {
    /// A checker for `sim`'s joint table.
    pub fn new(sim: &LockstepSim) -> Self {
        let watch = sim
            .fw
            .profile()
            .joints
            .iter()
            .map(|c| Watch::new(Some(c.clone())))
            .collect();
        Checker {
            watch,
            violations: Vec::new(),
            samples: 0,
            worst: (0.0, 0.0),
            worst_at: (String::new(), String::new()),
        }
    }

    /// Check the invariants on the plants' state now; `what` says where in the stream.
    pub fn check(&mut self, sim: &LockstepSim, what: &str) {
        self.samples += 1;
        let fw = &sim.fw;
        let joints = &fw.profile().joints;
        self.watch.resize(joints.len(), Watch::new(None));
        for (j, cfg) in joints.iter().enumerate() {
            let Some(servo) = sim.hw.chain.servo(cfg.servo_id) else {
                continue;
            };
            let sign = cfg.sign as f64;
            let q = sign * (servo.theta - cfg.offset as f64);
            let w = &mut self.watch[j];
            // The output's speed now (the motor may turn inside the backlash while the joint
            // stands still: that is not the joint moving).
            let now = sim.now_us();
            let qd = sign * servo.output_speed();
            // Time since the last sample, for the allowed speed's fall.
            let dt = w
                .last
                .map_or(0.0, |(t, _)| now.saturating_sub(t) as f64 * 1e-6);
            w.last = Some((now, servo.theta));
            if w.row.as_ref() != Some(cfg) {
                // A new row (limits, servo, sign, offset): the joint may be outside its new
                // limits, and may only come back.
                w.row = Some(cfg.clone());
                w.outside = outside(q, &cfg.limits) + stopping(qd);
                w.speed = qd.abs();
                continue;
            }
            // Pressed against a mechanical stop (limits set beyond the joint's mechanical
            // range): the stop, not the firmware, decides where the joint is.
            let at_stop = servo
                .stops
                .is_some_and(|(lo, hi)| servo.theta <= lo + 0.02 || servo.theta >= hi - 0.02);
            let controlled = !at_stop
                && cfg.kind != JointKind::Gripper
                && fw.joints().get(j).is_some_and(|c| c.mode != JointMode::Off)
                && fw
                    .bus()
                    .servos
                    .iter()
                    .filter(|s| s.joint as usize == j)
                    .all(|s| {
                        // Under control once its configuration (a mode change: torque off,
                        // mode, goal, torque on) is done: until then the servo is limp.
                        s.status == ferrobot_firmware::bus::ServoStatus::Ok
                            && s.hw_error == 0
                            && s.ops == 0
                    });
            let d = outside(q, &cfg.limits);
            let vmax = cfg.limits.velocity as f64 * (1.0 + SPEED_TOL) + SPEED_ABS;
            let mode = fw.joints().get(j).map(|c| c.mode).unwrap_or(JointMode::Off);
            if (!w.was_controlled || w.mode != mode) && controlled {
                w.grace_until = now + GRACE_US;
            }
            w.was_controlled = controlled;
            w.mode = mode;
            if !controlled || now < w.grace_until {
                // A limp joint goes where gravity takes it; once under control it must come
                // back from there, and slow down from that speed.
                w.outside = w.outside.max(d + stopping(qd));
                w.speed = w.speed.max(qd.abs());
                continue;
            }
            let (dp, dv) = (
                d - w.outside,
                qd.abs() - (cfg.limits.velocity as f64).max(w.speed),
            );
            let here = || {
                format!(
                    "{what}: t={} us joint {j} ({:?}) at {q:.4} rad, {qd:.3} rad/s, {:?}",
                    sim.now_us(),
                    fw.joints()[j].mode,
                    cfg.limits
                )
            };
            if dp > self.worst.0 {
                self.worst.0 = dp;
                self.worst_at.0 = here();
            }
            if dv > self.worst.1 {
                self.worst.1 = dv;
                self.worst_at.1 = here();
            }
            let servo_state = || {
                format!(
                    "{:?}; servo torque {}, error {}, mode {}",
                    fw.joints()[j].mode,
                    servo.torque_enabled(),
                    servo.hardware_error(),
                    servo.get(dxl::addr::OPERATING_MODE, 1)
                )
            };
            if d > w.outside + POS_TOL {
                self.violations.push(format!(
                    "{what}: t={} us joint {j} ({}) at {q:.4} rad, {d:.4} rad outside {:?}",
                    sim.now_us(),
                    servo_state(),
                    cfg.limits
                ));
            }
            if qd.abs() > vmax.max(w.speed + SPEED_ABS) {
                self.violations.push(format!(
                    "{what}: t={} us joint {j} ({}) at {q:.4} rad, {qd:.3} rad/s, limits {:?}",
                    sim.now_us(),
                    servo_state(),
                    cfg.limits
                ));
            }
            w.outside = w.outside.min(d + stopping(qd));
            // A joint found too fast slows down at most at the braking rate: the allowed speed
            // falls at that rate (never below what it is now).
            w.speed = w.speed.min((w.speed - BRAKING * dt).max(qd.abs()));
        }
        // Every servo the firmware believes configured runs the mode and torque it asked for.
        for b in fw.bus().servos.iter() {
            let settled = b.status == ferrobot_firmware::bus::ServoStatus::Ok && b.ops == 0;
            if let (true, Some(sv)) = (settled, sim.hw.chain.servo(b.id)) {
                let mode = sv.get(dxl::addr::OPERATING_MODE, 1) as u8;
                if mode != b.mode || (b.torque && !sv.torque_enabled() && sv.hardware_error() == 0)
                {
                    self.violations.push(format!(
                        "{what}: t={} us servo {} runs mode {mode} (torque {}), the firmware asked mode {} (torque {})",
                        sim.now_us(),
                        b.id,
                        sv.torque_enabled(),
                        b.mode,
                        b.torque
                    ));
                }
            }
        }
        if let Some(base) = sim.hw.base.as_ref() {
            let top = fw.profile().base.max_wheel_speed as f64 * (1.0 + WHEEL_TOL);
            let (l, r) = base.drive.speed;
            if l.abs() > top || r.abs() > top {
                self.violations.push(format!(
                    "{what}: t={} us wheels at ({l:.3}, {r:.3}) m/s, top {top:.3}",
                    sim.now_us()
                ));
            }
        }
    }
}

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
    run(&mut s, &mut c, 1_500_000, "configuration");
    for k in 0..messages {
        let msg = message(rng, &s.sim.fw);
        let what = format!("after message {k} {msg:?}");
        s.send(&msg);
        let gap = match rng.random_range(0..20) {
            0 => rng.random_range(100_000..600_000),
            1..=4 => rng.random_range(10_000..50_000),
            _ => rng.random_range(0..5_000),
        };
        run(&mut s, &mut c, gap, &what);
        s.inbox.clear();
    }
    // The end: an emergency stop in whatever state the stream left.
    let seq = s.send(&HostMsg::EmergencyStop);
    let stop_at = s.sim.now_us();
    run(&mut s, &mut c, 1000, "emergency stop");
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
            run(&mut s, &mut c, 1000, "emergency stop");
        }
        assert_eq!(
            s.sim.hw.wheel_command(),
            (0.0, 0.0),
            "{robot}: base still commanded"
        );
    }
    run(&mut s, &mut c, 800_000, "after the emergency stop");
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
    run(&mut s, &mut c, 600_000, "recovery");
    s.command(&HostMsg::Waypoint {
        joints: 0b1,
        duration_us: 1_000_000,
        points: [JointPoint::at_rest(0.4)].into_iter().collect(),
    })
    .expect("waypoint accepted");
    run(&mut s, &mut c, 2_500_000, "recovery waypoint");
    let cfg = &s.sim.fw.profile().joints[0];
    let q = cfg.sign as f64
        * (s.sim.hw.chain.servo(cfg.servo_id).expect("servo").theta - cfg.offset as f64);
    assert!(
        (q - 0.4).abs() < 0.02,
        "{robot}: joint 0 at {q} after the recovery waypoint"
    );
    let t = s.sim.now_us();
    (c, t)
}
