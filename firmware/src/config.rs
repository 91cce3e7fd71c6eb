//! Firmware configuration: the joint table, the base and the bus, and the built-in profiles
//! of the bundled robots (the host can replace joint rows at run time).

use ferrobot_protocol::{
    BaseKind, JointConfig, JointKind, JointLimits, Name, PidGains, ServoModel, MAX_JOINTS,
};
use heapless::Vec;

use crate::time::Duration;

/// Wheel geometry and encoder of a differential-drive base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseConfig {
    /// Which base.
    pub kind: BaseKind,
    /// Wheel radius, m.
    pub wheel_radius: f32,
    /// Distance between the wheels' contact points, m.
    pub track: f32,
    /// Encoder ticks per wheel revolution.
    pub ticks_per_rev: f32,
    /// Largest wheel speed the base accepts, m/s.
    pub max_wheel_speed: f32,
    /// Feedback silence after which the base counts as lost.
    pub feedback_timeout: Duration,
}

impl BaseConfig {
    /// No base.
    pub const NONE: BaseConfig = BaseConfig {
        kind: BaseKind::None,
        wheel_radius: 0.0,
        track: 0.0,
        ticks_per_rev: 1.0,
        max_wheel_speed: 0.0,
        feedback_timeout: Duration::ZERO,
    };

    /// Yujin Kobuki: wheel separation 0.230 m, wheel radius 0.035 m, 2578.33 ticks per wheel
    /// revolution (0.002436917 rad per tick), feedback at 50 Hz.
    pub const KOBUKI: BaseConfig = BaseConfig {
        kind: BaseKind::Kobuki,
        wheel_radius: 0.035,
        track: 0.230,
        ticks_per_rev: 2578.33,
        max_wheel_speed: 0.7,
        feedback_timeout: Duration::from_millis(200),
    };

    /// iRobot Create 2: wheel diameter 72 mm and axle 235 mm as the Open Interface
    /// specification gives them, 508.8 ticks per wheel revolution, 0.5 m/s top speed, sensor
    /// stream every 15 ms.
    pub const CREATE2: BaseConfig = BaseConfig {
        kind: BaseKind::Create2,
        wheel_radius: 0.036,
        track: 0.235,
        ticks_per_rev: 508.8,
        max_wheel_speed: 0.5,
        feedback_timeout: Duration::from_millis(200),
    };

    /// Wheel angle per encoder tick, rad.
    pub fn rad_per_tick(&self) -> f32 {
        core::f32::consts::TAU / self.ticks_per_rev
    }
}

/// Gripper behaviour, in servo ticks and goal-PWM units (the LoCoBot driver's numbers).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperConfig {
    /// Goal position when open, ticks.
    pub open_tick: i32,
    /// Below this present position the gripper is fully closed, ticks.
    pub closed_tick: i32,
    /// Goal PWM while closing (negative closes).
    pub close_pwm: i16,
    /// Goal PWM of the short kick when the load first exceeds the threshold.
    pub kick_pwm: i16,
    /// Goal PWM while holding an object or closed.
    pub hold_pwm: i16,
    /// Load (present-load units) above which an object is suspected.
    pub load_threshold: i16,
    /// Kick duration.
    pub kick_time: Duration,
    /// How long the load must persist after the kick to count as an object.
    pub persist_time: Duration,
    /// Ignore the load this long after closing starts (breakaway transient).
    pub grace_time: Duration,
    /// Within this many ticks of `open_tick` the gripper counts as open.
    pub open_tolerance: i32,
}

impl GripperConfig {
    /// The LoCoBot gripper: open at 2800 ticks, closed below 1800, PWM −500, kick −700 when
    /// the load exceeds 500.
    pub const LOCOBOT: GripperConfig = GripperConfig {
        open_tick: 2800,
        closed_tick: 1800,
        close_pwm: -500,
        kick_pwm: -700,
        hold_pwm: -350,
        load_threshold: 500,
        kick_time: Duration::from_millis(50),
        persist_time: Duration::from_millis(150),
        grace_time: Duration::from_millis(100),
        open_tolerance: 25,
    };
}

