//! The arm: joint control (position, velocity, torque), forward and inverse kinematics, and
//! end-effector motions. Joint vectors are in the order of the configuration's `arm.joints`;
//! poses are of the end-effector frame in the arm's base frame (`base_link` on the LoCoBots,
//! `base` on Sawyer).

use std::time::Duration;

use ferrobot_protocol::{HostMsg, JointMode, JointState};
use nalgebra::{Isometry3, Matrix3, Rotation3, UnitQuaternion, Vector3};

use std::sync::Arc;

use crate::arm_parts::ArmParts;
use crate::error::{check_finite, Error, Result};
use crate::goals::Claim;
use crate::hub::Hub;
use crate::joints_goal::JointsGoal;
use crate::kinematics::Chain;
use crate::motion::Motion;
use crate::robot::Robot;
use crate::validate;

/// A pose: position (m), rotation matrix and quaternion `[x, y, z, w]` of a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Position, m.
    pub position: [f64; 3],
    /// Rotation matrix, rows.
    pub rotation: [[f64; 3]; 3],
    /// Unit quaternion `[x, y, z, w]`.
    pub quaternion: [f64; 4],
}

impl From<Isometry3<f64>> for Pose {
    fn from(t: Isometry3<f64>) -> Self {
        let m = t.rotation.to_rotation_matrix();
        let m = m.matrix();
        let q = t.rotation.coords;
        Pose {
            position: [t.translation.x, t.translation.y, t.translation.z],
            rotation: [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ],
            quaternion: [q.x, q.y, q.z, q.w],
        }
    }
}

/// How far from orthonormal a rotation matrix may be (`‖MᵀM − I‖`, Frobenius): a rotation
/// written to four decimals, as PyRobot's programs write them, is within it; the nearest
/// rotation is used.
pub const ROTATION_MATRIX_TOLERANCE: f64 = 1e-3;

/// An orientation, in whichever form is at hand.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Orientation {
    /// Unit quaternion `[x, y, z, w]`: its norm must be 1 within
    /// [`validate::QUATERNION_NORM_TOLERANCE`] (a far-from-unit one is refused).
    Quaternion([f64; 4]),
    /// Euler angles `[yaw, pitch, roll]`, rad: `R = Rz(yaw)·Ry(pitch)·Rx(roll)`.
    YawPitchRoll([f64; 3]),
    /// Rotation matrix, rows: orthonormal within [`ROTATION_MATRIX_TOLERANCE`], det +1.
    Matrix([[f64; 3]; 3]),
}

impl Orientation {
    /// As a unit quaternion; an error for a quaternion far from unit norm, absurd angles, or a
    /// matrix that is not a rotation.
    pub fn to_quaternion(&self) -> Result<UnitQuaternion<f64>> {
        match *self {
            Orientation::Quaternion(q) => Ok(validate::unit_quaternion(q)?),
            Orientation::YawPitchRoll([y, p, r]) => {
                validate::angles("yaw-pitch-roll", &[y, p, r])?;
                Ok(UnitQuaternion::from_euler_angles(r, p, y))
            }
            Orientation::Matrix(m) => {
                check_finite("rotation matrix", &m.concat())?;
                let mm = Matrix3::from_row_slice(&m.concat());
                let orth = (mm.transpose() * mm - Matrix3::identity()).norm();
                if orth > ROTATION_MATRIX_TOLERANCE || mm.determinant() < 0.0 {
                    return Err(Error::Unreachable {
                        why: format!(
                            "the matrix is not a rotation (orthonormal within {ROTATION_MATRIX_TOLERANCE}, det +1)"
                        ),
                    });
                }
                // The nearest rotation: a matrix printed to four decimals is one within the
                // tolerance.
                let r = Rotation3::from_matrix_eps(&mm, 1e-12, 100, Rotation3::identity());
                Ok(UnitQuaternion::from_rotation_matrix(&r))
            }
        }
    }
}

