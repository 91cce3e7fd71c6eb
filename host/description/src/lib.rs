//! Robot descriptions: a TOML file naming a URDF and describing the arm, gripper, camera,
//! base and the firmware's joint table. Bundled robots (`locobot`, `locobot_lite`, `sawyer`)
//! are compiled in; any other robot is a TOML file plus its URDF on disk.
//!
//! Loading is strict: unknown keys, wrong types and inconsistencies (an arm joint the URDF
//! lacks, a home vector of the wrong length, duplicate servo IDs…) are errors that name the
//! file, the key and the problem.

#![warn(missing_docs)]

pub mod camera_mount;
pub use camera_mount::{CameraCalibration, CameraMount};

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use ferrobot_firmware::config::{
    self as fwcfg, BaseConfig, BusConfig, GripperConfig, RobotProfile,
};
use ferrobot_firmware::time::Duration;
use ferrobot_protocol::{
    ranges, BaseKind, JointConfig, JointKind, JointLimits, PidGains, ServoModel,
};
use serde::Deserialize;

use ferrobot_control::odometry_calibration::WheelGeometry;
use ferrobot_geometry::validate;
use ferrobot_kinematics::Chain;

/// Everything that can go wrong with a description.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// No bundled robot of that name.
    #[error("unknown robot {name:?}; bundled robots are: {known}")]
    UnknownRobot {
        /// The name asked for.
        name: String,
        /// The bundled names, comma-separated.
        known: String,
    },
    /// A configuration file is missing, unreadable or invalid.
    #[error("{file}: {key}: {problem}", file = file.display())]
    Config {
        /// The file.
        file: PathBuf,
        /// The key (dotted path) concerned, or `-` for the whole file.
        key: String,
        /// What is wrong.
        problem: String,
    },
    /// An unknown name (a base controller).
    #[error("unknown {what} {name:?}")]
    UnknownName {
        /// What kind of name.
        what: &'static str,
        /// The name.
        name: String,
    },
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Names of the bundled robots.
pub const BUNDLED: [&str; 3] = ["locobot", "locobot_lite", "sawyer"];

/// The bundled robot `name`'s configuration and URDF texts.
pub fn bundled_files(name: &str) -> Option<(&'static str, &'static str)> {
    match name {
        "locobot" => Some((
            include_str!("../robots/locobot.toml"),
            include_str!("../robots/locobot.urdf"),
        )),
        "locobot_lite" => Some((
            include_str!("../robots/locobot_lite.toml"),
            include_str!("../robots/locobot_lite.urdf"),
        )),
        "sawyer" => Some((
            include_str!("../robots/sawyer.toml"),
            include_str!("../robots/sawyer.urdf"),
        )),
        _ => None,
    }
}

/// Which inverse-kinematics solver an arm uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IkKind {
    /// Closed form for the LoCoBot's yaw-pitch-pitch-pitch-roll arm.
    LocobotPitchRoll,
    /// Levenberg-Marquardt with random restarts, for any chain.
    Numerical,
}

/// `[arm]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmConfig {
    /// Arm joint names, base to tip (URDF names).
    pub joints: Vec<String>,
    /// Frame in which end-effector poses are given (the robot's root link).
    pub base_frame: String,
    /// End-effector frame.
    pub ee_frame: String,
    /// Home configuration, rad.
    pub home: Vec<f64>,
    /// The configuration the arm travels in while the base drives, rad: folded within the
    /// base's footprint (or as near it as the arm's self-collision allows) and out of the
    /// camera's view. `None`: the arm has no such pose.
    #[serde(default)]
    pub stow: Option<Vec<f64>>,
    /// The configuration the arm holds while the camera looks at a table in front of the
    /// robot (grasping at PyRobot's 0.8 rad tilt), rad: out of that view. `None`: the stow
    /// pose serves.
    #[serde(default)]
    pub look: Option<Vec<f64>>,
    /// IK solver.
    pub ik: IkKind,
    /// IK position tolerance, m.
    #[serde(default = "default_ik_tol")]
    pub ik_position_tolerance: f64,
    /// IK orientation tolerance, rad.
    #[serde(default = "default_ik_tol")]
    pub ik_orientation_tolerance: f64,
    /// A joint has arrived when within this of its target, rad.
    #[serde(default = "default_joint_tol")]
    pub joint_tolerance: f64,
    /// Default timeout of a blocking arm motion, s.
    #[serde(default = "default_timeout")]
    pub timeout: f64,
    /// Acceleration limit of each arm joint, rad/s², base to tip: what planned trajectories
    /// respect. When absent, each joint's speed limit per 0.5 s (full speed in half a second).
    #[serde(default)]
    pub acceleration: Vec<f64>,
    /// RRT-Connect's longest extension step for this arm, rad of joint-space distance (as
    /// MoveIt's `range` in `ompl_planning.yaml`). When absent, a fifth of the diagonal of the
    /// joint limits' box (OMPL's default).
    #[serde(default)]
    pub planning_range: Option<f64>,
}

