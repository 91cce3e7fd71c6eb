//! End to end on the host-run firmware (a stock robot's firmware core on this computer) with
//! its devices emulated: the simulated plants behind pseudo-terminals at the stock robot's
//! rates (the Dynamixel bus at 1 Mbit/s, the base at 115200), granting the firmware its time
//! over a virtual-time link, and the host over the firmware's served link. The same `Robot`
//! program as on the simulator.

use std::time::Instant;

use ferrobot::{Backend, Robot};

fn robot(name: &str) -> Robot {
    Robot::builder(name)
        .backend(Backend::DirectEmulated)
        .build()
        .unwrap_or_else(|e| panic!("the host-run firmware of {name} on emulated devices: {e}"))
}

#[test]
fn the_locobot_moves_its_arm_and_base_on_the_host_run_firmware() {
    let wall = Instant::now();
    let bot = robot("locobot");
    let arm = bot.arm().expect("arm");
    eprintln!("start {:?}", arm.get_joint_angles());
    eprintln!("diag {:?}", bot.diagnostics());
    eprintln!("telemetry {:?}", bot.telemetry());
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
    eprintln!("done in {:?}", wall.elapsed());
}
