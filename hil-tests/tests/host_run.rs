//! End to end on the host-run firmware (a stock robot's firmware core on this computer) with
//! its devices emulated: the simulated plants behind pseudo-terminals at the stock robot's
//! rates (the Dynamixel bus at 1 Mbit/s, the base at 115200), granting the firmware its time
//! over a virtual-time link, and the host over the serial backend. The same `Robot` program
//! as on the simulator; then the faults of real cables, each ending in a safe state with a
//! typed error, and the robot moving again once the fault clears. Times to a safe state are
//! the plants' (simulated) time, so they do not depend on the machine's load; each test
//! prints its figure (`docs/real-robots.md`, "Faults of real wires").

use std::sync::Arc;
use std::time::{Duration, Instant};

use ferrobot::arm::MoveOptions;
use ferrobot::backend::emulated::EmulatedBoard;
use ferrobot::{Backend, Error, Robot};
use ferrobot_protocol::FaultKind;

/// Where the firmware runs: on this computer (the host-run firmware of a stock robot), or
/// the board's ELF in QEMU. Both drive the same plants behind the same pseudo-terminals.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Firmware {
    HostRun,
    Qemu,
}

/// One QEMU at a time: each paces its clock to the wall clock, and two would share the cores.
static QEMU: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A LoCoBot's firmware on emulated devices, the host connected over the serial backend, and
/// the plants to inject faults into.
struct Rig {
    bot: Robot,
    board: Watched,
    firmware: Firmware,
    _qemu: Option<std::sync::MutexGuard<'static, ()>>,
}

/// The rig's board; a failing test prints what it saw when it drops: the plants' counters and
/// last frames on each link, and whether the firmware stopped.
struct Watched(EmulatedBoard);

impl std::ops::Deref for Watched {
    type Target = EmulatedBoard;
    fn deref(&self) -> &EmulatedBoard {
        &self.0
    }
}

impl Drop for Watched {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("{}", self.0.server.report());
            if let Some(why) = self.0.qemu_exited() {
                eprintln!("the firmware stopped: {why}");
            }
        }
    }
}

impl Rig {
    fn on(firmware: Firmware, name: &str) -> Rig {
        let scene = Arc::new(ferrobot_sim::scene::Scene::empty());
        let (board, guard) = match firmware {
            Firmware::HostRun => {
                let cfg = ferrobot::profile::bundled(name).expect("description");
                (EmulatedBoard::start_host_run(&cfg, scene), None)
            }
            Firmware::Qemu => {
                let guard = QEMU.lock().unwrap_or_else(|e| e.into_inner());
                let elf = ferrobot_hil::firmware_elf().expect("the QEMU board's firmware");
                let log = std::env::temp_dir().join(format!(
                    "ferrobot-host-run-qemu-{}-{:?}.defmt",
                    std::process::id(),
                    std::thread::current().id()
                ));
                let opts = ferrobot_sim::board::BoardOptions {
                    seed: ferrobot_hil::SEED,
                    ..Default::default()
                };
                (
                    EmulatedBoard::start_in(name, &elf, opts, log, scene),
                    Some(guard),
                )
            }
        };
        let board = board.unwrap_or_else(|e| panic!("{firmware:?} on emulated devices: {e}"));
        let bot = Robot::builder(name)
            .backend(Backend::Serial {
                path: board.server.host.clone(),
            })
            .board_clock(board.server.clock())
            .build()
            .unwrap_or_else(|e| panic!("connect: {e}"));
        Rig {
            bot,
            board: Watched(board),
            firmware,
            _qemu: guard,
        }
    }

    /// Pull the servo bus's cable (`false`) or plug it again. The host-run firmware's USB
    /// device vanishes (its reads fail with EIO) and comes back under another name; a board's
    /// wire to its servos is cut: nothing answers.
    fn servo_cable(&self, plugged: bool) {
        match self.firmware {
            Firmware::HostRun => self.board.server.rewire(|w| w.plugged[0] = plugged),
            Firmware::Qemu => self.silence_all(!plugged),
        }
    }

    /// Every servo silent (or answering again).
    fn silence_all(&self, silent: bool) {
        let on = if silent { "on" } else { "off" };
        for id in 1..=9 {
            assert_eq!(
                self.board.server.command(&format!("silent {id} {on}"))["ok"],
                true
            );
        }
    }

    /// The plants' (simulated) time.
    fn now(&self) -> Duration {
        Duration::from_micros(self.board.server.now_us())
    }