fn default_ik_tol() -> f64 {
    1e-5
}
fn default_joint_tol() -> f64 {
    0.01
}
fn default_timeout() -> f64 {
    20.0
}

/// `[gripper]`: a Dynamixel gripper driven by the firmware's gripper state machine, in servo
/// ticks (4096 per turn, 2048 at the centre).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GripperSection {
    /// The joint-table entry of the gripper motor.
    pub joint: String,
    /// Goal position when open, ticks.
    pub open_tick: i32,
    /// Below this present position the gripper is fully closed, ticks.
    pub closed_tick: i32,
    /// The fingers' mechanical stops (closed, open), ticks: where the simulated gripper stops.
    pub stops: [i32; 2],
    /// The URDF's finger joints (prismatic), each moving its finger away from the centre
    /// line as the gripper opens, with the sign of that motion along the joint's axis.
    #[serde(default)]
    pub fingers: Vec<FingerSection>,
    /// Each finger's distance from the centre line (m) at the closed and at the open stop;
    /// linear in the motor's angle in between.
    #[serde(default)]
    pub finger_travel: [f64; 2],
}

/// `[[gripper.fingers]]`: one finger joint of the URDF.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerSection {
    /// URDF joint name (prismatic).
    pub joint: String,
    /// +1 or -1: the direction of opening along the joint's axis.
    pub sign: f64,
}

impl GripperSection {
    /// The firmware's gripper driver for these ticks; the closing, kick and holding PWM, the
    /// load threshold and the timing are those of PyRobot's LoCoBot gripper driver.
    pub fn driver(&self) -> GripperConfig {
        GripperConfig {
            open_tick: self.open_tick,
            closed_tick: self.closed_tick,
            ..GripperConfig::LOCOBOT
        }
    }

    /// Each finger's distance from the centre line (m) when the motor is at `ticks`
    /// (clamped to the stops).
    pub fn finger_offset(&self, ticks: f64) -> f64 {
        let [c, o] = self.stops.map(f64::from);
        let t = if ticks.is_finite() {
            ((ticks - c) / (o - c)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.finger_travel[0] + t * (self.finger_travel[1] - self.finger_travel[0])
    }

    /// The finger joints' values (m, in `fingers` order) when the motor is at `ticks`.
    pub fn finger_positions(&self, ticks: f64) -> Vec<(String, f64)> {
        let s = self.finger_offset(ticks);
        self.fingers
            .iter()
            .map(|f| (f.joint.clone(), f.sign * s))
            .collect()
    }
}

/// `[bus]`: the servo bus (optional; 4 Mbit/s and a 1 kHz servo loop when absent).
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusSection {
    /// Bit rate, bit/s.
    pub baud: u32,
    /// Servo-loop period, µs.
    pub loop_period_us: u32,
}

impl Default for BusSection {
    fn default() -> Self {
        BusSection {
            baud: 4_000_000,
            loop_period_us: 1000,
        }
    }
}

/// `[camera]`: the pan-tilt head and the RGB-D camera's intrinsics.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSection {
    /// Pan joint.
    pub pan_joint: String,
    /// Tilt joint.
    pub tilt_joint: String,
    /// Optical frame (x right, y down, z forward).
    pub frame: String,
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Focal length x, px.
    pub fx: f64,
    /// Focal length y, px.
    pub fy: f64,
    /// Principal point x, px.
    pub cx: f64,
    /// Principal point y, px.
    pub cy: f64,
    /// Nearest depth kept in point clouds, m.
    pub depth_min: f64,
    /// Farthest depth kept in point clouds, m.
    pub depth_max: f64,
    /// Frames per second (default 30, the D435's colour and depth rate).
    #[serde(default = "default_camera_rate")]
    pub rate: f64,
    /// The fiducial marker on the arm that hand-eye calibration looks for, if any.
    #[serde(default)]
    pub marker: Option<MarkerSection>,
}

/// `[camera.marker]`: a square fiducial (a black square on a white plate) on a link of the
/// arm, seen by the camera during hand-eye calibration.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerSection {
    /// The link the marker is fixed to (PyRobot's LoCoBot: `ar_tag` on the gripper).
    pub link: String,
    /// Side of the black square, m (PyRobot's AR tag: 0.03).
    pub size: f64,
    /// Centre of the square's face in the link's frame, m; the square lies in the link's xy
    /// plane (its sides along x and y), facing +z.
    pub xyz: [f64; 3],
}