/// Options of a joint-space move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveOptions {
    /// Plan (true, PyRobot's default): a collision-free path around the planning scene and
    /// the arm itself, timed optimally under the joints' speed and acceleration limits; or
    /// send the target at once and let the firmware's rate limiter take the joints there
    /// (false).
    pub plan: bool,
    /// Arrival tolerance per joint, rad, in `[1e-4, 0.5]`; the configuration's when `None`.
    pub tolerance: Option<f64>,
    /// Give up after this long (at most [`validate::MAX_DURATION_S`]); the configuration's
    /// when `None`.
    pub timeout: Option<Duration>,
}

impl Default for MoveOptions {
    fn default() -> Self {
        Self {
            plan: true,
            tolerance: None,
            timeout: None,
        }
    }
}

/// The arm of a [`Robot`]: a handle (clone of the robot's), so arm motions run while other
/// components move.
#[derive(Clone, Debug)]
pub struct Arm {
    pub(crate) robot: Robot,
}

impl Arm {
    pub(crate) fn new(robot: Robot) -> Self {
        Arm { robot }
    }

    pub(crate) fn parts(&self) -> &ArmParts {
        // Present: `Robot::arm` checks it.
        self.robot.arm_parts().expect("arm parts")
    }

    /// The arm's kinematic chain, base frame to end effector.
    pub(crate) fn chain(&self) -> Result<&crate::kinematics::Chain> {
        Ok(&self.parts().chain)
    }

    pub(crate) fn cfg_arm(&self) -> &crate::config::ArmConfig {
        self.cfg()
    }

    /// Firmware indices of the arm's joints, base to tip.
    pub(crate) fn parts_joints(&self) -> &[usize] {
        &self.parts().joints
    }

    /// Joint count, finiteness and limits of a goal.
    pub(crate) fn check_goal(&self, q: &[f64]) -> Result<()> {
        self.check_angles("joint positions", q)?;
        self.check_limits(q)
    }

    /// Switch the arm's joints to position mode unless they are in it.
    pub(crate) fn ensure_position_mode(&self, io: &mut Hub) -> Result<()> {
        self.ensure_mode(io, JointMode::Position)
    }

    pub(crate) fn cfg(&self) -> &crate::config::ArmConfig {
        // Present: `Robot::arm` checks it.
        self.robot.cfg().arm.as_ref().expect("arm config")
    }

    /// A chain from the arm's base frame to `frame`, cached.
    pub(crate) fn chain_to(&self, frame: &str) -> Result<Arc<Chain>> {
        let mut chains = self.parts().chains.lock();
        if let Some(c) = chains.get(frame) {
            return Ok(c.clone());
        }
        let c = Arc::new(Chain::from_urdf(
            &self.robot.cfg().urdf,
            &self.cfg().base_frame,
            frame,
        )?);
        chains.insert(frame.to_string(), c.clone());
        Ok(c)
    }

    /// Number of arm joints.
    pub fn dof(&self) -> usize {
        self.parts().joints.len()
    }

    /// Arm joint names, base to tip.
    pub fn joint_names(&self) -> Vec<String> {
        self.cfg().joints.clone()
    }

    pub(crate) fn check_count(&self, what: &'static str, v: &[f64]) -> Result<()> {
        if v.len() != self.dof() {
            return Err(Error::JointCount {
                what,
                expected: self.dof(),
                got: v.len(),
            });
        }
        check_finite(what, v)
    }

    /// Joint angles: the arm's count, each finite and within ±[`validate::MAX_ANGLE`].
    pub(crate) fn check_angles(&self, what: &'static str, q: &[f64]) -> Result<()> {
        self.check_count(what, q)?;
        Ok(validate::angles(what, q)?)
    }

    pub(crate) fn check_limits(&self, q: &[f64]) -> Result<()> {
        for (&j, &v) in self.parts().joints.iter().zip(q) {
            let c = &self.robot.cfg().joints[j];
            let (lo, hi) = (c.limits.min as f64, c.limits.max as f64);
            if v < lo - 1e-9 || v > hi + 1e-9 {
                return Err(Error::OutOfLimits {
                    joint: c.name.to_string(),
                    value: v,
                    min: lo,
                    max: hi,
                });
            }
        }
        Ok(())
    }