    /// Wait until `pred` holds, at most `within` of simulated time (and a generous wall-clock
    /// bound for a machine that stopped); the simulated time it took.
    fn until(&self, within: Duration, what: &str, mut pred: impl FnMut(&Rig) -> bool) -> Duration {
        let (t0, wall) = (self.now(), Instant::now());
        loop {
            if pred(self) {
                return self.now() - t0;
            }
            let waited = self.now() - t0;
            assert!(
                waited < within && wall.elapsed() < Duration::from_secs(120),
                "{what}: not within {within:?} of simulated time"
            );
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// The plants' arm joint angles.
    fn arm_truth(&self) -> Vec<f64> {
        self.board
            .server
            .with_hardware(|hw, _| hw.chain.arm_angles())
    }

    /// The base's commanded wheel speeds in the plant, m/s.
    fn wheels(&self) -> (f64, f64) {
        self.board.server.with_hardware(|hw, _| hw.wheel_command())
    }

    fn faults(&self) -> Vec<FaultKind> {
        self.bot.take_faults().iter().map(|f| f.kind).collect()
    }
}

/// Whether `e` is the fault of a servo the firmware lost.
fn servo_lost(e: &Error) -> bool {
    matches!(
        e,
        Error::Fault {
            kind: FaultKind::ServoLost,
            ..
        }
    )
}

fn direct() -> MoveOptions {
    MoveOptions {
        plan: false,
        ..MoveOptions::default()
    }
}

/// The robot `name` on `Backend::DirectEmulated` (the one call a program makes): its arm to a
/// joint target and its base 0.3 m ahead.
fn moves_its_arm_and_base(name: &str) {
    let bot = Robot::builder(name)
        .backend(Backend::DirectEmulated)
        .build()
        .unwrap_or_else(|e| panic!("the host-run firmware on emulated devices: {e}"));
    let arm = bot.arm().expect("arm");
    let target = [0.4, 0.3, -0.5, 0.6, -0.3];
    arm.set_joint_positions(&target).expect("joint motion");
    let got = arm.get_joint_angles().expect("angles");
    for (g, t) in got.iter().zip(target) {
        assert!((g - t).abs() < 0.02, "{got:?} vs {target:?}");
    }
    let base = bot.base().expect("base");
    base.go_to_relative([0.3, 0.0, 0.0]).expect("base motion");
    let s = base.get_state().expect("odometry");
    assert!((s[0] - 0.3).abs() < 0.03, "odometry {s:?}");
}

#[test]
fn the_locobot_moves_its_arm_and_base_on_the_host_run_firmware() {
    moves_its_arm_and_base("locobot");
}

#[test]
fn the_locobot_lite_moves_its_arm_and_its_create_2_on_the_host_run_firmware() {
    moves_its_arm_and_base("locobot_lite");
}

fn the_servo_bus_cable_pulled_mid_motion_stops_the_arm_and_it_moves_again_when_plugged(
    fw: Firmware,
) {
    let rig = Rig::on(fw, "locobot");
    let arm = rig.bot.arm().expect("arm");
    let start = rig.arm_truth();
    let motion = arm
        .move_joints(&[0.6, 0.3, -0.4, 0.5, 0.2], direct())
        .expect("motion");
    rig.until(Duration::from_secs(2), "the arm moving", |r| {
        r.arm_truth()[0] > 0.1
    });
    rig.servo_cable(false);
    let pulled = rig.now();
    let err = motion
        .wait()
        .expect_err("the motion cannot finish without its servos");
    let to_safe = rig.now() - pulled;
    assert!(servo_lost(&err), "{err}");
    // The servos hold their last goals, which lie on the motion's path: the arm comes to rest
    // on it, short of the target, and stays there.
    let (start, target) = (start, [0.6, 0.3, -0.4, 0.5, 0.2]);
    rig.until(Duration::from_secs(2), "a second", |r| {
        r.now() - pulled > Duration::from_millis(1000)
    });
    let rest = rig.arm_truth();
    rig.until(Duration::from_secs(2), "another half second", |r| {
        r.now() - pulled > Duration::from_millis(1500)
    });
    let later = rig.arm_truth();
    for j in 0..5 {
        let (lo, hi) = (start[j].min(target[j]), start[j].max(target[j]));
        assert!(
            later[j] > lo - 0.02 && later[j] < hi + 0.02 && (later[j] - rest[j]).abs() < 0.005,
            "joint {j} left the path or kept moving with its bus out: {start:?} -> {rest:?} -> \
             {later:?}"
        );
    }
    assert!(
        arm.set_joint_positions(&[0.0; 5]).is_err(),
        "a motion without servos"
    );
    eprintln!("servo bus cable pulled: ServoLost after {to_safe:?} of simulated time");
    // Plugged again, under another PTY name behind the same link: recovered, moves again.
    rig.servo_cable(true);
    let back = rig.until(Duration::from_secs(5), "ServoRecovered", |r| {
        r.faults().contains(&FaultKind::ServoRecovered)
    });
    eprintln!("servo bus cable plugged again: recovered after {back:?}");
    rig.until(Duration::from_secs(3), "every servo back", |_| {
        arm.set_joint_positions(&[0.2, 0.0, 0.0, 0.0, 0.0]).is_ok()
    });
    assert!(
        (rig.arm_truth()[0] - 0.2).abs() < 0.02,
        "{:?}",
        rig.arm_truth()
    );
}

fn a_base_that_stops_answering_is_stopped_and_drives_again_when_it_answers(fw: Firmware) {
    let rig = Rig::on(fw, "locobot");
    let base = rig.bot.base().expect("base");
    let mut motion = base.set_vel_async(0.2, 0.0, 5.0).expect("drive");
    // Polling lets the robot's time pass and steps the drive.
    rig.until(Duration::from_secs(2), "driving", |r| {
        let _ = motion.poll();
        r.wheels().0 > 0.1
    });
    rig.board
        .server
        .with_hardware(|hw, _| hw.base.as_mut().expect("base").mute = true);
    // The firmware stops the base by itself: nothing on the host steps the drive meanwhile.
    let to_stop = rig.until(Duration::from_secs(1), "wheels commanded to zero", |r| {
        r.wheels() == (0.0, 0.0)
    });
    let err = motion
        .wait()
        .expect_err("a drive on a base that says nothing");
    assert!(
        matches!(
            err,
            Error::Fault {
                kind: FaultKind::BaseLost,
                ..
            }
        ),
        "{err}"
    );
    eprintln!("base stops answering: wheels stopped after {to_stop:?}");
    rig.board
        .server
        .with_hardware(|hw, _| hw.base.as_mut().expect("base").mute = false);
    rig.until(Duration::from_secs(2), "BaseRecovered", |r| {
        r.faults().contains(&FaultKind::BaseRecovered)
    });
    base.go_to_relative([0.2, 0.0, 0.0]).expect("drives again");
}

fn a_servo_that_stops_answering_is_lost_and_recovered(fw: Firmware) {
    let rig = Rig::on(fw, "locobot");
    let arm = rig.bot.arm().expect("arm");
    let motion = arm
        .move_joints(&[0.3, 0.3, 0.3, 0.3, 0.3], direct())
        .expect("motion");
    rig.until(Duration::from_secs(2), "moving", |r| {
        r.arm_truth()[2] > 0.05
    });
    assert_eq!(rig.board.server.command("silent 4 on")["ok"], true);
    let silent = rig.now();
    let err = motion.wait().expect_err("joint_3 without its servo");
    let to_safe = rig.now() - silent;
    assert!(servo_lost(&err), "{err}");
    eprintln!("a servo stops answering: ServoLost after {to_safe:?}");
    assert_eq!(rig.board.server.command("silent 4 off")["ok"], true);
    rig.until(Duration::from_secs(2), "ServoRecovered", |r| {
        r.faults().contains(&FaultKind::ServoRecovered)
    });
    arm.set_joint_positions(&[0.0, 0.0, 0.5, 0.0, 0.0])
        .expect("moves again");
    assert!((rig.arm_truth()[2] - 0.5).abs() < 0.02);
}

fn a_servo_power_cycled_is_configured_again_and_holds(fw: Firmware) {
    let rig = Rig::on(fw, "locobot");
    let arm = rig.bot.arm().expect("arm");
    arm.set_joint_positions(&[0.0, 0.0, 0.6, 0.0, 0.0])
        .expect("pose");
    // Power off for 300 ms (no answer), then back with torque off and its RAM reset.
    assert_eq!(rig.board.server.command("silent 4 on")["ok"], true);
    let off = rig.now();
    rig.until(Duration::from_secs(1), "the servo's boot", |r| {
        r.now() - off > Duration::from_millis(300)
    });
    rig.board.server.with_hardware(|hw, _| {
        let s = hw.chain.servo_mut(4).expect("servo 4");
        s.reboot();
        s.silent = false;
    });
    let back = rig.until(Duration::from_secs(2), "ServoRecovered", |r| {
        r.faults().contains(&FaultKind::ServoRecovered)
    });
    let torque = rig.until(Duration::from_secs(1), "its torque on again", |r| {
        r.board.server.command("servo 4")["torque_enabled"] == true
    });
    // It sagged while its torque was off and may still be falling when its torque returns; it
    // is held where it then stands (not driven back to where it stood), and comes to rest. A
    // plan is made from a joint at rest: one made while it still moved started 0.07 rad from
    // it in a CI run (StalePlan).
    let sagged = rig.arm_truth()[2];
    let on = rig.now();
    let mut window: std::collections::VecDeque<(Duration, f64)> = Default::default();
    let still = rig.until(Duration::from_secs(2), "joint_3 at rest", |r| {
        let t = r.now() - on;
        window.push_back((t, r.arm_truth()[2]));
        while window
            .front()
            .is_some_and(|(t0, _)| t - *t0 > Duration::from_millis(100))
        {
            window.pop_front();
        }
        let (lo, hi) = window
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), (_, q)| {
                (lo.min(*q), hi.max(*q))
            });
        t > Duration::from_millis(100) && hi - lo < 0.002
    });
    eprintln!(
        "a servo power-cycled: taken back {back:?} after it answered, its torque on {torque:?} \
         later at {sagged:.3} rad, at rest {still:?} later at {:.3} rad",
        rig.arm_truth()[2]
    );
    arm.set_joint_positions(&[0.0, 0.0, 0.3, 0.0, 0.0])
        .expect("moves again");
    assert!(
        (rig.arm_truth()[2] - 0.3).abs() < 0.02,
        "{:?}",
        rig.arm_truth()
    );
}