impl MarkerSection {
    /// The square's corners in the marker link's frame, m: (+x, +y), (−x, +y), (−x, −y),
    /// (+x, −y) from the centre, counter-clockwise seen from +z.
    pub fn corners(&self) -> [[f64; 3]; 4] {
        let h = self.size / 2.0;
        let [x, y, z] = self.xyz;
        [[h, h], [-h, h], [-h, -h], [h, -h]].map(|[dx, dy]| [x + dx, y + dy, z])
    }
}

fn default_camera_rate() -> f64 {
    30.0
}

/// Which base.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BaseModel {
    /// Yujin Kobuki.
    Kobuki,
    /// iRobot Create 2.
    Create2,
}

/// Base position controllers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BaseController {
    /// Rotate, drive, rotate, with velocity ramps.
    Proportional,
    /// Time-varying LQR tracking a reference (sharp or smooth) under the tracking limits.
    Lqr,
    /// Iterative LQR: the reference made dynamically consistent and optimal, then tracked.
    Ilqr,
    /// Dynamic window approach: velocity sampling under acceleration limits, scored on
    /// obstacle clearance, progress to the goal and heading (used when obstacles are given).
    Dwa,
}

impl BaseController {
    /// Every controller, in the benchmark's order.
    pub const ALL: [BaseController; 4] = [
        BaseController::Proportional,
        BaseController::Lqr,
        BaseController::Ilqr,
        BaseController::Dwa,
    ];

    /// The configuration and command-line name.
    pub fn name(self) -> &'static str {
        match self {
            BaseController::Proportional => "proportional",
            BaseController::Lqr => "lqr",
            BaseController::Ilqr => "ilqr",
            BaseController::Dwa => "dwa",
        }
    }
}

impl std::str::FromStr for BaseController {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        BaseController::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| Error::UnknownName {
                what: "base controller",
                name: s.to_string(),
            })
    }
}

/// `[base]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseSection {
    /// Which base.
    pub kind: BaseModel,
    /// Nominal wheel radius, m.
    pub wheel_radius: f64,
    /// Nominal wheel separation, m.
    pub track: f64,
    /// Radius of the base's footprint, m (obstacle clearance of the dynamic window).
    pub footprint_radius: f64,
    /// Smallest wheel speed that surely moves the wheels (just above their deadband), m/s:
    /// the creep speed of the finisher after LQR position goals.
    pub min_wheel_speed: f64,
    /// Largest forward speed of position controllers, m/s.
    pub max_linear: f64,
    /// Largest yaw rate of position controllers, rad/s.
    pub max_angular: f64,
    /// Default position controller.
    pub controller: BaseController,
    /// Position tolerance of position controllers, m.
    #[serde(default = "default_translation_tol")]
    pub translation_tolerance: f64,
    /// Heading tolerance of position controllers, rad.
    #[serde(default = "default_rotation_tol")]
    pub rotation_tolerance: f64,
    /// Calibrated odometry geometry, e.g. `odometry = { left_radius = 0.03617,
    /// right_radius = 0.03628, track = 0.2372 }` (m), as `ferrobot calibrate-odometry` prints
    /// it; each value within 10 % of the nominal one. Absent: the nominal `wheel_radius` and
    /// `track`.
    #[serde(default)]
    pub odometry: Option<WheelGeometry>,
}

impl BaseSection {
    /// The nominal geometry: both wheels of `wheel_radius`, `track` apart.
    pub fn nominal_geometry(&self) -> WheelGeometry {
        WheelGeometry::nominal(self.wheel_radius, self.track)
    }
}

fn default_translation_tol() -> f64 {
    0.01
}
fn default_rotation_tol() -> f64 {
    1f64.to_radians()
}

/// Servo of a joint.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServoSection {
    /// Dynamixel ID.
    pub id: u8,
    /// `xm430-w350` or `xl430-w250`.
    pub model: String,
    /// +1 or −1.
    #[serde(default = "one")]
    pub sign: i8,
    /// Servo angle at joint zero, rad.
    #[serde(default)]
    pub offset: f64,
    /// Mirrored twin servo sharing the load.
    pub twin: Option<u8>,
}

fn one() -> i8 {
    1
}

/// Per-field overrides of the URDF's joint limits.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsOverride {
    /// Lower position limit, rad.
    pub min: Option<f64>,
    /// Upper position limit, rad.
    pub max: Option<f64>,
    /// Speed limit, rad/s.
    pub velocity: Option<f64>,
}

/// Joint PID of current mode.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PidSection {
    /// N·m/rad.
    pub kp: f64,
    /// N·m/(rad·s).
    pub ki: f64,
    /// N·m·s/rad.
    pub kd: f64,
    /// Integral bound, N·m.
    pub i_limit: f64,
}

/// Joint kind in the table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointRole {
    /// Arm joint.
    Arm,
    /// Pan or tilt.
    Head,
    /// Gripper motor.
    Gripper,
}

