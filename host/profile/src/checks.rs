//! [`ProfileChecks`]: a description checked against the wire's ranges
//! (`ferrobot_protocol::ranges`: joint positions, speeds, efforts and gains, base speeds, the
//! loop period, names of at most 16 bytes, at most `MAX_JOINTS` joints), the firmware (the
//! servos its bus drives, what each servo model can give) and the arm's kinematic chain (the
//! URDF's tree, the chain's joints, the numerical IK's joint count), each at its place among
//! the description's own checks.

use std::path::Path;

use ferrobot_description::{
    config_error as cfg_err, in_range as num, ArmConfig, BaseSection, BusSection, Checks, IkKind,
    Joint, JointEntry, JointSection, Result,
};
use ferrobot_geometry::validate;
use ferrobot_protocol::ranges;

use crate::derive::{chain_of, joint_row, nominal_geometry, odometry_geometry};

/// The checks of a robot that is to run, beyond its description's own.
#[derive(Debug, Clone, Copy, Default)]
pub struct ProfileChecks;

impl Checks for ProfileChecks {
    fn urdf(&self, file: &Path, urdf: &urdf_rs::Robot) -> Result<()> {
        // Names, links, axes and origins, then the tree: one root, no cycle, every link on it.
        ferrobot_kinematics::LinkTree::from_urdf(urdf)
            .map_err(|e| cfg_err(file, "urdf", format!("invalid URDF: {e}")))?;
        Ok(())
    }

    fn table(&self, file: &Path, joints: &[JointSection]) -> Result<()> {
        // The firmware's bus drives at most this many servos, twins included; more were
        // dropped without an error (a joint, or a twin's half of its torque, never driven).
        let servos: usize = joints
            .iter()
            .map(|j| 1 + usize::from(j.servo.twin.is_some()))
            .sum();
        if servos > ferrobot_firmware::bus::MAX_SERVOS {
            return Err(cfg_err(
                file,
                "joint",
                format!(
                    "{servos} servos (twins included); the firmware drives at most {}",
                    ferrobot_firmware::bus::MAX_SERVOS
                ),
            ));
        }
        Ok(())
    }

    fn joint(&self, file: &Path, entry: &JointEntry) -> Result<()> {
        joint_numbers(file, entry)?;
        joint_row_fits(file, entry)
    }

    fn joints(&self, file: &Path, joints: &[Joint]) -> Result<()> {
        if joints.len() > ferrobot_protocol::MAX_JOINTS {
            return Err(cfg_err(
                file,
                "joint",
                format!("at most {} joints", ferrobot_protocol::MAX_JOINTS),
            ));
        }
        Ok(())
    }

    fn arm(
        &self,
        file: &Path,
        urdf: &urdf_rs::Robot,
        arm: &ArmConfig,
        joints: &[Joint],
    ) -> Result<()> {
        arm_chain_fits(file, urdf, arm, joints)
    }

    fn base_speeds(&self, file: &Path, b: &BaseSection) -> Result<()> {
        for (k, v, lo, hi) in [
            (
                "base.max_linear",
                b.max_linear,
                1e-3,
                ranges::BASE_SPEED_MAX as f64,
            ),
            (
                "base.max_angular",
                b.max_angular,
                1e-3,
                ranges::BASE_TURN_MAX as f64,
            ),
        ] {
            num(file, k, v, lo, hi)?;
        }
        Ok(())
    }

    fn base_odometry(&self, file: &Path, b: &BaseSection) -> Result<()> {
        if let Some(g) = &odometry_geometry(b) {
            if !g.near(&nominal_geometry(b), 0.1) {
                return Err(cfg_err(
                    file,
                    "base.odometry",
                    "left_radius, right_radius and track must be within 10 % of wheel_radius and track",
                ));
            }
        }
        Ok(())
    }

    fn bus(&self, file: &Path, bus: &BusSection) -> Result<()> {
        num(
            file,
            "bus.loop_period_us",
            bus.loop_period_us as f64,
            ranges::LOOP_PERIOD_MIN_US as f64,
            ranges::LOOP_PERIOD_MAX_US as f64,
        )
    }
}