/// Servo-bus timing used to size reply timeouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BusConfig {
    /// Time one byte takes on the bus, ns (10 bits per byte: 2500 ns at 4 Mbps): finer than a
    /// [`Duration`]'s µs, so a count of ns; [`BusConfig::bytes_time`] rounds a packet's up.
    pub byte_ns: u32,
    /// Slack added to every reply timeout for the servo's processing and the shell's latency.
    pub reply_margin: Duration,
}

impl BusConfig {
    /// A bus at `baud` bit/s with a 150 µs reply margin.
    pub const fn at_baud(baud: u32) -> Self {
        BusConfig {
            byte_ns: 10_000_000_000u64.div_ceil(baud as u64) as u32,
            reply_margin: Duration::from_micros(150),
        }
    }

    /// Time `n` bytes take on the bus (rounded up to whole µs).
    pub fn bytes_time(&self, n: usize) -> Duration {
        Duration::from_micros(
            (n as u64)
                .saturating_mul(u64::from(self.byte_ns))
                .div_ceil(1000),
        )
    }
}

/// Everything the firmware core needs to start.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotProfile {
    /// Robot name.
    pub robot: Name,
    /// Joint table.
    pub joints: Vec<JointConfig, MAX_JOINTS>,
    /// The base.
    pub base: BaseConfig,
    /// The gripper's driver, for the joint of kind [`JointKind::Gripper`]; `None` for a robot
    /// without a gripper (a gripper row then runs as a plain position joint).
    pub gripper: Option<GripperConfig>,
    /// Servo bus.
    pub bus: BusConfig,
    /// Servo-loop period (the firmware runs none shorter than [`crate::MIN_LOOP_PERIOD`]).
    pub loop_period: Duration,
    /// Host watchdog period, armed at the first accepted Hello; zero disables.
    pub watchdog_period: Duration,
    /// Telemetry period after the first accepted Hello; zero sends none.
    pub telemetry_period: Duration,
}

fn name(s: &str) -> Name {
    let mut n = Name::new();
    for c in s.chars() {
        if n.push(c).is_err() {
            break;
        }
    }
    n
}

/// Build one joint row with the defaults of its model.
#[allow(clippy::too_many_arguments)]
pub fn joint(
    joint_name: &str,
    kind: JointKind,
    model: ServoModel,
    servo_id: u8,
    twin_id: Option<u8>,
    sign: i8,
    limits: JointLimits,
) -> JointConfig {
    let pid = match model {
        ServoModel::Xm430W350 => PidGains {
            kp: 25.0,
            ki: 20.0,
            kd: 1.0,
            i_limit: 1.0,
        },
        _ => PidGains {
            kp: 8.0,
            ki: 8.0,
            kd: 0.25,
            i_limit: 0.3,
        },
    };
    JointConfig {
        name: name(joint_name),
        kind,
        model,
        servo_id,
        twin_id,
        sign,
        offset: 0.0,
        limits,
        pid,
        position_ki: if kind == JointKind::Gripper { 0.0 } else { 4.0 },
        // ROBOTIS' factory gains, and no motion profile: the firmware streams interpolated
        // setpoints every tick, so the servo must not add a profile of its own.
        servo: model.factory_gains(),
    }
}

const fn lim(min: f32, max: f32, velocity: f32, effort: f32) -> JointLimits {
    JointLimits {
        min,
        max,
        velocity,
        effort,
    }
}