/// One `[[joint]]` of the firmware's joint table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSection {
    /// Joint name (a URDF joint, except for the gripper motor).
    pub name: String,
    /// Role.
    pub kind: JointRole,
    /// Servo.
    pub servo: ServoSection,
    /// Limit overrides.
    pub limits: Option<LimitsOverride>,
    /// Effort limit, N·m.
    pub effort_limit: f64,
    /// Current-mode PID; the model's default when absent.
    pub pid: Option<PidSection>,
    /// Position-mode goal-offset integrator gain, 1/s; the default when absent.
    pub position_ki: Option<f64>,
}

/// `[sim]`: options of the simulated robot.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimSection {
    /// Whether the arm's links load the servos with gravity (default true).
    #[serde(default = "yes")]
    pub gravity: bool,
}

fn yes() -> bool {
    true
}

/// The file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    name: String,
    urdf: String,
    board_profile: Option<String>,
    arm: Option<ArmConfig>,
    gripper: Option<GripperSection>,
    camera: Option<CameraSection>,
    base: Option<BaseSection>,
    bus: Option<BusSection>,
    #[serde(rename = "joint", default)]
    joints: Vec<JointSection>,
    sim: Option<SimSection>,
    collision: Option<CollisionSection>,
}

/// `[collision]`: the self-collision matrix, as `ferrobot collision-matrix` computes it by
/// sampling (MoveIt's setup assistant's method).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionSection {
    /// Link pairs never checked against each other, with the reason: `adjacent`, `default`
    /// (touching in the home pose), `always` or `never` (in every or no sample).
    #[serde(default)]
    pub disabled: Vec<(String, String, String)>,
}

/// A loaded, validated robot configuration.
#[derive(Debug, Clone)]
pub struct RobotConfig {
    /// Robot name.
    pub name: String,
    /// Where it came from (`<bundled>/NAME.toml` for bundled robots).
    pub file: PathBuf,
    /// The firmware's built-in profile a board runs for this robot, if it has one
    /// (`ferrobot_firmware::config::by_name`).
    pub board_profile: Option<String>,
    /// `[bus]`.
    pub bus: BusSection,
    /// The parsed URDF.
    pub urdf: urdf_rs::Robot,
    /// The URDF's file name as the configuration gives it (relative to the configuration).
    pub urdf_file: String,
    /// `[collision]`.
    pub collision: Option<CollisionSection>,
    /// `[arm]`.
    pub arm: Option<ArmConfig>,
    /// `[gripper]`.
    pub gripper: Option<GripperSection>,
    /// `[camera]`.
    pub camera: Option<CameraSection>,
    /// `[base]`.
    pub base: Option<BaseSection>,
    /// The firmware joint table, with limits resolved against the URDF.
    pub joints: Vec<JointConfig>,
    /// Gravity in simulation.
    pub sim_gravity: bool,
    /// The arm chain, base frame to end effector.
    pub arm_chain: Option<Chain>,
}

fn cfg_err(file: &Path, key: impl Into<String>, problem: impl Into<String>) -> Error {
    Error::Config {
        file: file.to_path_buf(),
        key: key.into(),
        problem: problem.into(),
    }
}

/// Largest configuration file read, bytes.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;
/// Largest URDF file read, bytes.
pub const MAX_URDF_BYTES: u64 = 16 << 20;

/// The bytes of a regular file of at most `max` bytes: a directory, a device (`/dev/zero`), a
/// FIFO or a larger file is an error, read no further than `max` bytes.
pub fn read_bytes(path: &Path, max: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(std::io::Error::other("not a regular file"));
    }
    if meta.len() > max {
        return Err(std::io::Error::other(format!(
            "{} bytes, larger than the {max} bytes accepted",
            meta.len()
        )));
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(max + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max {
        return Err(std::io::Error::other(format!(
            "larger than the {max} bytes accepted"
        )));
    }
    Ok(bytes)
}

/// The text of a regular file of at most `max` bytes ([`read_bytes`]); text that is not UTF-8
/// is an error too.
pub fn read_text(path: &Path, max: u64) -> std::io::Result<String> {
    String::from_utf8(read_bytes(path, max)?).map_err(|_| std::io::Error::other("not UTF-8 text"))
}

/// `value` finite and within `[lo, hi]`, or an error naming the file and the key.
fn num(file: &Path, key: impl Into<String>, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        return Ok(());
    }
    Err(cfg_err(
        file,
        key,
        format!("{value} is not a finite number in [{lo}, {hi}]"),
    ))
}

/// Where a configuration comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigSource {
    /// A bundled robot by name.
    Bundled(String),
    /// A TOML file on disk; its `urdf` path is relative to it.
    File(PathBuf),
}