/// A joint motion with `fraction` of the servo bus's bytes damaged both ways: it arrives or
/// fails with a typed error, and no joint ever leaves the span between start and target.
fn corrupted_bus(fw: Firmware, fraction: f64) {
    let rig = Rig::on(fw, "locobot");
    let arm = rig.bot.arm().expect("arm");
    let start = rig.arm_truth();
    let target = [0.5, 0.3, -0.3, 0.4, 0.3];
    rig.board.server.rewire(|w| w.corruption[0] = fraction);
    let opts = MoveOptions {
        timeout: Some(Duration::from_secs(6)),
        ..direct()
    };
    let mut motion = arm.move_joints(&target, opts).expect("motion");
    let mut worst: f64 = 0.0;
    rig.until(Duration::from_secs(10), "the motion's end", |r| {
        for (j, q) in r.arm_truth().iter().enumerate() {
            let (lo, hi) = (start[j].min(target[j]), start[j].max(target[j]));
            worst = worst.max(lo - q).max(q - hi);
        }
        // Polling lets the robot's time pass and steps the motion.
        motion.poll().is_some()
    });
    let outcome = motion.wait();
    let d = rig.bot.diagnostics().expect("diagnostics");
    eprintln!(
        "{:.0} % of servo bus bytes damaged: {outcome:?}, worst excursion {worst:.4} rad, \
         {} bad packets, {} timeouts",
        fraction * 100.0,
        d.servo_bad_packets,
        d.servo_timeouts
    );
    assert!(
        d.servo_bad_packets + d.servo_timeouts > 0,
        "no damage seen: {d:?}"
    );
    assert!(worst < 0.02, "a joint left its path by {worst} rad");
    if let Err(e) = outcome {
        assert!(
            matches!(e, Error::Fault { .. } | Error::Timeout { .. }),
            "{e}"
        );
    }
    rig.board.server.rewire(|w| w.corruption[0] = 0.0);
    rig.until(Duration::from_secs(3), "moving again", |_| {
        arm.set_joint_positions(&[0.0; 5]).is_ok()
    });
}

