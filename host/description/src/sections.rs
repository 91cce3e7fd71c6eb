//! The sections of a robot's TOML as written (`[arm]`, `[gripper]`, `[bus]`, `[camera]`,
//! `[sim]`, `[collision]`), strict: an unknown key or a wrong type is an error. Lengths in m,
//! angles in rad, gripper positions in servo ticks.

use serde::Deserialize;

use crate::base::BaseSection;
use crate::joints::JointSection;

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
pub(crate) struct ConfigFile {
    pub(crate) name: String,
    pub(crate) urdf: String,
    pub(crate) board_profile: Option<String>,
    pub(crate) arm: Option<ArmConfig>,
    pub(crate) gripper: Option<GripperSection>,
    pub(crate) camera: Option<CameraSection>,
    pub(crate) base: Option<BaseSection>,
    pub(crate) bus: Option<BusSection>,
    pub(crate) direct: Option<crate::direct::DirectSection>,
    #[serde(rename = "joint", default)]
    pub(crate) joints: Vec<JointSection>,
    pub(crate) sim: Option<SimSection>,
    pub(crate) collision: Option<CollisionSection>,
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
