//! What a loaded description derives: the firmware's joint table (SI units in `f32`), the
//! firmware profile a board runs, the base kind as the protocol names it, the gripper driver
//! (servo ticks), the wheel geometry (m) and the arm's kinematic chain (rad, m).

use ferrobot_control::odometry_calibration::WheelGeometry;
use ferrobot_description::{
    ArmConfig, BaseModel, BaseSection, GripperSection, Joint, JointRole, RobotConfig, ServoModel,
};
use ferrobot_firmware::config::{
    self as fwcfg, BaseConfig, BusConfig, GripperConfig, RobotProfile,
};
use ferrobot_firmware::time::Duration;
use ferrobot_kinematics::Chain;
use ferrobot_protocol::{BaseKind, JointConfig, JointKind, JointLimits, PidGains};

/// The firmware's row of joint `j`: the servo model's default gains, overridden by the
/// description's.
pub fn joint_row(j: &Joint) -> JointConfig {
    let kind = match j.kind {
        JointRole::Arm => JointKind::Arm,
        JointRole::Head => JointKind::Head,
        JointRole::Gripper => JointKind::Gripper,
    };
    let model = match j.model {
        ServoModel::Xm430W350 => ferrobot_protocol::ServoModel::Xm430W350,
        ServoModel::Xl430W250 => ferrobot_protocol::ServoModel::Xl430W250,
    };
    let l = j.limits;
    let mut row = fwcfg::joint(
        &j.name,
        kind,
        model,
        j.servo_id,
        j.twin_id,
        j.sign,
        JointLimits {
            min: l.min,
            max: l.max,
            velocity: l.velocity,
            effort: l.effort,
        },
    );
    row.offset = j.offset;
    if let Some(p) = j.pid {
        row.pid = PidGains {
            kp: p.kp as f32,
            ki: p.ki as f32,
            kd: p.kd as f32,
            i_limit: p.i_limit as f32,
        };
    }
    if let Some(k) = j.position_ki {
        row.position_ki = k as f32;
    }
    row
}

/// The firmware's joint table of `cfg`.
pub fn joint_table(cfg: &RobotConfig) -> Vec<JointConfig> {
    cfg.joints.iter().map(joint_row).collect()
}

/// The firmware profile `cfg` asks for.
pub fn firmware_profile(cfg: &RobotConfig) -> RobotProfile {
    // The base's model gives its encoder, top speed and feedback timing; the description
    // gives its wheel geometry.
    let base = match cfg.base.as_ref() {
        Some(b) => BaseConfig {
            wheel_radius: b.wheel_radius as f32,
            track: b.track as f32,
            ..match b.kind {
                BaseModel::Kobuki => BaseConfig::KOBUKI,
                BaseModel::Create2 => BaseConfig::CREATE2,
            }
        },
        None => BaseConfig::NONE,
    };
    let mut robot = ferrobot_protocol::Name::new();
    for c in cfg.name.chars() {
        if robot.push(c).is_err() {
            break;
        }
    }
    RobotProfile {
        robot,
        joints: cfg.joints.iter().map(joint_row).collect(),
        base,
        gripper: cfg.gripper.as_ref().map(gripper_driver),
        bus: BusConfig::at_baud(cfg.bus.baud),
        loop_period: Duration::from_micros(u64::from(cfg.bus.loop_period_us)),
        watchdog_period: Duration::from_millis(500),
        telemetry_period: Duration::from_millis(10),
    }
}

/// The firmware profile the host-run firmware runs for `cfg` (its `[direct]` section: the
/// adapter's bit rate, the host's loop period, the USB round trip in every reply's margin),
/// or `None` for a robot without one.
pub fn direct_profile(cfg: &RobotConfig) -> Option<RobotProfile> {
    let direct = cfg.direct.as_ref()?;
    let mut profile = firmware_profile(&cfg.direct_config()?);
    profile.bus.reply_margin = Duration::from_micros(u64::from(direct.reply_margin_us));
    Some(profile)
}

/// The base kind of `cfg` as the protocol names it.
pub fn base_kind(cfg: &RobotConfig) -> BaseKind {
    match cfg.base.as_ref().map(|b| b.kind) {
        Some(BaseModel::Kobuki) => BaseKind::Kobuki,
        Some(BaseModel::Create2) => BaseKind::Create2,
        None => BaseKind::None,
    }
}

/// The firmware's gripper driver for `g`'s ticks; the closing, kick and holding PWM, the
/// load threshold and the timing are those of PyRobot's LoCoBot gripper driver.
pub fn gripper_driver(g: &GripperSection) -> GripperConfig {
    GripperConfig {
        open_tick: g.open_tick,
        closed_tick: g.closed_tick,
        ..GripperConfig::LOCOBOT
    }
}

/// The base's nominal geometry: both wheels of `wheel_radius`, `track` apart.
pub fn nominal_geometry(b: &BaseSection) -> WheelGeometry {
    WheelGeometry::nominal(b.wheel_radius, b.track)
}

/// The base's calibrated geometry (`[base] odometry`), if it has one.
pub fn odometry_geometry(b: &BaseSection) -> Option<WheelGeometry> {
    b.odometry.map(|o| WheelGeometry {
        left_radius: o.left_radius,
        right_radius: o.right_radius,
        track: o.track,
    })
}

/// The chain of `arm` from its base frame to its end effector in `urdf`, with the limits of
/// the joint table `joints` (which the configuration may override), not the URDF's: IK
/// answers within what the arm is allowed.
pub(crate) fn chain_of(
    urdf: &urdf_rs::Robot,
    arm: &ArmConfig,
    joints: &[Joint],
) -> ferrobot_kinematics::Result<Chain> {
    let mut chain = Chain::from_urdf(urdf, &arm.base_frame, &arm.ee_frame)?;
    for cj in &mut chain.joints {
        if let Some(j) = joints.iter().find(|j| j.name == cj.name) {
            (cj.lower, cj.upper) = j.bounds;
        }
    }
    Ok(chain)
}

/// The arm chain of `cfg`, base frame to end effector; `None` without an arm (or, for a
/// description loaded without [`crate::ProfileChecks`], when the URDF has no such chain).
pub fn arm_chain(cfg: &RobotConfig) -> Option<Chain> {
    chain_of(&cfg.urdf, cfg.arm.as_ref()?, &cfg.joints).ok()
}
