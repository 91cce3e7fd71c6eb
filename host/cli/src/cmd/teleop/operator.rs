//! The robot side of teleoperation: the core's commands executed through the public API
//! (non-blocking motions, so the loop stays live), and the robot's state as it reports it.

use ferrobot::config::IkKind;
use ferrobot::{Motion, MoveOptions, Orientation, Robot};
use ferrobot_teleop::{Action, Command, GripperAction, KeyMap, Step};
use serde::Serialize;

use super::QuitReason;

/// PyRobot's teleoperation start pose of the LoCoBot's 5-joint arm (`teleoperation.py`), rad:
/// bent, away from the straight-up pose where Cartesian steps are singular.
pub const START_ARM: [f64; 5] = [0.0, -0.14, 0.76, 1.07, 0.0];
/// PyRobot's teleoperation start pan and tilt (`teleop.yaml`: `START_PAN`, `START_TILT`), rad.
pub const START_PAN_TILT: [f64; 2] = [0.0, 0.85];

/// What the robot reports, as the screen and the trace show it.
#[derive(Debug, Clone, Default, Serialize)]
pub struct State {
    /// The robot's clock, s.
    pub t: f64,
    /// Arm joint angles, rad (empty without an arm).
    pub arm: Vec<f64>,
    /// End-effector position in the arm's base frame, m.
    pub ee: Option<[f64; 3]>,
    /// Gripper pitch below horizontal (5-joint arms: the sum of the three pitch joints), rad.
    pub pitch: Option<f64>,
    /// Gripper state.
    pub gripper: Option<String>,
    /// Pan and tilt, rad.
    pub head: Option<[f64; 2]>,
    /// Base odometry `[x m, y m, θ rad, v m/s, w rad/s]`.
    pub base: Option<[f64; 5]>,
    /// Faults active now (the firmware's fault flags), then the latest reported (kind and
    /// firmware time).
    pub faults: Vec<String>,
    /// Whether an arm, head or gripper motion is under way.
    pub moving: Vec<&'static str>,
    /// Commands executed so far.
    pub commands: u64,
    /// What the last command did, or why it failed.
    pub last: String,
}

/// What the robot did after a quit.
#[derive(Debug, Clone, Serialize)]
pub struct QuitReport {
    /// The state at the end of the watch.
    pub state: State,
    /// The largest arm joint movement during the watch, rad.
    pub arm_moved: f64,
    /// Whether the base was stopped at the end (|v| < 1 mm/s, |w| < 0.01 rad/s).
    pub base_stopped: bool,
    /// Errors while making the robot safe.
    pub errors: Vec<String>,
}

impl QuitReport {
    /// One line for the terminal once restored.
    pub fn summary(&self, reason: QuitReason) -> String {
        let base = match self.state.base {
            Some(b) if self.base_stopped => {
                format!("base stopped at [{:.3}, {:.3}, {:.3}]", b[0], b[1], b[2])
            }
            Some(b) => format!("base NOT stopped: v {:.3} m/s, w {:.3} rad/s", b[3], b[4]),
            None => "no base".into(),
        };
        let arm = if self.state.arm.is_empty() {
            "no arm".into()
        } else {
            format!(
                "arm holding at {:?} rad (moved {:.4} rad while watched)",
                crate::cmd::common::round(&self.state.arm),
                self.arm_moved
            )
        };
        let errors = if self.errors.is_empty() {
            String::new()
        } else {
            format!("; errors: {}", self.errors.join("; "))
        };
        format!(
            "teleop: quit ({reason:?}) at t = {:.3} s; {base}; {arm}{errors}",
            self.state.t
        )
    }
}

/// The robot under teleoperation: its components, the motions under way, the targets the
/// next steps build on.
pub struct Operator {
    bot: Robot,
    /// The arm's joint names (empty without an arm).
    joints: Vec<String>,
    /// The closed-form pitch-roll IK serves Cartesian steps (5-joint LoCoBot arms).
    pitch_roll: bool,
    arm_motion: Option<Motion>,
    head_motion: Option<Motion>,
    gripper_motion: Option<Motion>,
    /// The arm target last commanded: steps build on it, not on the measured angles, so that
    /// arrival tolerances do not add up.
    arm_target: Option<Vec<f64>>,
    /// The pan and tilt last commanded.
    head_target: Option<[f64; 2]>,
    /// The latest faults reported, oldest first.
    recent: Vec<String>,
    state: State,
}

