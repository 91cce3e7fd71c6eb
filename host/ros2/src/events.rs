//! The robot's events as ROS 2 messages: commands on `/cmd_vel`, `/joint_commands` and
//! `/gripper/command`; everything else (faults, emergency stops, mode changes, link events) as
//! `/rosout` log lines; SLAM's poses on `/slam/pose`; the arm's plans on `/arm/planned_path`.

use std::time::Duration;

use ferrobot::events::{Event, GripperCommand, HostMsg, JointMode};
use ferrobot::fault_flags;

use crate::encode::{self, level, Knot};
use crate::robot::RobotInfo;
use crate::topics::{self, Topic};

/// The logger name of the API's own lines on `/rosout`.
const LOGGER: &str = "ferrobot";

/// The names of the joints a mask selects, lowest bit first.
fn selected(robot: &RobotInfo, mask: u16) -> Vec<String> {
    robot
        .joints
        .iter()
        .enumerate()
        .filter(|(i, _)| *i < 16 && mask & (1 << i) != 0)
        .map(|(_, n)| n.clone())
        .collect()
}

/// The messages of event `e`: each with its topic.
pub fn encode(robot: &RobotInfo, e: &Event) -> Vec<(Topic, Vec<u8>)> {
    let t = e.time();
    let log = |lvl: u8, msg: &str| (topics::ROSOUT, encode::log(t, lvl, LOGGER, msg));
    match e {
        Event::Command { msg, .. } => {
            let exact = postcard::to_allocvec(msg).unwrap_or_default();
            let mut out = vec![(topics::COMMANDS, encode::command(msg.kind(), &exact))];
            out.extend(command(robot, t, msg));
            out
        }
        Event::Fault { fault, .. } => {
            let joint = fault
                .joint
                .map_or(String::new(), |j| format!(" on joint {j}"));
            let text = format!(
                "fault {:?}{joint} (code {}, firmware time {} us)",
                fault.kind, fault.code, fault.time_us
            );
            vec![log(level::ERROR, &text)]
        }
        Event::Link { event, .. } => vec![log(level::WARN, &format!("link: {event:?}"))],
        Event::Slam { report, .. } => {
            let mut out = vec![(
                topics::SLAM_POSE,
                encode::pose_stamped(t, topics::MAP_FRAME, &report.pose),
            )];
            if report.loop_closed {
                out.push(log(level::INFO, "SLAM closed a loop"));
            }
            out
        }
        Event::ArmPlan { plan, .. } => {
            vec![(topics::ARM_PLANNED_PATH, crate::view::planned_path(t, plan))]
        }
        _ => vec![log(level::INFO, &format!("{e:?}"))],
    }
}

/// The message of a command, if it is one that is recorded (heartbeats, telemetry and
/// configuration are not).
fn command(robot: &RobotInfo, t: Duration, msg: &HostMsg) -> Option<(Topic, Vec<u8>)> {
    let log = |lvl: u8, text: &str| Some((topics::ROSOUT, encode::log(t, lvl, LOGGER, text)));
    match msg {
        HostMsg::BaseVelocity { v, w, .. } => {
            Some((topics::CMD_VEL, encode::twist(f64::from(*v), f64::from(*w))))
        }
        HostMsg::Waypoint {
            joints,
            duration_us,
            points,
        } => {
            let knot = Knot {
                positions: points.iter().map(|p| f64::from(p.position)).collect(),
                velocities: points.iter().map(|p| f64::from(p.velocity)).collect(),
                effort: points.iter().map(|p| f64::from(p.effort)).collect(),
                time_from_start: Duration::from_micros(u64::from(*duration_us)),
            };
            let names = selected(robot, *joints);
            Some((
                topics::JOINT_COMMANDS,
                encode::joint_trajectory(t, &names, &[knot]),
            ))
        }
        HostMsg::JointCommand { joints, values } => {
            // Velocity (rad/s) in velocity mode, effort (N·m, or a PWM fraction) otherwise;
            // the mode is on /rosout where it changed. Both fields carry the values.
            let v: Vec<f64> = values.iter().map(|&x| f64::from(x)).collect();
            let knot = Knot {
                positions: Vec::new(),
                velocities: v.clone(),
                effort: v,
                time_from_start: Duration::ZERO,
            };
            let names = selected(robot, *joints);
            Some((
                topics::JOINT_COMMANDS,
                encode::joint_trajectory(t, &names, &[knot]),
            ))
        }
        HostMsg::Gripper(g) => {
            let what = match g {
                GripperCommand::Open => "open",
                GripperCommand::Close => "close",
                _ => "stop",
            };
            Some((topics::GRIPPER_COMMAND, encode::string(what)))
        }
        HostMsg::SetMode { joints, mode } => {
            let names = selected(robot, *joints).join(", ");
            let mode = match mode {
                JointMode::Off => "off",
                JointMode::Position => "position",
                JointMode::Velocity => "velocity",
                JointMode::Current => "current",
                JointMode::Pwm => "pwm",
                JointMode::Teach => "teach",
                _ => "other",
            };
            log(level::INFO, &format!("mode {mode}: {names}"))
        }
        HostMsg::EmergencyStop => log(level::ERROR, "emergency stop"),
        HostMsg::Resume => log(level::INFO, "resume"),
        HostMsg::ResetOdometry => log(level::INFO, "odometry reset"),
        HostMsg::ClearQueue { joints } => log(
            level::INFO,
            &format!("queue cleared: {}", selected(robot, *joints).join(", ")),
        ),
        _ => None,
    }
}

/// The firmware's fault flags as a log line, when they change from `old` to `new`.
pub fn fault_flags(old: u16, new: u16) -> String {
    const NAMES: [(u16, &str); 9] = [
        (fault_flags::ESTOP, "emergency stop"),
        (fault_flags::WATCHDOG, "watchdog"),
        (fault_flags::SERVO_LOST, "servo lost"),
        (fault_flags::SERVO_HARDWARE, "servo hardware error"),
        (fault_flags::BASE_LOST, "base lost"),
        (fault_flags::BASE_SAFETY, "base safety sensor"),
        (fault_flags::OVERRUN, "loop overrun"),
        (fault_flags::CONFIGURING, "configuring"),
        (fault_flags::ARM_MODEL, "arm gravity model trusted"),
    ];
    let list = |bits: u16| -> String {
        let v: Vec<&str> = NAMES
            .iter()
            .filter(|(b, _)| bits & b != 0)
            .map(|(_, n)| *n)
            .collect();
        if v.is_empty() {
            "none".into()
        } else {
            v.join(", ")
        }
    };
    format!(
        "fault flags now: {} (raised: {}; cleared: {})",
        list(new),
        list(new & !old),
        list(old & !new)
    )
}