    /// Switch the arm's joints to `mode` unless they are in it.
    pub(crate) fn ensure_mode(&self, io: &mut Hub, mode: JointMode) -> Result<()> {
        let mut current = self.parts().mode.lock();
        if current.unwrap_or(JointMode::Position) != mode {
            io.set_mode(&self.parts().joints, mode)?;
            *current = Some(mode);
        }
        Ok(())
    }

    pub(crate) fn states_in(&self, io: &mut Hub) -> Result<Vec<JointState>> {
        let t = io.link.telemetry()?;
        Ok(self
            .parts()
            .joints
            .iter()
            .map(|&j| t.joints.get(j).copied().unwrap_or_default())
            .collect())
    }

    pub(crate) fn states(&self) -> Result<Vec<JointState>> {
        self.states_in(&mut self.robot.lock_hub())
    }

    /// Start moving to joint positions `q` (rad); returns the motion under way. An arm motion
    /// still under way is preempted. With planning, a plan the arm moved away from while it
    /// was made (an older motion drove it, or it settled) is made again from where the arm
    /// has come to rest ([`Arm::execute`] would refuse it as stale).
    pub fn move_joints(&self, q: &[f64], opts: MoveOptions) -> Result<Motion> {
        self.check_angles("joint positions", q)?;
        self.check_limits(q)?;
        if let Some(t) = opts.tolerance {
            validate::in_range("joint tolerance", t, 1e-4, 0.5)?;
        }
        let timeout = match opts.timeout {
            Some(t) => validate::timeout("arm motion timeout", t)?,
            None => Duration::from_secs_f64(self.cfg().timeout),
        };
        let tolerance = opts.tolerance.unwrap_or(self.cfg().joint_tolerance);
        if opts.plan {
            return self.plan_and_execute(q, tolerance, opts.timeout.map(|_| timeout));
        }
        let parts = self.parts();
        let claim = Claim {
            joints: parts.mask(),
            ..Claim::default()
        };
        self.robot
            .start_motion(claim, "arm joint motion", |io: &mut Hub| {
                self.ensure_mode(io, JointMode::Position)?;
                let now = self.states_in(io)?;
                // A cubic between rest states peaks at 1.5·Δq/T: choose T so that no joint
                // exceeds 90 % of its speed limit.
                let mut t = 0.0f64;
                for ((&j, &target), s) in parts.joints.iter().zip(q).zip(&now) {
                    let v = self.robot.cfg().joints[j].limits.velocity as f64;
                    t = t.max(1.5 * (target - s.position as f64).abs() / (0.9 * v));
                }
                let duration = if opts.plan { t.max(0.2) } else { 0.0 };
                io.send_rest_waypoint(
                    parts.mask(),
                    q.iter().copied(),
                    duration,
                    "arm joint target",
                )?;
                let started = io.link.now();
                let goal = JointsGoal::new(
                    parts.joints.clone(),
                    q.to_vec(),
                    tolerance,
                    started,
                    started + Duration::from_secs_f64(duration),
                );
                Ok((Box::new(goal) as Box<dyn crate::goals::Goal>, timeout))
            })
    }

    /// Move to joint positions `q` (rad) on a planned trajectory and wait until every joint is
    /// within the arrival tolerance.
    pub fn set_joint_positions(&self, q: &[f64]) -> Result<()> {
        self.move_joints(q, MoveOptions::default())?.wait()
    }

    /// [`Arm::set_joint_positions`] with options.
    pub fn set_joint_positions_with(&self, q: &[f64], opts: MoveOptions) -> Result<()> {
        self.move_joints(q, opts)?.wait()
    }