/// Every number of a joint-table entry within the range the wire accepts
/// (`ferrobot_protocol::ranges`).
fn joint_numbers(file: &Path, entry: &JointEntry) -> Result<()> {
    let (i, j) = (entry.index, entry.section);
    let (min, max, velocity) = (entry.min, entry.max, entry.velocity);
    let key = |k: &str| format!("joint[{i}].{k}");
    let from = |field: &str, overridden: bool| {
        if overridden {
            key(&format!("limits.{field}"))
        } else {
            format!(
                "{} (the URDF's limit of joint {:?})",
                key(&format!("limits.{field}")),
                j.name
            )
        }
    };
    let o = j.limits.clone().unwrap_or_default();
    let pmax = ranges::JOINT_POSITION_MAX as f64;
    num(file, from("min", o.min.is_some()), min, -pmax, pmax)?;
    num(file, from("max", o.max.is_some()), max, -pmax, pmax)?;
    if max - min < ranges::JOINT_RANGE_MIN as f64 {
        return Err(cfg_err(
            file,
            key("limits"),
            format!(
                "max - min must be at least {} rad (min {min}, max {max})",
                ranges::JOINT_RANGE_MIN
            ),
        ));
    }
    num(
        file,
        from("velocity", o.velocity.is_some()),
        velocity,
        ranges::JOINT_SPEED_LIMIT_MIN as f64,
        ranges::JOINT_SPEED_MAX as f64,
    )?;
    num(
        file,
        key("effort_limit"),
        j.effort_limit,
        0.0,
        ranges::JOINT_EFFORT_MAX as f64,
    )?;
    num(file, key("servo.offset"), j.servo.offset, -pmax, pmax)?;
    let gmax = ranges::GAIN_MAX as f64;
    if let Some(p) = j.pid {
        for (k, v) in [
            ("kp", p.kp),
            ("ki", p.ki),
            ("kd", p.kd),
            ("i_limit", p.i_limit),
        ] {
            num(file, key(&format!("pid.{k}")), v, 0.0, gmax)?;
        }
    }
    if let Some(k) = j.position_ki {
        num(file, key("position_ki"), k, 0.0, gmax)?;
    }
    Ok(())
}

/// A joint-table entry's name on the wire, and its row within what its servos can give and
/// the firmware accepts.
fn joint_row_fits(file: &Path, entry: &JointEntry) -> Result<()> {
    let (i, j) = (entry.index, entry.section);
    let row = joint_row(entry.joint);
    if j.name.len() > 16 {
        return Err(cfg_err(
            file,
            format!("joint[{i}].name"),
            "joint names are at most 16 bytes on the wire",
        ));
    }
    if let Some(gain) = ranges::gains_beyond_servo(&row.pid, &row) {
        return Err(cfg_err(
            file,
            format!("joint[{i}].pid.{gain}"),
            format!(
                "more than its {:?} servo(s) can use ({:.1} N·m of strength: kp at most \
                 {:.0} N·m/rad, ki {:.0} N·m/(rad·s), kd {:.0} N·m·s/rad, i_limit {:.1} N·m)",
                row.model,
                ranges::strength(&row),
                ranges::KP_PER_STRENGTH * ranges::strength(&row),
                ranges::KI_PER_STRENGTH * ranges::strength(&row),
                ranges::KD_PER_STRENGTH * ranges::strength(&row),
                ranges::strength(&row)
            ),
        ));
    }
    if ranges::effort_beyond_servo(row.limits.effort, &row) {
        return Err(cfg_err(
            file,
            format!("joint[{i}].effort_limit"),
            format!(
                "{} N·m is more than its {:?} servo(s) can give ({:.1} N·m)",
                row.limits.effort,
                row.model,
                ranges::strength(&row)
            ),
        ));
    }
    if !ranges::joint_config_ok(&row) {
        return Err(cfg_err(
            file,
            format!("joint[{i}]"),
            "outside the ranges the firmware accepts (ferrobot_protocol::ranges)",
        ));
    }
    Ok(())
}

/// The arm's timeout within the API's longest duration; its URDF chain, base frame to end
/// effector, moving exactly its joints; and no more joints than the numerical IK handles.
fn arm_chain_fits(
    file: &Path,
    urdf: &urdf_rs::Robot,
    arm: &ArmConfig,
    joints: &[Joint],
) -> Result<()> {
    num(
        file,
        "arm.timeout",
        arm.timeout,
        0.1,
        validate::MAX_DURATION_S,
    )?;
    let chain =
        chain_of(urdf, arm, joints).map_err(|e| cfg_err(file, "arm.ee_frame", e.to_string()))?;
    let names: Vec<&str> = chain.joints.iter().map(|j| j.name.as_str()).collect();
    if names != arm.joints.iter().map(String::as_str).collect::<Vec<_>>() {
        return Err(cfg_err(
            file,
            "arm.joints",
            format!(
                "the URDF chain {} -> {} moves {names:?}",
                arm.base_frame, arm.ee_frame
            ),
        ));
    }
    if arm.ik == IkKind::Numerical && names.len() > ferrobot_kinematics::ik::MAX_DOF {
        return Err(cfg_err(
            file,
            "arm.ik",
            format!(
                "the numerical solver handles at most {} joints; the arm has {}",
                ferrobot_kinematics::ik::MAX_DOF,
                names.len()
            ),
        ));
    }
    Ok(())
}