/// Set dotted `key`s of a TOML document to values.
fn apply_overrides(text: &str, file: &Path, overrides: &[(String, toml::Value)]) -> Result<String> {
    let mut doc: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| cfg_err(file, "-", e.message().to_string()))?;
    for (key, value) in overrides {
        let mut parts = key.split('.').peekable();
        let mut table = &mut doc;
        while let Some(p) = parts.next() {
            if parts.peek().is_none() {
                table.insert(p.to_string(), value.clone());
            } else {
                table = table
                    .entry(p.to_string())
                    .or_insert_with(|| toml::Value::Table(Default::default()))
                    .as_table_mut()
                    .ok_or_else(|| cfg_err(file, key.clone(), format!("{p:?} is not a table")))?;
            }
        }
    }
    Ok(doc.to_string())
}

impl RobotConfig {
    /// Load from `source` with `overrides` (dotted keys, e.g. `("arm.joint_tolerance", 0.005)`)
    /// applied to the TOML before it is validated, so an override is checked like the file.
    pub fn load(source: &ConfigSource, overrides: &[(String, toml::Value)]) -> Result<Self> {
        let with_overrides = |text: &str, file: &Path| -> Result<String> {
            if overrides.is_empty() {
                Ok(text.to_string())
            } else {
                apply_overrides(text, file, overrides)
            }
        };
        match source {
            ConfigSource::Bundled(n) => {
                let (toml, urdf) = bundled_files(n).ok_or_else(|| Error::UnknownRobot {
                    name: n.to_string(),
                    known: BUNDLED.join(", "),
                })?;
                let file = PathBuf::from(format!("<bundled>/{n}.toml"));
                let text = with_overrides(toml, &file)?;
                Self::parse(&text, &file, |_| Ok(urdf.to_string()))
            }
            ConfigSource::File(p) => {
                let text = read_text(p, MAX_CONFIG_BYTES)
                    .map_err(|e| cfg_err(p, "-", format!("cannot read: {e}")))?;
                let text = with_overrides(&text, p)?;
                let dir = p.parent().map(Path::to_path_buf).unwrap_or_default();
                Self::parse(&text, p, |u| {
                    let up = dir.join(u);
                    read_text(&up, MAX_URDF_BYTES).map_err(|e| {
                        cfg_err(p, "urdf", format!("cannot read {}: {e}", up.display()))
                    })
                })
            }
        }
    }

    /// Load a bundled robot by name.
    pub fn bundled(name: &str) -> Result<Self> {
        Self::load(&ConfigSource::Bundled(name.to_string()), &[])
    }