fn one_percent_of_the_servo_bus_damaged_executes_nothing_wrong(fw: Firmware) {
    corrupted_bus(fw, 0.01);
}

fn five_percent_of_the_servo_bus_damaged_executes_nothing_wrong(fw: Firmware) {
    corrupted_bus(fw, 0.05);
}

fn a_latency_spike_of_100_ms_stops_the_arm_safely_and_it_moves_again(fw: Firmware) {
    let rig = Rig::on(fw, "locobot");
    let arm = rig.bot.arm().expect("arm");
    let motion = arm
        .move_joints(&[0.5, 0.0, 0.0, 0.0, 0.0], direct())
        .expect("motion");
    rig.until(Duration::from_secs(2), "moving", |r| r.arm_truth()[0] > 0.1);
    // The USB adapter delivers nothing for 100 ms: no servo's reply reaches the firmware in
    // that time (under a virtual clock a late byte is a lost one: the firmware has given up on
    // it by then).
    rig.silence_all(true);
    let t0 = rig.now();
    rig.until(Duration::from_secs(1), "100 ms", |r| {
        r.now() - t0 >= Duration::from_millis(100)
    });
    rig.silence_all(false);
    let outcome = motion.wait();
    eprintln!("a 100 ms latency spike on the servo bus: {outcome:?}");
    if let Err(e) = &outcome {
        assert!(servo_lost(e), "{e}");
    }
    rig.until(Duration::from_secs(3), "moving again", |_| {
        arm.set_joint_positions(&[0.0; 5]).is_ok()
    });
    assert!(rig.arm_truth()[0].abs() < 0.02);
}