    /// Send one direct value per arm joint in `mode`, each within ±`limit` of its joint.
    pub(crate) fn direct(
        &self,
        what: &'static str,
        values: &[f64],
        limit: fn(&crate::config::JointLimits) -> f32,
        mode: JointMode,
    ) -> Result<()> {
        self.check_count(what, values)?;
        for (&j, &v) in self.parts().joints.iter().zip(values) {
            let c = &self.robot.cfg().joints[j];
            let l = limit(&c.limits) as f64;
            if v.abs() > l + 1e-9 {
                return Err(Error::OutOfLimits {
                    joint: c.name.to_string(),
                    value: v,
                    min: -l,
                    max: l,
                });
            }
        }
        let joints = self.parts().mask();
        let values = values.iter().map(|&v| v as f32).collect();
        let mut io = self.robot.lock_hub();
        // Direct commands take the joints over from any arm motion under way.
        io.prepare(
            self.robot.cfg(),
            Claim {
                joints,
                ..Claim::default()
            },
        );
        self.ensure_mode(&mut io, mode)?;
        io.link
            .command(&HostMsg::JointCommand { joints, values }, what)
    }

    /// Send one rest knot of the Cartesian path, waiting while the firmware's queue is full
    /// (the motions under way go on meanwhile). The queue's fill is known from telemetry,
    /// which lags the knots just sent, so a full queue shows as a `QueueFull` rejection: then
    /// let a knot play out and send again, for at most `timeout` without progress.
    pub(crate) fn send_when_queued(
        &self,
        q: &[f64],
        seconds: f64,
        timeout: Duration,
    ) -> Result<()> {
        let mask = self.parts().mask();
        let since = self.robot.lock_hub().link.now();
        loop {
            let mut io = self.robot.lock_hub();
            // Keep the firmware queue short: send while telemetry shows it not nearly full, and
            // after the timeout in any case (its rejection is then the answer).
            let waited_out = io.link.now().saturating_sub(since) > timeout;
            if waited_out || (io.link.telemetry()?.queued as usize) < 8 * self.dof() {
                match io.send_rest_waypoint(mask, q.iter().copied(), seconds, "Cartesian waypoint")
                {
                    Err(Error::Rejected {
                        reason: ferrobot_protocol::RejectReason::QueueFull,
                        ..
                    }) if !waited_out => {}
                    r => return r,
                }
            }
            drop(io);
            self.robot.wait_for(Duration::from_millis(20));
        }
    }

    /// Command joint velocities (rad/s); the arm switches to velocity control and keeps them
    /// until told otherwise (the firmware brakes at the position limits).
    pub fn set_joint_velocities(&self, qd: &[f64]) -> Result<()> {
        self.direct("joint velocities", qd, |l| l.velocity, JointMode::Velocity)
    }

    /// Command joint torques (N·m); the arm switches to current control.
    pub fn set_joint_torques(&self, tau: &[f64]) -> Result<()> {
        self.direct("joint torques", tau, |l| l.effort, JointMode::Current)
    }

    /// Measured joint angles, rad.
    pub fn get_joint_angles(&self) -> Result<Vec<f64>> {
        Ok(self.states()?.iter().map(|s| s.position as f64).collect())
    }

    /// Measured joint velocities, rad/s.
    pub fn get_joint_velocities(&self) -> Result<Vec<f64>> {
        Ok(self.states()?.iter().map(|s| s.velocity as f64).collect())
    }

    /// Measured joint torques, N·m.
    pub fn get_joint_torques(&self) -> Result<Vec<f64>> {
        Ok(self.states()?.iter().map(|s| s.effort as f64).collect())
    }

