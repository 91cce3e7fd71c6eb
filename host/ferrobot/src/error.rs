//! The one error type of the `ferrobot` crate: every failure says what, which value and which
//! limit.

use std::path::PathBuf;
use std::time::Duration;

use ferrobot_protocol::{FaultKind, RejectReason};

/// Everything that can go wrong.
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
    #[error("{file}: {key}: {problem}")]
    Config {
        /// The file.
        file: PathBuf,
        /// The key (dotted path) concerned, or `-` for the whole file.
        key: String,
        /// What is wrong.
        problem: String,
    },
    /// The robot has no such component.
    #[error("the robot {robot:?} has no {component}")]
    NoComponent {
        /// Robot name.
        robot: String,
        /// `arm`, `gripper`, `base`, `camera`.
        component: &'static str,
    },
    /// A vector has the wrong number of joints.
    #[error("{what}: expected {expected} values, got {got}")]
    JointCount {
        /// What was passed.
        what: &'static str,
        /// How many the arm has.
        expected: usize,
        /// How many were given.
        got: usize,
    },
    /// A NaN or infinite value.
    #[error("{what} is not a finite number: {value}")]
    NotFinite {
        /// What.
        what: String,
        /// The value.
        value: f64,
    },
    /// A finite number outside what the API accepts (an absurd duration, distance, size or
    /// count); the range is in [`crate::validate`].
    #[error("{what} = {} is outside the accepted range [{}, {}]", num(*value), num(*min), num(*max))]
    OutOfRange {
        /// What.
        what: String,
        /// The value.
        value: f64,
        /// Smallest accepted.
        min: f64,
        /// Largest accepted.
        max: f64,
    },
    /// A joint target beyond the joint's limits.
    #[error("joint {joint} target {value:.4} is outside its limits [{min:.4}, {max:.4}]")]
    OutOfLimits {
        /// Joint name.
        joint: String,
        /// Target.
        value: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
    /// No joint configuration reaches the pose.
    #[error("unreachable pose: {why}")]
    Unreachable {
        /// Why.
        why: String,
    },
    /// An occupancy-grid map that cannot be used.
    #[error("invalid map: {why}")]
    InvalidMap {
        /// Why.
        why: String,
    },
    /// Odometry calibration could not determine the base's geometry.
    #[error("odometry calibration failed: {why}")]
    Calibration {
        /// Why.
        why: String,
    },
    /// An unknown joint or frame name.
    #[error("unknown {what} {name:?}")]
    UnknownName {
        /// `joint` or `frame`.
        what: &'static str,
        /// The name.
        name: String,
    },
    /// A motion did not finish in time.
    #[error("{what} did not finish within {after:?}")]
    Timeout {
        /// What.
        what: String,
        /// The timeout.
        after: Duration,
    },
    /// A joint stopped moving short of its target.
    #[error("joint {joint} stalled at {position:.4} rad, {error:.4} rad from its target")]
    Stalled {
        /// Joint name.
        joint: String,
        /// Where it stopped.
        position: f64,
        /// Remaining error.
        error: f64,
    },
    /// The firmware refused a command.
    #[error("the firmware rejected {what}: {reason:?}")]
    Rejected {
        /// What was sent.
        what: String,
        /// Its reason.
        reason: RejectReason,
    },
    /// An emergency stop is active.
    #[error("an emergency stop is active; call resume() first")]
    EmergencyStop,
    /// A newer motion of the same joints, base or gripper took over; this one was stopped.
    #[error("{what} was preempted by a newer motion of the same component")]
    Preempted {
        /// The motion that was preempted.
        what: String,
    },
    /// A fault stopped the motion.
    #[error("motion aborted by a {kind:?} fault{}", detail.as_deref().map(|d| format!(": {d}")).unwrap_or_default())]
    Fault {
        /// The fault.
        kind: FaultKind,
        /// Details (joint, sensor bits).
        detail: Option<String>,
    },
    /// The motion was cancelled through its handle.
    #[error("motion cancelled")]
    Cancelled,
    /// Host and firmware speak different protocol versions or schemas.
    #[error("protocol mismatch: host speaks version {host} (schema {host_schema:#010x}), firmware {firmware} (schema {firmware_schema:#010x})")]
    VersionMismatch {
        /// Host protocol version.
        host: u16,
        /// Host schema hash.
        host_schema: u32,
        /// Firmware protocol version.
        firmware: u16,
        /// Firmware schema hash.
        firmware_schema: u32,
    },
    /// The firmware runs another robot's profile than the configuration describes.
    #[error("the firmware runs the {firmware:?} profile (base {firmware_base}), the configuration describes {config:?} (base {config_base})")]
    WrongRobot {
        /// The configuration's robot name.
        config: String,
        /// The configuration's base kind.
        config_base: String,
        /// The robot the firmware named in its Hello.
        firmware: String,
        /// The firmware's base kind.
        firmware_base: String,
    },
    /// The firmware's joint table does not match the robot configuration.
    #[error("the firmware's joint table does not match the configuration: {0}")]
    JointTableMismatch(String),
    /// A planned trajectory that no longer holds when it is to run: it starts away from where
    /// the arm is, or it touches something in the scene as it is now (an object added, the
    /// gripper opened since planning). Plan again.
    #[error("the plan no longer holds: {why}; plan again")]
    StalePlan {
        /// What changed.
        why: String,
    },
    /// The link to the firmware is down.
    #[error("link to the firmware lost: {0}")]
    Link(String),
    /// Arguments that do not make a request (a missing or conflicting choice).
    #[error("{0}")]
    Usage(String),
    /// SLAM has no confirmed pose: lost for the last `frames` camera frames (matched to
    /// nothing, with no odometry to carry it), or not yet found in the saved map it localises
    /// in. It is found again by relocalisation once a mapped view returns.
    #[error("SLAM is lost: no confirmed pose for the last {frames} frame(s) (it relocalises once a mapped view returns)")]
    SlamLost {
        /// Frames in a row without a confirmed pose.
        frames: usize,
    },
    /// The hardware check of a robot on its own cables failed: nothing moves until it passes
    /// (`ferrobot hardware check ROBOT` prints the table with the fixes).
    #[error("the hardware check failed: {}; nothing moves until it passes", faults.join("; "))]
    HardwareCheck {
        /// Each fault with its fix.
        faults: Vec<String>,
        /// The whole table, as `ferrobot hardware check` prints it.
        table: String,
    },
    /// A path the program would create already exists: nothing is removed or replaced.
    #[error("{} already exists; refusing to replace it", path.display())]
    PathExists {
        /// The path.
        path: PathBuf,
    },
    #[cfg(feature = "sim")]
    /// A scene that cannot be loaded or placed (unknown name, malformed file, an object where
    /// the robot stands).
    #[error("scene: {0}")]
    Scene(#[from] ferrobot_sim::scene::SceneError),
    /// A bad image, pixel, depth range, cloud, file or parameter in perception, or what
    /// perception could not find (no table plane).
    #[error("perception: {0}")]
    Perception(ferrobot_perception::PerceptionError),
    /// Arm planning refused or failed: a malformed scene object, a start or goal in
    /// collision (naming the two bodies), no collision-free IK solution, no path within the
    /// time limit, a straight line that cannot be followed.
    #[error("planning: {0}")]
    Planning(#[from] ferrobot_planning::Error),
    /// Navigation on a map refused or failed: a map file that cannot be read, a path's end
    /// off the map or too near an obstacle, no path.
    #[error("navigation: {0}")]
    Navigation(ferrobot_nav::Error),
    /// SLAM refused its input: settings, a frame, a trajectory or dataset file.
    #[error("SLAM: {0}")]
    Slam(#[from] ferrobot_slam::Error),
    /// An I/O error.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Whether the caller's input is at fault (a bad value, name, count or file), as opposed
    /// to the robot, the link or the world: the command line exits with code 2 for these.
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            Error::UnknownRobot { .. }
                | Error::Config { .. }
                | Error::NoComponent { .. }
                | Error::JointCount { .. }
                | Error::NotFinite { .. }
                | Error::OutOfRange { .. }
                | Error::OutOfLimits { .. }
                | Error::InvalidMap { .. }
                | Error::UnknownName { .. }
                | Error::PathExists { .. }
                | Error::Usage(_)
                | Error::Planning(ferrobot_planning::Error::Invalid { .. })
                | Error::Slam(_)
        ) || self.is_scene_error()
            || matches!(self, Error::Navigation(e) if e.is_input())
            || matches!(self, Error::Perception(e) if e.is_input())
    }
}

impl Error {
    /// Whether this is a scene's error (a simulated world's file or name: the caller's input).
    fn is_scene_error(&self) -> bool {
        #[cfg(feature = "sim")]
        if matches!(self, Error::Scene(_)) {
            return true;
        }
        false
    }
}

pub(crate) use ferrobot_geometry::validate::num;

// The errors of the crates below the API map onto the API's own variants, so a program
// matches one enum whichever layer refused.

impl From<ferrobot_geometry::ValueError> for Error {
    fn from(e: ferrobot_geometry::ValueError) -> Self {
        use ferrobot_geometry::ValueError as V;
        match e {
            V::NotFinite { what, value } => Error::NotFinite { what, value },
            V::OutOfRange {
                what,
                value,
                min,
                max,
            } => Error::OutOfRange {
                what,
                value,
                min,
                max,
            },
            V::Length {
                what,
                expected,
                got,
            } => Error::JointCount {
                what,
                expected,
                got,
            },
            other => Error::OutOfRange {
                what: other.to_string(),
                value: f64::NAN,
                min: f64::NAN,
                max: f64::NAN,
            },
        }
    }
}

impl From<ferrobot_description::Error> for Error {
    fn from(e: ferrobot_description::Error) -> Self {
        use ferrobot_description::Error as D;
        match e {
            D::UnknownRobot { name, known } => Error::UnknownRobot { name, known },
            D::Config { file, key, problem } => Error::Config { file, key, problem },
            D::UnknownName { what, name } => Error::UnknownName { what, name },
            other => Error::Config {
                file: PathBuf::from("-"),
                key: "-".into(),
                problem: other.to_string(),
            },
        }
    }
}

impl From<ferrobot_kinematics::Error> for Error {
    fn from(e: ferrobot_kinematics::Error) -> Self {
        use ferrobot_kinematics::Error as K;
        match e {
            K::Value(v) => v.into(),
            K::Unreachable { why } => Error::Unreachable { why },
            K::UnknownName { what, name } => Error::UnknownName { what, name },
            other => Error::Unreachable {
                why: other.to_string(),
            },
        }
    }
}

impl From<ferrobot_control::Error> for Error {
    fn from(e: ferrobot_control::Error) -> Self {
        use ferrobot_control::Error as C;
        match e {
            C::Value(v) => v.into(),
            C::Calibration { why } => Error::Calibration { why },
            other => Error::Calibration {
                why: other.to_string(),
            },
        }
    }
}

impl From<ferrobot_nav::Error> for Error {
    fn from(e: ferrobot_nav::Error) -> Self {
        use ferrobot_nav::Error as N;
        match e {
            N::Value(v) => v.into(),
            N::InvalidMap { why } => Error::InvalidMap { why },
            other => Error::Navigation(other),
        }
    }
}

/// Check that every value is finite.
pub(crate) fn check_finite(what: &str, values: &[f64]) -> Result<()> {
    Ok(crate::validate::finite(what, values)?)
}
