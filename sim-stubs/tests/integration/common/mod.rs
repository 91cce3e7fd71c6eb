//! Helpers shared by the lockstep acceptance tests.

use ferrobot_protocol::dxl::units;
use ferrobot_protocol::*;
use ferrobot_sim::HostSide;
use ferrobot_sim::SimHost;

/// Arm joints of the LoCoBot profile (joint_1 … joint_5).
pub const ARM: u16 = 0b1_1111;

/// A session on `robot` with the arm's gravity model sent, as a host sends it; the session's
/// keepalive feeds the watchdog, as a host's I/O thread would.
pub fn session(robot: &str) -> SimHost {
    session_with(robot, 7, 1.0)
}

/// [`session`] with plant seed `seed` and the arm's masses `scale` times the description's.
pub fn session_with(robot: &str, seed: u64, scale: f64) -> SimHost {
    start(robot, seed, scale, true)
}

/// [`session`] with no gravity model sent.
pub fn session_without_model(robot: &str) -> SimHost {
    start(robot, 7, 1.0, false)
}

fn start(robot: &str, seed: u64, scale: f64, with_model: bool) -> SimHost {
    let mut s = SimHost::start(robot, seed).expect("simulator starts");
    s.sim.hw.chain.scale_arm_masses(|_| scale);
    s.command(&HostMsg::SetTelemetry { period_ms: 10 })
        .expect("telemetry at 100 Hz");
    let mut model = ferrobot_sim::robots::arm_model(robot);
    if !with_model {
        model.clear();
    }
    for (index, &link) in (0u8..).zip(&model) {
        let count = model.len() as u8;
        s.command(&HostMsg::ArmLink { index, count, link })
            .expect("the arm's gravity model");
    }
    // Let the servos be configured and measured.
    s.wait_telemetry(1_000_000, |t| t.faults & fault_flags::CONFIGURING == 0)
        .expect("servos configured");
    // The arm, held still, bears the model out (ModelConfirmed) once it carries a load.
    s.run_for(400_000);
    s
}

/// Points for the selected joints.
pub fn points(q: &[f32]) -> heapless::Vec<JointPoint, MAX_JOINTS> {
    q.iter().map(|&p| JointPoint::at_rest(p)).collect()
}

/// A waypoint to rest at `q` (rad, one per set bit of `joints`, lowest first) reached
/// `duration_us` after the previous knot.
pub fn waypoint(joints: u16, duration_us: u32, q: &[f32]) -> HostMsg {
    HostMsg::Waypoint {
        joints,
        duration_us,
        points: points(q),
    }
}

/// Joint angles (rad) of the arm as the simulated servos really are (ground truth, not
/// the firmware's reading): servo angle through the joint's sign.
pub fn true_arm(s: &SimHost) -> Vec<f32> {
    let chain = &s.sim.hw.chain;
    let profile = s.sim.fw.profile();
    profile.joints[..5]
        .iter()
        .map(|j| {
            let servo = chain.servo(j.servo_id).expect("servo exists");
            (j.sign as f64 * (servo.theta - j.offset as f64)) as f32
        })
        .collect()
}

/// Measured arm angles from the newest telemetry.
pub fn measured_arm(s: &SimHost) -> Vec<f32> {
    s.telemetry.as_ref().expect("telemetry").joints[..5]
        .iter()
        .map(|j| j.position)
        .collect()
}

/// Largest absolute difference.
pub fn max_err(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// Gripper servo position, ticks.
pub fn gripper_ticks(s: &SimHost) -> i32 {
    units::rad_to_tick(s.sim.hw.chain.servo(7).expect("gripper").theta as f32)
}