    pub(crate) fn by_name(&self, name: &str) -> Result<JointState> {
        let k = self
            .cfg()
            .joints
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| Error::UnknownName {
                what: "joint",
                name: name.to_string(),
            })?;
        Ok(self.states()?[k])
    }

    /// Measured angle of one joint by name, rad.
    pub fn get_joint_angle(&self, name: &str) -> Result<f64> {
        Ok(self.by_name(name)?.position as f64)
    }

    /// Measured velocity of one joint by name, rad/s.
    pub fn get_joint_velocity(&self, name: &str) -> Result<f64> {
        Ok(self.by_name(name)?.velocity as f64)
    }

    /// Measured torque of one joint by name, N·m.
    pub fn get_joint_torque(&self, name: &str) -> Result<f64> {
        Ok(self.by_name(name)?.effort as f64)
    }

    /// Move to the configuration's home position.
    pub fn go_home(&self) -> Result<()> {
        let home = self.cfg().home.clone();
        self.set_joint_positions(&home)
    }

    /// Fold the arm into the description's stow pose (`[arm] stow`), the pose it travels in
    /// while the base drives: within (or near) the base's footprint and out of the camera's
    /// view. Moves as [`Arm::set_joint_positions`] does. Error: the description has no stow
    /// pose.
    pub fn stow(&self) -> Result<()> {
        let stow = self
            .cfg()
            .stow
            .clone()
            .ok_or_else(|| self.robot.missing("arm stow pose"))?;
        self.set_joint_positions(&stow)
    }

    /// Fold the arm out of the camera's view of a table in front of the robot: to its stow
    /// pose (`[arm] stow`), then to its look pose (`[arm] look`), each when the description
    /// has it. Moves as [`Arm::set_joint_positions`] does, with nothing known around it yet.
    /// (The LoCoBot's stow pose hides the table's near middle from the camera; its look pose
    /// folds the arm across the base, above it. Turned straight to the look pose, a hanging
    /// arm swept the table's near edge; from the stow pose the turn stays within 0.2 m of the
    /// base's centre and 0.2 m above the floor.)
    pub fn clear_view(&self) -> Result<()> {
        let cfg = self.cfg();
        let (stow, look) = (cfg.stow.clone(), cfg.look.clone());
        if let Some(q) = stow {
            self.set_joint_positions(&q)?;
        }
        match look {
            Some(q) => self.set_joint_positions(&q),
            None => Ok(()),
        }
    }

    /// How far the arm reaches from the base's centre across the floor now, m: the largest
    /// horizontal distance of its links' covering spheres (measured joints) that come down
    /// into the map's obstacle band (0.1-0.8 m above the floor). Where it exceeds the base's
    /// footprint radius, navigation on a map takes it as the robot's radius (see
    /// [`crate::GoalOptions::map`]); [`Arm::stow`] brings it in.
    pub fn reach(&self) -> Result<f64> {
        self.robot.arm_reach()
    }

    /// Move the end effector to a pose (through IK and a planned joint move).
    /// The IK solution is the collision-free one nearest the current joints, from several
    /// seeds.
    pub fn set_ee_pose(&self, position: [f64; 3], orientation: Orientation) -> Result<()> {
        self.move_to_pose(position, orientation, MoveOptions::default())?
            .wait()
    }

    /// Start moving the end effector to a pose (`position` m, `orientation`, base frame):
    /// [`Arm::set_ee_pose`]'s IK, then [`Arm::move_joints`] with `opts`; returns the motion
    /// under way.
    pub fn move_to_pose(
        &self,
        position: [f64; 3],
        orientation: Orientation,
        opts: MoveOptions,
    ) -> Result<Motion> {
        let q = self.free_ik(position, orientation)?;
        self.move_joints(&q, opts)
    }

    /// 5-DOF arms: move the end effector to `position` with gripper pitch `pitch` (rad below
    /// horizontal; π/2 points down) and roll `roll` (rad about the gripper's x axis; the
    /// current roll when `None`).
    pub fn set_ee_pose_pitch_roll(
        &self,
        position: [f64; 3],
        pitch: f64,
        roll: Option<f64>,
    ) -> Result<()> {
        let q = self.ik_pitch_roll(position, pitch, roll, None)?;
        self.set_joint_positions(&q)
    }

    /// Move the end effector along a straight line by `displacement` (m, base frame), keeping
    /// its orientation, through IK solutions every `step` metres (checked before moving).
    /// `step` is at least [`validate::MIN_CARTESIAN_STEP`], and the line has at most
    /// [`validate::MAX_CARTESIAN_WAYPOINTS`] steps. Waypoints are streamed as the firmware's
    /// queue makes room, so lines of any number of steps run.
    ///
    /// The line is checked first (PyRobot's `plan=True`): every step free of collision with
    /// the planning scene and the arm itself, and no joint jumping between steps; see
    /// [`Arm::move_ee_xyz_with`] to skip the check.
    pub fn move_ee_xyz(&self, displacement: [f64; 3], step: f64) -> Result<()> {
        self.move_ee_xyz_with(displacement, step, true)
    }

    /// [`Arm::move_ee_xyz`], the line checked for collisions and joint jumps when `plan`.
    pub fn move_ee_xyz_with(&self, displacement: [f64; 3], step: f64, plan: bool) -> Result<()> {
        let d = validate::arm_point("displacement", displacement)?;
        validate::in_range(
            "Cartesian step",
            step,
            validate::MIN_CARTESIAN_STEP,
            validate::MAX_ARM_REACH,
        )?;
        let steps = (d.norm() / step).ceil();
        let n = validate::count(
            "Cartesian waypoints (distance / step)",
            steps as usize,
            0..=validate::MAX_CARTESIAN_WAYPOINTS,
        )?
        .max(1);
        let q0 = self.get_joint_angles()?;
        let ee = self.cfg().ee_frame.clone();
        let start = self.compute_fk_position(&q0, &ee)?;
        // Solve every waypoint first: a line that leaves the workspace moves nothing.
        let mut path = Vec::with_capacity(n);
        let mut seed = q0.clone();
        // Keep the gripper's pitch; roll stays with joint 5. On the pitch-roll arm the pitch is
        // the sum of the three pitch joints (the solver's q4 = pitch − q2 − q3), exact past
        // π/2 too, where Euler angles would fold it back and flip the gripper. Other arms keep
        // the whole orientation.
        let pitch = self
            .parts()
            .locobot_ik
            .is_some()
            .then(|| q0[1] + q0[2] + q0[3]);
        for k in 1..=n {
            let p = Vector3::from(start.position) + d * (k as f64 / n as f64);
            let q = if let Some(pitch) = pitch {
                self.ik_pitch_roll([p.x, p.y, p.z], pitch, None, Some(seed.clone()))?
            } else {
                let [x, y, z, w] = start.quaternion;
                self.compute_ik(
                    [p.x, p.y, p.z],
                    Orientation::Quaternion([x, y, z, w]),
                    Some(&seed),
                )?
            };
            path.push(q.clone());
            seed = q;
        }
        if plan {
            self.check_cartesian(&q0, &path, step)?;
        }
        // Stream the path as knots, each timed by the joints' speed limits. The motion is under
        // way from the first knot, so that other motions see (and preempt) it.
        let parts = self.parts();
        let idx = parts.joints.clone();
        let timeout = Duration::from_secs_f64(self.cfg().timeout);
        let tolerance = self.cfg().joint_tolerance;
        let target = path.last().cloned().unwrap_or_else(|| q0.clone());
        let mut durations = Vec::with_capacity(path.len());
        let mut prev = &q0;
        for q in &path {
            let mut t = 0.0f64;
            for ((&j, a), b) in idx.iter().zip(q).zip(prev) {
                t = t
                    .max((a - b).abs() / (0.5 * self.robot.cfg().joints[j].limits.velocity as f64));
            }
            durations.push(t.max(0.02));
            prev = q;
        }
        let total: f64 = durations.iter().sum();
        let claim = Claim {
            joints: parts.mask(),
            ..Claim::default()
        };
        let motion = self
            .robot
            .start_motion(claim, "Cartesian motion", |io: &mut Hub| {
                self.ensure_mode(io, JointMode::Position)?;
                let started = io.link.now();
                // Streaming may fall behind the knots' timing (a full queue): then the
                // tolerance decides.
                let goal = JointsGoal::new(
                    idx,
                    target,
                    tolerance,
                    started,
                    started + Duration::from_secs_f64(total),
                );
                Ok((Box::new(goal) as Box<dyn crate::goals::Goal>, timeout))
            })?;
        for (q, &t) in path.iter().zip(&durations) {
            if motion.is_finished() {
                // Ended while streaming (a fault, a preemption): its result says why.
                break;
            }
            if let Err(e) = self.send_when_queued(q, t, timeout) {
                let _ = motion.cancel();
                return Err(e);
            }
        }
        motion.wait()
    }
}