/// How many reported faults the screen keeps.
const RECENT_FAULTS: usize = 3;

impl Operator {
    /// Teleoperate `bot`.
    pub fn new(bot: Robot) -> ferrobot::Result<Self> {
        let cfg = bot.config();
        let joints = match (&cfg.arm, bot.arm()) {
            (Some(a), Ok(_)) => a.joints.clone(),
            _ => Vec::new(),
        };
        let pitch_roll = cfg
            .arm
            .as_ref()
            .is_some_and(|a| a.ik == IkKind::LocobotPitchRoll);
        let mut op = Operator {
            bot,
            joints,
            pitch_roll,
            arm_motion: None,
            head_motion: None,
            gripper_motion: None,
            arm_target: None,
            head_target: None,
            recent: Vec::new(),
            state: State::default(),
        };
        op.observe();
        Ok(op)
    }

    /// The robot's name.
    pub fn name(&self) -> &str {
        self.bot.name()
    }

    /// The two wrist joints PyRobot's `h`/`j` and `k`/`l` turn: the arm's last two (its
    /// `joint_4` and `joint_5` on a LoCoBot).
    pub fn wrist_joints(&self) -> [String; 2] {
        let n = self.joints.len();
        if n >= 2 {
            [self.joints[n - 2].clone(), self.joints[n - 1].clone()]
        } else {
            ["joint_4".into(), "joint_5".into()]
        }
    }

    /// Whether this robot can do `action` (has the component).
    pub fn can(&self, action: &Action) -> bool {
        match action {
            Action::Step(Step::Ee(_) | Step::Joint { .. } | Step::Reset) => !self.joints.is_empty(),
            Action::Step(Step::Gripper(_)) => self.bot.gripper().is_ok(),
            Action::Step(Step::PanTilt(_)) => self.bot.head().is_ok(),
            Action::Base { .. } => self.bot.base().is_ok(),
            Action::Quit => true,
        }
    }

    /// PyRobot's start: the arm to its teleoperation pose (5-joint arms), the gripper open,
    /// the camera to its start pan and tilt. A failure is shown, not fatal.
    pub fn start_pose(&mut self) {
        let mut errors = Vec::new();
        if self.pitch_roll && self.joints.len() == START_ARM.len() {
            match self
                .bot
                .arm()
                .and_then(|a| a.set_joint_positions(&START_ARM))
            {
                Ok(()) => self.arm_target = Some(START_ARM.to_vec()),
                Err(e) => errors.push(format!("start pose: {e}")),
            }
        }
        if let Ok(g) = self.bot.gripper() {
            if let Err(e) = g.open() {
                errors.push(format!("gripper: {e}"));
            }
        }
        if let Ok(h) = self.bot.head() {
            let [p, t] = START_PAN_TILT;
            match h.set_pan_tilt(p, t) {
                Ok(()) => self.head_target = Some(START_PAN_TILT),
                Err(e) => errors.push(format!("head: {e}")),
            }
        }
        self.observe();
        self.state.last = if errors.is_empty() {
            "ready".into()
        } else {
            errors.join("; ")
        };
    }

    /// The robot's clock, s.
    pub fn time(&self) -> f64 {
        self.bot.time()
    }

    /// Let `seconds` of robot time pass (the motions under way go on).
    pub fn wait(&self, seconds: f64) {
        if let Err(e) = self.bot.wait(seconds) {
            eprintln!("teleop: wait: {e}");
        }
    }

    /// The state as last observed.
    pub fn state(&self) -> State {
        self.state.clone()
    }