    /// Load a robot from a TOML file; its `urdf` path is relative to the file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        Self::load(&ConfigSource::File(path.as_ref().to_path_buf()), &[])
    }

    /// Parse TOML text (named `file` in errors); `read_urdf` fetches the URDF it names.
    pub fn parse(
        text: &str,
        file: &Path,
        read_urdf: impl FnOnce(&str) -> Result<String>,
    ) -> Result<Self> {
        let de = toml::Deserializer::parse(text)
            .map_err(|e| cfg_err(file, "-", e.message().to_string()))?;
        let raw: ConfigFile = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            cfg_err(
                file,
                if key.is_empty() || key == "." {
                    "-".to_string()
                } else {
                    key
                },
                e.inner().message().to_string(),
            )
        })?;
        let urdf_text = read_urdf(&raw.urdf)?;
        let urdf = urdf_rs::read_from_string(&urdf_text)
            .map_err(|e| cfg_err(file, "urdf", format!("invalid URDF: {e}")))?;
        // Names, links, axes and origins, then the tree: one root, no cycle, every link on it.
        ferrobot_kinematics::LinkTree::from_urdf(&urdf)
            .map_err(|e| cfg_err(file, "urdf", format!("invalid URDF: {e}")))?;
        Self::validate(raw, urdf, file)
    }

    fn validate(mut raw: ConfigFile, urdf: urdf_rs::Robot, file: &Path) -> Result<Self> {
        let urdf_joint = |name: &str| urdf.joints.iter().find(|j| j.name == name);
        // The joint table.
        let mut ids = BTreeSet::new();
        let mut joints = Vec::new();
        // The firmware's bus drives at most this many servos, twins included; more were
        // dropped without an error (a joint, or a twin's half of its torque, never driven).
        let servos: usize = raw
            .joints
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
        // Each table joint's limits as checked (before the table's `f32`), rad or m; its keys
        // are the names seen so far.
        let mut checked: BTreeMap<&str, (f64, f64)> = BTreeMap::new();
        for (i, j) in raw.joints.iter().enumerate() {
            let key = |k: &str| format!("joint[{i}].{k}");
            if checked.contains_key(j.name.as_str()) {
                return Err(cfg_err(
                    file,
                    key("name"),
                    format!("joint {:?} has two [[joint]] entries", j.name),
                ));
            }
            let model = match j.servo.model.as_str() {
                "xm430-w350" => ServoModel::Xm430W350,
                "xl430-w250" => ServoModel::Xl430W250,
                other => {
                    return Err(cfg_err(
                        file,
                        key("servo.model"),
                        format!("unknown servo model {other:?}; known: xm430-w350, xl430-w250"),
                    ))
                }
            };
            if j.servo.sign != 1 && j.servo.sign != -1 {
                return Err(cfg_err(
                    file,
                    key("servo.sign"),
                    format!("must be 1 or -1, not {}", j.servo.sign),
                ));
            }
            for id in std::iter::once(j.servo.id).chain(j.servo.twin) {
                if id >= 0xFD {
                    return Err(cfg_err(
                        file,
                        key("servo.id"),
                        format!("Dynamixel IDs are 0-252, not {id}"),
                    ));
                }
                if !ids.insert(id) {
                    return Err(cfg_err(
                        file,
                        key("servo.id"),
                        format!("servo ID {id} is used twice"),
                    ));
                }
            }
            // Limits: the URDF's, overridden per field.
            let (mut min, mut max, mut velocity) = match urdf_joint(&j.name) {
                Some(u) => (u.limit.lower, u.limit.upper, u.limit.velocity),
                None if j.kind == JointRole::Gripper => (-1.2, 1.6, 3.0),
                None => {
                    return Err(cfg_err(
                        file,
                        key("name"),
                        format!("the URDF has no joint {:?}", j.name),
                    ));
                }
            };
            if let Some(o) = &j.limits {
                min = o.min.unwrap_or(min);
                max = o.max.unwrap_or(max);
                velocity = o.velocity.unwrap_or(velocity);
            }
            // Every number within the range the wire accepts (`ferrobot_protocol::ranges`).
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
            checked.insert(j.name.as_str(), (min, max));
            let kind = match j.kind {
                JointRole::Arm => JointKind::Arm,
                JointRole::Head => JointKind::Head,
                JointRole::Gripper => JointKind::Gripper,
            };
            let mut row = fwcfg::joint(
                &j.name,
                kind,
                model,
                j.servo.id,
                j.servo.twin,
                j.servo.sign,
                JointLimits {
                    min: min as f32,
                    max: max as f32,
                    velocity: velocity as f32,
                    effort: j.effort_limit as f32,
                },
            );
            if j.name.len() > 16 {
                return Err(cfg_err(
                    file,
                    key("name"),
                    "joint names are at most 16 bytes on the wire",
                ));
            }
            row.offset = j.servo.offset as f32;
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
                    key("effort_limit"),
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
            joints.push(row);
        }
        if joints.len() > ferrobot_protocol::MAX_JOINTS {
            return Err(cfg_err(
                file,
                "joint",
                format!("at most {} joints", ferrobot_protocol::MAX_JOINTS),
            ));
        }
        let in_table = |n: &str| joints.iter().any(|j| j.name.as_str() == n);
        // The arm.
        let mut arm_chain = None;
        if let Some(arm) = &mut raw.arm {
            if arm.joints.is_empty() {
                return Err(cfg_err(
                    file,
                    "arm.joints",
                    "an arm needs at least one joint",
                ));
            }
            for (i, n) in arm.joints.iter().enumerate() {
                if !in_table(n) {
                    return Err(cfg_err(
                        file,
                        format!("arm.joints[{i}]"),
                        format!("{n:?} has no [[joint]] entry"),
                    ));
                }
            }
            let named = std::iter::once(("arm.home", &arm.home))
                .chain(arm.stow.iter().map(|s| ("arm.stow", s)))
                .chain(arm.look.iter().map(|s| ("arm.look", s)));
            for (key, pose) in named {
                if pose.len() != arm.joints.len() {
                    return Err(cfg_err(
                        file,
                        key,
                        format!(
                            "has {} values for {} arm joints",
                            pose.len(),
                            arm.joints.len()
                        ),
                    ));
                }
                for (i, (n, &q)) in arm.joints.iter().zip(pose).enumerate() {
                    let l = joints
                        .iter()
                        .find(|j| j.name.as_str() == n.as_str())
                        .map(|j| j.limits);
                    if let Some(l) = l {
                        num(file, format!("{key}[{i}]"), q, l.min as f64, l.max as f64)?;
                    }
                }
            }
            num(
                file,
                "arm.ik_position_tolerance",
                arm.ik_position_tolerance,
                1e-9,
                0.1,
            )?;
            num(
                file,
                "arm.ik_orientation_tolerance",
                arm.ik_orientation_tolerance,
                1e-9,
                0.5,
            )?;
            num(file, "arm.joint_tolerance", arm.joint_tolerance, 1e-4, 0.5)?;
            if arm.acceleration.is_empty() {
                arm.acceleration = arm
                    .joints
                    .iter()
                    .map(|n| {
                        joints
                            .iter()
                            .find(|j| j.name.as_str() == n.as_str())
                            .map_or(1.0, |j| j.limits.velocity as f64)
                            / 0.5
                    })
                    .collect();
            } else if arm.acceleration.len() != arm.joints.len() {
                return Err(cfg_err(
                    file,
                    "arm.acceleration",
                    format!(
                        "has {} values for {} arm joints",
                        arm.acceleration.len(),
                        arm.joints.len()
                    ),
                ));
            }
            for (i, &a) in arm.acceleration.iter().enumerate() {
                num(file, format!("arm.acceleration[{i}]"), a, 0.01, 1000.0)?;
            }
            if let Some(r) = arm.planning_range {
                num(file, "arm.planning_range", r, 0.01, 10.0)?;
            }
            num(
                file,
                "arm.timeout",
                arm.timeout,
                0.1,
                validate::MAX_DURATION_S,
            )?;
            let mut chain = Chain::from_urdf(&urdf, &arm.base_frame, &arm.ee_frame)
                .map_err(|e| cfg_err(file, "arm.ee_frame", e.to_string()))?;
            // The limits the table checked (and the configuration may override), not the
            // URDF's: IK answers within what the arm is allowed.
            for cj in &mut chain.joints {
                if let Some(&(lo, hi)) = checked.get(cj.name.as_str()) {
                    (cj.lower, cj.upper) = (lo, hi);
                }
            }
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
            if arm.ik == IkKind::LocobotPitchRoll && names.len() != 5 {
                return Err(cfg_err(
                    file,
                    "arm.ik",
                    "locobot_pitch_roll needs a 5-joint arm",
                ));
            }
            arm_chain = Some(chain);
        }
        if let (None, Some(j)) = (
            &raw.gripper,
            joints.iter().find(|j| j.kind == JointKind::Gripper),
        ) {
            return Err(cfg_err(
                file,
                "gripper",
                format!("joint {:?} is a gripper but there is no [gripper]", j.name),
            ));
        }
        if let Some(g) = &raw.gripper {
            for (k, v) in [
                ("gripper.open_tick", g.open_tick),
                ("gripper.closed_tick", g.closed_tick),
                ("gripper.stops[0]", g.stops[0]),
                ("gripper.stops[1]", g.stops[1]),
            ] {
                num(file, k, v as f64, 0.0, 4095.0)?;
            }
            let order = "the ticks must satisfy stops[0] < closed_tick < open_tick <= stops[1]";
            for (k, ok) in [
                ("gripper.closed_tick", g.stops[0] < g.closed_tick),
                ("gripper.open_tick", g.closed_tick < g.open_tick),
                ("gripper.stops[1]", g.open_tick <= g.stops[1]),
            ] {
                if !ok {
                    return Err(cfg_err(file, k, order));
                }
            }
            for (k, f) in g.fingers.iter().enumerate() {
                let key = format!("gripper.fingers[{k}]");
                match urdf.joints.iter().find(|j| j.name == f.joint) {
                    Some(j) if j.joint_type == urdf_rs::JointType::Prismatic => {}
                    _ => {
                        return Err(cfg_err(
                            file,
                            format!("{key}.joint"),
                            format!("{:?} is not a prismatic joint of the URDF", f.joint),
                        ))
                    }
                }
                if f.sign != 1.0 && f.sign != -1.0 {
                    return Err(cfg_err(file, format!("{key}.sign"), "the sign is 1 or -1"));
                }
            }
            for v in g.finger_travel {
                num(file, "gripper.finger_travel", v, 0.0, 0.5)?;
            }
            if !g.fingers.is_empty() && g.finger_travel[0] >= g.finger_travel[1] {
                return Err(cfg_err(
                    file,
                    "gripper.finger_travel",
                    "a finger is farther from the centre open than closed",
                ));
            }
            if !joints
                .iter()
                .any(|j| j.name.as_str() == g.joint && j.kind == JointKind::Gripper)
            {
                return Err(cfg_err(
                    file,
                    "gripper.joint",
                    format!("{:?} is not a [[joint]] of kind \"gripper\"", g.joint),
                ));
            }
        }
        if let Some(c) = &raw.camera {
            for (k, n) in [
                ("camera.pan_joint", &c.pan_joint),
                ("camera.tilt_joint", &c.tilt_joint),
            ] {
                if !in_table(n) {
                    return Err(cfg_err(file, k, format!("{n:?} has no [[joint]] entry")));
                }
            }
            for (k, v) in [("camera.width", c.width), ("camera.height", c.height)] {
                num(file, k, v as f64, 1.0, 8192.0)?;
            }
            num(file, "camera.fx", c.fx, 1e-3, 1e5)?;
            num(file, "camera.fy", c.fy, 1e-3, 1e5)?;
            num(file, "camera.cx", c.cx, 0.0, c.width as f64)?;
            num(file, "camera.cy", c.cy, 0.0, c.height as f64)?;
            num(file, "camera.depth_min", c.depth_min, 0.0, 100.0)?;
            num(file, "camera.rate", c.rate, 0.1, 1000.0)?;
            num(
                file,
                "camera.depth_max",
                c.depth_max,
                c.depth_min + 1e-3,
                100.0,
            )?;
            if !urdf.links.iter().any(|l| l.name == c.frame) {
                return Err(cfg_err(
                    file,
                    "camera.frame",
                    format!("the URDF has no link {:?}", c.frame),
                ));
            }
            if let Some(m) = &c.marker {
                if !urdf.links.iter().any(|l| l.name == m.link) {
                    return Err(cfg_err(
                        file,
                        "camera.marker.link",
                        format!("the URDF has no link {:?}", m.link),
                    ));
                }
                num(file, "camera.marker.size", m.size, 1e-3, 1.0)?;
                for v in m.xyz {
                    num(file, "camera.marker.xyz", v, -1.0, 1.0)?;
                }
            }
        }
        if let Some(b) = &raw.base {
            for (k, v, lo, hi) in [
                ("base.wheel_radius", b.wheel_radius, 1e-3, 1.0),
                ("base.track", b.track, 1e-2, 5.0),
                ("base.footprint_radius", b.footprint_radius, 1e-2, 5.0),
                ("base.min_wheel_speed", b.min_wheel_speed, 1e-4, 1.0),
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
                (
                    "base.translation_tolerance",
                    b.translation_tolerance,
                    1e-4,
                    1.0,
                ),
                (
                    "base.rotation_tolerance",
                    b.rotation_tolerance,
                    1e-4,
                    std::f64::consts::PI,
                ),
            ] {
                num(file, k, v, lo, hi)?;
            }
            if let Some(g) = &b.odometry {
                if !g.near(&b.nominal_geometry(), 0.1) {
                    return Err(cfg_err(
                        file,
                        "base.odometry",
                        "left_radius, right_radius and track must be within 10 % of wheel_radius and track",
                    ));
                }
            }
        }
        let bus = raw.bus.unwrap_or_default();
        num(file, "bus.baud", bus.baud as f64, 9600.0, 10_500_000.0)?;
        num(
            file,
            "bus.loop_period_us",
            bus.loop_period_us as f64,
            ranges::LOOP_PERIOD_MIN_US as f64,
            ranges::LOOP_PERIOD_MAX_US as f64,
        )?;
        if let Some(c) = &raw.collision {
            for (i, (a, b, why)) in c.disabled.iter().enumerate() {
                for l in [a, b] {
                    if !urdf.links.iter().any(|k| &k.name == l) {
                        return Err(cfg_err(
                            file,
                            format!("collision.disabled[{i}]"),
                            format!("{l:?} is no link of the URDF"),
                        ));
                    }
                }
                if !["adjacent", "default", "always", "never"].contains(&why.as_str()) {
                    return Err(cfg_err(
                        file,
                        format!("collision.disabled[{i}]"),
                        format!("reason {why:?} is not adjacent, default, always or never"),
                    ));
                }
            }
        }
        Ok(RobotConfig {
            name: raw.name,
            file: file.to_path_buf(),
            board_profile: raw.board_profile,
            bus,
            urdf_file: raw.urdf,
            collision: raw.collision,
            urdf,
            arm: raw.arm,
            gripper: raw.gripper,
            camera: raw.camera,
            base: raw.base,
            joints,
            sim_gravity: raw.sim.map(|s| s.gravity).unwrap_or(true),
            arm_chain,
        })
    }

    /// Index of a joint in the firmware's table.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name.as_str() == name)
    }

    /// The firmware profile this configuration asks for.
    pub fn firmware_profile(&self) -> RobotProfile {
        // The base's model gives its encoder, top speed and feedback timing; the description
        // gives its wheel geometry.
        let base = match self.base.as_ref() {
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
        for c in self.name.chars() {
            if robot.push(c).is_err() {
                break;
            }
        }
        RobotProfile {
            robot,
            joints: self.joints.iter().cloned().collect(),
            base,
            gripper: self.gripper.as_ref().map(GripperSection::driver),
            bus: BusConfig::at_baud(self.bus.baud),
            loop_period: Duration::from_micros(u64::from(self.bus.loop_period_us)),
            watchdog_period: Duration::from_millis(500),
            telemetry_period: Duration::from_millis(10),
            // The built-in profile's arm model, for the robots that have one.
            gravity: ferrobot_firmware::config::by_name(&self.name).and_then(|p| p.gravity),
        }
    }

    /// The base kind as the protocol names it.
    pub fn base_kind(&self) -> BaseKind {
        match self.base.as_ref().map(|b| b.kind) {
            Some(BaseModel::Kobuki) => BaseKind::Kobuki,
            Some(BaseModel::Create2) => BaseKind::Create2,
            None => BaseKind::None,
        }
    }
}