/// LoCoBot arm, gripper and pan-tilt (PyRobot's `dynamixels.yaml`): joint_1 = 1, joint_2 = 2
/// with mirrored twin 3, joint_3 = 4, joint_4 = 5, joint_5 = 6 (joints 3-5 sign-inverted),
/// gripper = 7, pan = 8, tilt = 9. Arm joints ±1.57 rad at 1 rad/s; pan −2.7…2.6 rad, tilt
/// −1.4…1.75 rad.
fn locobot_joints() -> Vec<JointConfig, MAX_JOINTS> {
    use JointKind::*;
    use ServoModel::*;
    let arm = lim(-1.57, 1.57, 1.0, 3.5);
    let wrist = lim(-1.57, 1.57, 1.0, 1.4);
    let rows = [
        joint("joint_1", Arm, Xm430W350, 1, None, 1, arm),
        joint("joint_2", Arm, Xm430W350, 2, Some(3), 1, arm),
        joint("joint_3", Arm, Xm430W350, 4, None, -1, arm),
        joint("joint_4", Arm, Xm430W350, 5, None, -1, arm),
        joint("joint_5", Arm, Xl430W250, 6, None, -1, wrist),
        joint(
            "gripper",
            Gripper,
            Xl430W250,
            7,
            None,
            1,
            lim(-1.2, 1.6, 3.0, 1.4),
        ),
        joint(
            "head_pan_joint",
            Head,
            Xl430W250,
            8,
            None,
            1,
            lim(-2.7, 2.6, 1.0, 1.4),
        ),
        joint(
            "head_tilt_joint",
            Head,
            Xl430W250,
            9,
            None,
            1,
            lim(-1.4, 1.75, 1.0, 1.4),
        ),
    ];
    rows.into_iter().collect()
}

/// The LoCoBot (Kobuki base), servo bus at 4 Mbps, 1 kHz loop.
pub fn locobot() -> RobotProfile {
    RobotProfile {
        robot: name("locobot"),
        joints: locobot_joints(),
        base: BaseConfig::KOBUKI,
        gripper: Some(GripperConfig::LOCOBOT),
        bus: BusConfig::at_baud(4_000_000),
        loop_period: Duration::from_millis(1),
        watchdog_period: Duration::from_millis(500),
        telemetry_period: Duration::from_millis(20),
    }
}

/// The LoCoBot-Lite: the LoCoBot's arm on an iRobot Create 2.
pub fn locobot_lite() -> RobotProfile {
    RobotProfile {
        robot: name("locobot_lite"),
        base: BaseConfig::CREATE2,
        ..locobot()
    }
}

/// Sawyer's seven joints on the simulated stand-in (position-controlled XM430s, IDs 1-7):
/// position limits from Rethink's URDF, velocity limits from Rethink's joint specification
/// (`host/description/robots/sawyer.toml`). No gripper and no base; the stand-in has no
/// gravity model.
fn sawyer_joints() -> Vec<JointConfig, MAX_JOINTS> {
    use JointKind::Arm;
    use ServoModel::Xm430W350;
    let rows = [
        ("right_j0", lim(-3.0503, 3.0503, 1.74, 3.5)),
        ("right_j1", lim(-3.8095, 2.2736, 1.328, 3.5)),
        ("right_j2", lim(-3.0426, 3.0426, 1.957, 3.5)),
        ("right_j3", lim(-3.0439, 3.0439, 1.957, 3.5)),
        ("right_j4", lim(-2.9761, 2.9761, 3.0, 3.5)),
        ("right_j5", lim(-2.9761, 2.9761, 3.0, 3.5)),
        ("right_j6", lim(-4.7124, 4.7124, 3.0, 3.5)),
    ];
    rows.into_iter()
        .zip(1u8..)
        .map(|((n, l), id)| joint(n, Arm, Xm430W350, id, None, 1, l))
        .collect()
}

/// Sawyer's stand-in: seven servos on a 4 Mbps bus, 1 kHz loop, no gripper, no base.
pub fn sawyer() -> RobotProfile {
    RobotProfile {
        robot: name("sawyer"),
        joints: sawyer_joints(),
        base: BaseConfig::NONE,
        gripper: None,
        bus: BusConfig::at_baud(4_000_000),
        loop_period: Duration::from_millis(1),
        watchdog_period: Duration::from_millis(500),
        telemetry_period: Duration::from_millis(20),
    }
}

/// A profile by robot name.
pub fn by_name(robot: &str) -> Option<RobotProfile> {
    match robot {
        "locobot" => Some(locobot()),
        "locobot_lite" => Some(locobot_lite()),
        "sawyer" => Some(sawyer()),
        _ => None,
    }
}

/// Check a joint row against the protocol's ranges ([`ferrobot_protocol::ranges`]).
pub fn joint_is_valid(c: &JointConfig) -> bool {
    ferrobot_protocol::ranges::joint_config_ok(c)
}