    /// Execute one command of the core; the result shows in [`State::last`].
    pub fn execute(&mut self, c: &Command, map: &KeyMap) {
        let r = match c {
            Command::Step(Step::Ee(d)) => self.ee_step(*d),
            Command::Step(Step::Joint { joint, delta }) => self.joint_step(joint, *delta),
            Command::Step(Step::Gripper(g)) => self.gripper(*g),
            Command::Step(Step::PanTilt(d)) => self.pan_tilt(*d),
            Command::Step(Step::Reset) => self.reset(),
            Command::BaseVelocity { v, w } => self
                .bot
                .base()
                .and_then(|b| b.set_vel_async(*v, *w, ferrobot::validate::MAX_DURATION_S))
                .map(|m| {
                    // The velocity runs until the next base command preempts it.
                    drop(m);
                    format!("v {v:.3} m/s, w {w:.3} rad/s")
                }),
            Command::BaseStop => self
                .bot
                .base()
                .and_then(|b| b.stop())
                .map(|()| "stop".into()),
            Command::Quit => Ok("stopping the base, holding the arm".into()),
        };
        let what = describe(c, map);
        self.state.commands += 1;
        self.state.last = match r {
            Ok(s) => format!("{what}: {s}"),
            Err(e) => format!("{what}: refused: {e}"),
        };
    }

    /// A value of the arm's description (the default without an arm).
    fn arm_config<T: Default>(&self, f: impl Fn(&ferrobot::config::ArmConfig) -> T) -> T {
        self.bot.config().arm.as_ref().map(f).unwrap_or_default()
    }

    /// The arm's joints the next step builds on: the last target, else the measured angles.
    fn arm_base(&self) -> ferrobot::Result<Vec<f64>> {
        match &self.arm_target {
            Some(q) => Ok(q.clone()),
            None => self.bot.arm()?.get_joint_angles(),
        }
    }

    fn ee_step(&mut self, d: [f64; 3]) -> ferrobot::Result<String> {
        let arm = self.bot.arm()?;
        let q0 = self.arm_base()?;
        let ee = self.arm_config(|a| a.ee_frame.clone());
        let start = arm.compute_fk_position(&q0, &ee)?;
        let p = [
            start.position[0] + d[0],
            start.position[1] + d[1],
            start.position[2] + d[2],
        ];
        let q = if self.pitch_roll {
            // The gripper's pitch is the sum of the three pitch joints; roll stays with the
            // wrist (as `Arm::move_ee_xyz` keeps them).
            let pitch = q0[1] + q0[2] + q0[3];
            arm.compute_ik_pitch_roll(p, pitch, None, Some(&q0))?
        } else {
            arm.compute_ik(p, Orientation::Quaternion(start.quaternion), Some(&q0))?
        };
        self.move_arm(q)?;
        Ok(format!("to [{:.4}, {:.4}, {:.4}] m", p[0], p[1], p[2]))
    }

    fn joint_step(&mut self, joint: &str, delta: f64) -> ferrobot::Result<String> {
        let k = self.joints.iter().position(|j| j == joint).ok_or_else(|| {
            ferrobot::Error::UnknownName {
                what: "arm joint",
                name: joint.to_string(),
            }
        })?;
        let mut q = self.arm_base()?;
        q[k] += delta;
        let to = q[k];
        self.move_arm(q)?;
        Ok(format!("{joint} to {to:.4} rad"))
    }

    /// Start a planned move to `q` (collision-free against the arm's planning scene and
    /// itself, timed under the joints' limits).
    fn move_arm(&mut self, q: Vec<f64>) -> ferrobot::Result<()> {
        let arm = self.bot.arm()?;
        self.arm_motion = Some(arm.move_joints(&q, MoveOptions::default())?);
        self.arm_target = Some(q);
        Ok(())
    }

    fn reset(&mut self) -> ferrobot::Result<String> {
        let home = self.arm_config(|a| a.home.clone());
        self.move_arm(home)?;
        Ok("arm to home".into())
    }

    fn gripper(&mut self, g: GripperAction) -> ferrobot::Result<String> {
        let gripper = self.bot.gripper()?;
        self.gripper_motion = Some(match g {
            GripperAction::Open => gripper.open_async()?,
            GripperAction::Close => gripper.close_async()?,
        });
        Ok("started".into())
    }

    fn pan_tilt(&mut self, d: [f64; 2]) -> ferrobot::Result<String> {
        let head = self.bot.head()?;
        let [p0, t0] = match self.head_target {
            Some(h) => h,
            None => head.get_state()?,
        };
        let (p, t) = (p0 + d[0], t0 + d[1]);
        self.head_motion = Some(head.set_pan_tilt_async(p, t)?);
        self.head_target = Some([p, t]);
        Ok(format!("pan {p:.4}, tilt {t:.4} rad"))
    }

