//! The simulated demo (`ferrobot demo`): handshake, move the arm, work the gripper, drive the
//! base, all through the protocol and the firmware core, in lockstep.

use crate::lockstep::HostSide;
use ferrobot_protocol::HostMsg;

use super::{LockstepSim, SimError, SimHost};

/// The simulated demo: handshake, move the arm, work the gripper, drive the base, all
/// through the protocol and the firmware core; prints what happened and the simulation speed.
pub fn demo(robot: &str, seed: u64, out: &mut dyn std::io::Write) -> Result<(), SimError> {
    let wall = std::time::Instant::now();
    let mut s = SimHost::new(LockstepSim::new(robot, seed)?);
    let info = s.handshake()?;
    let w = |out: &mut dyn std::io::Write, line: String| {
        let _ = writeln!(out, "{line}");
    };
    w(
        out,
        format!(
            "Ferrobot demo: simulated {} (firmware core {}.{}.{} on board {:?}, {} joints, base {:?}, servo loop {} us, seed {seed})",
            info.robot,
            info.firmware_version[0],
            info.firmware_version[1],
            info.firmware_version[2],
            info.board.as_str(),
            info.joints.len(),
            info.base,
            info.loop_period_us
        ),
    );
    s.command(&HostMsg::SetTelemetry { period_ms: 10 })?;
    s.wait_telemetry(2_000_000, |t| {
        t.faults & ferrobot_protocol::fault_flags::CONFIGURING == 0
    })?;
    demo_arm(&mut s, out)?;
    demo_gripper(&mut s, out)?;
    demo_base(&mut s, out)?;
    let d = s.sim.fw.diagnostics();
    let t = s.telemetry.clone();
    let simulated = s.sim.now_us() as f64 * 1e-6;
    let took = wall.elapsed().as_secs_f64();
    w(
        out,
        format!(
            "bus    {} status packets, {} bad, {} timeouts; worst servo tick {} us",
            d.servo_packets,
            d.servo_bad_packets,
            d.servo_timeouts,
            t.map(|t| t.loop_stats.worst_tick_us).unwrap_or(0)
        ),
    );
    w(
        out,
        format!(
            "simulated {simulated:.1} s in {took:.3} s of wall time: {:.0}x real time",
            simulated / took.max(1e-9)
        ),
    );
    Ok(())
}

/// The demo's arm: a waypoint for the first five joints, reached within 0.01 rad.
fn demo_arm(s: &mut SimHost, out: &mut dyn std::io::Write) -> Result<(), SimError> {
    use ferrobot_protocol::JointPoint;
    let w = |out: &mut dyn std::io::Write, line: String| {
        let _ = writeln!(out, "{line}");
    };
    let target = [0.3f32, 0.5, -0.4, 0.2, 0.1];
    let t0 = s.sim.now_us();
    s.command(&HostMsg::Waypoint {
        joints: 0b1_1111,
        duration_us: 2_000_000,
        points: target.iter().map(|&p| JointPoint::at_rest(p)).collect(),
    })?;
    let t = s.wait_telemetry(5_000_000, |t| {
        t.joints
            .iter()
            .zip(target)
            .all(|(j, q)| (j.position - q).abs() < 0.01)
            && t.queued == 0
    })?;
    let err = t
        .joints
        .iter()
        .zip(target)
        .map(|(j, q)| (j.position - q).abs())
        .fold(0.0, f32::max);
    w(
        out,
        format!(
            "arm    -> {target:?} rad: reached in {:.2} s, largest joint error {:.4} rad",
            (t.time_us - t0) as f64 * 1e-6,
            err
        ),
    );
    Ok(())
}

/// The demo's gripper: closed, then opened.
fn demo_gripper(s: &mut SimHost, out: &mut dyn std::io::Write) -> Result<(), SimError> {
    use ferrobot_protocol::{GripperCommand, GripperState};
    let w = |out: &mut dyn std::io::Write, line: String| {
        let _ = writeln!(out, "{line}");
    };
    for (cmd, want) in [
        (GripperCommand::Close, GripperState::Closed),
        (GripperCommand::Open, GripperState::Open),
    ] {
        let t0 = s.sim.now_us();
        s.command(&HostMsg::Gripper(cmd))?;
        let t = s.wait_telemetry(3_000_000, |t| t.gripper == want)?;
        w(
            out,
            format!(
                "gripper {cmd:?}: {:?} after {:.2} s",
                t.gripper,
                (t.time_us - t0) as f64 * 1e-6
            ),
        );
    }
    Ok(())
}

/// The demo's base, if any: 0.2 m/s for 2 s, ground truth against odometry.
fn demo_base(s: &mut SimHost, out: &mut dyn std::io::Write) -> Result<(), SimError> {
    let w = |out: &mut dyn std::io::Write, line: String| {
        let _ = writeln!(out, "{line}");
    };
    if s.sim.hw.base.is_some() {
        s.command(&HostMsg::ResetOdometry)?;
        let start = s.sim.base_truth().unwrap_or([0.0; 3]);
        s.command(&HostMsg::BaseVelocity {
            v: 0.2,
            w: 0.0,
            duration_ms: 2000,
        })?;
        s.run_for(3_000_000);
        let end = s.sim.base_truth().unwrap_or([0.0; 3]);
        let truth = ((end[0] - start[0]).powi(2) + (end[1] - start[1]).powi(2)).sqrt();
        let o = s.telemetry.clone().map(|t| t.odometry).unwrap_or_default();
        let odom = ((o.x as f64).powi(2) + (o.y as f64).powi(2)).sqrt();
        w(out, format!("base   0.2 m/s for 2 s: travelled {truth:.4} m (ground truth), odometry says {odom:.4} m"));
    }
    Ok(())
}