/// The host program killed mid-motion (its port closed with the base driving and the arm
/// holding a pose): the firmware's watchdog stops the base on its own, the arm holds, and a
/// watchdog fault waits for the next host.
fn a_host_killed_mid_motion_leaves_the_base_stopped_and_the_arm_holding(fw: Firmware) {
    use ferrobot_protocol::HostMsg;
    let rig = Rig::on(fw, "locobot");
    rig.bot
        .arm()
        .expect("arm")
        .set_joint_positions(&[0.3, 0.2, 0.2, 0.2, 0.0])
        .expect("pose");
    drop(rig.bot);
    let mut raw = ferrobot_hil::RawClient::open(&rig.board.server.host).expect("the port");
    rig_until(&rig.board, Duration::from_secs(3), "the handshake", || {
        raw.hello(Duration::from_millis(300)).is_some()
    });
    let drive = HostMsg::BaseVelocity {
        v: 0.2,
        w: 0.0,
        duration_ms: 10_000,
    };
    assert_eq!(raw.command(&drive), Some(true));
    let wheels = |b: &EmulatedBoard| b.server.with_hardware(|hw, _| hw.wheel_command());
    rig_until(&rig.board, Duration::from_secs(2), "driving", || {
        wheels(&rig.board).0 > 0.1
    });
    let arm = rig
        .board
        .server
        .with_hardware(|hw, _| hw.chain.arm_angles());
    // Killed: the port closes, nothing more comes.
    drop(raw);
    let killed = rig.board.server.now_us();
    rig_until(
        &rig.board,
        Duration::from_secs(2),
        "the watchdog's stop",
        || wheels(&rig.board) == (0.0, 0.0),
    );
    let to_stop = Duration::from_micros(rig.board.server.now_us() - killed);
    let still = rig
        .board
        .server
        .with_hardware(|hw, _| hw.chain.arm_angles());
    for (a, b) in arm.iter().zip(&still) {
        assert!((a - b).abs() < 0.01, "the arm moved: {arm:?} -> {still:?}");
    }
    assert!(
        to_stop <= Duration::from_millis(600),
        "stopped after {to_stop:?}"
    );
    eprintln!("host killed mid-motion ({fw:?}): base stopped after {to_stop:?}, arm held");
}

/// [`Rig::until`] on a board alone (the robot handle gone).
fn rig_until(board: &EmulatedBoard, within: Duration, what: &str, mut pred: impl FnMut() -> bool) {
    let (t0, wall) = (board.server.now_us(), Instant::now());
    while !pred() {
        let waited = Duration::from_micros(board.server.now_us() - t0);
        assert!(
            waited < within && wall.elapsed() < Duration::from_secs(120),
            "{what}: not within {within:?} of simulated time"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Each fault on each firmware that runs behind a serial port: `host_run::…` and `qemu::…`.
macro_rules! on_both {
    ($($name:ident),* $(,)?) => {
        mod host_run {
            $(#[test]
            fn $name() {
                super::$name(super::Firmware::HostRun)
            })*
        }
        mod qemu {
            $(#[test]
            fn $name() {
                super::$name(super::Firmware::Qemu)
            })*
        }
    };
}

on_both!(
    the_servo_bus_cable_pulled_mid_motion_stops_the_arm_and_it_moves_again_when_plugged,
    a_base_that_stops_answering_is_stopped_and_drives_again_when_it_answers,
    a_servo_that_stops_answering_is_lost_and_recovered,
    a_servo_power_cycled_is_configured_again_and_holds,
    one_percent_of_the_servo_bus_damaged_executes_nothing_wrong,
    five_percent_of_the_servo_bus_damaged_executes_nothing_wrong,
    a_latency_spike_of_100_ms_stops_the_arm_safely_and_it_moves_again,
    a_host_killed_mid_motion_leaves_the_base_stopped_and_the_arm_holding,
);