    /// Read the robot's state (telemetry, faults) and the results of finished motions.
    pub fn observe(&mut self) {
        let mut moving = Vec::new();
        for (name, slot) in [
            ("arm", &mut self.arm_motion),
            ("head", &mut self.head_motion),
            ("gripper", &mut self.gripper_motion),
        ] {
            let Some(m) = slot.take() else { continue };
            if !m.is_finished() {
                moving.push(name);
                *slot = Some(m);
            } else if let Err(e) = m.wait() {
                self.state.last = format!("{name} motion: {e}");
                match name {
                    "arm" => self.arm_target = None,
                    "head" => self.head_target = None,
                    _ => {}
                }
            }
        }
        self.state.moving = moving;
        self.state.t = self.bot.time();
        let Ok(tel) = self.bot.telemetry() else {
            self.state.faults = vec!["no telemetry".into()];
            return;
        };
        if let Ok(arm) = self.bot.arm() {
            if let Ok(q) = arm.get_joint_angles() {
                self.state.ee = arm.get_ee_pose().ok().map(|p| p.position);
                self.state.pitch = (self.pitch_roll && q.len() >= 4).then(|| q[1] + q[2] + q[3]);
                self.state.arm = q;
            }
        }
        self.state.gripper = self
            .bot
            .gripper()
            .ok()
            .map(|_| format!("{:?}", tel.gripper));
        self.state.head = self.bot.head().ok().and_then(|h| h.get_state().ok());
        if self.bot.base().is_ok() {
            let o = tel.odometry;
            self.state.base = Some([o.x, o.y, o.theta, o.v, o.w].map(f64::from));
        }
        for f in self.bot.take_faults() {
            if self.recent.len() == RECENT_FAULTS {
                self.recent.remove(0);
            }
            self.recent
                .push(format!("{:?} at {:.3} s", f.kind, f.time_us as f64 * 1e-6));
        }
        let mut faults = fault_names(tel.faults);
        faults.extend(self.recent.iter().cloned());
        self.state.faults = faults;
    }

    /// Make the robot safe: stop the base, stop every arm and head motion where it is (the
    /// joints hold), then watch it for `settle` s. Errors are reported, not fatal.
    pub fn quit(&mut self, settle: f64) -> QuitReport {
        let mut errors = Vec::new();
        if let Ok(base) = self.bot.base() {
            if let Err(e) = base.stop() {
                errors.push(format!("base stop: {e}"));
            }
        }
        for m in [self.arm_motion.take(), self.head_motion.take()]
            .into_iter()
            .flatten()
        {
            if let Err(e) = m.cancel() {
                errors.push(format!("hold: {e}"));
            }
        }
        self.observe();
        let before = self.state.arm.clone();
        if let Err(e) = self.bot.wait(settle) {
            errors.push(format!("watch: {e}"));
        }
        self.observe();
        let arm_moved = before
            .iter()
            .zip(&self.state.arm)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let base_stopped = self
            .state
            .base
            .is_none_or(|b| b[3].abs() < 1e-3 && b[4].abs() < 0.01);
        QuitReport {
            state: self.state.clone(),
            arm_moved,
            base_stopped,
            errors,
        }
    }
}

/// What a command is, in the key map's words (a step by its key and label).
fn describe(c: &Command, map: &KeyMap) -> String {
    let found = match c {
        Command::Step(step) => map
            .bindings
            .iter()
            .find(|b| matches!(&b.action, Action::Step(s) if s == step))
            .map(|b| format!("{} ({})", b.key, b.label)),
        Command::BaseVelocity { .. } | Command::BaseStop => Some("base".into()),
        Command::Quit => Some("quit".into()),
    };
    found.unwrap_or_else(|| format!("{c:?}"))
}

/// The names of the firmware's fault flags that are set.
fn fault_names(flags: u16) -> Vec<String> {
    use ferrobot::fault_flags::*;
    [
        (ESTOP, "emergency stop"),
        (WATCHDOG, "host watchdog"),
        (SERVO_LOST, "servo lost"),
        (SERVO_HARDWARE, "servo hardware error"),
        (BASE_LOST, "base lost"),
        (BASE_SAFETY, "bumper/cliff/wheel drop"),
    ]
    .iter()
    .filter(|(bit, _)| flags & bit != 0)
    .map(|(_, name)| name.to_string())
    .collect()
}
