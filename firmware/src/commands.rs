//! The commands of the host, one handler per message kind: each checks the whole command
//! against the joint table, the modes and the limits before it changes anything, and answers
//! `Ok` or the [`RejectReason`] the host gets. Units as on the wire: SI, `f32`; durations in
//! the wire's µs and ms are converted here.

use ferrobot_protocol::{
    ranges, GripperCommand, GripperState, HostMsg, JointConfig, JointLimits, JointMask, JointMode,
    JointPoint, PidGains, RejectReason, MAX_JOINTS,
};
use heapless::Vec;

use crate::gripper::Gripper;
use crate::time::Duration;
use crate::time::Instant;
use crate::{config, joint, Firmware};

impl Firmware {
    /// Indices selected by a mask, checked against the joint count.
    fn selected(&self, mask: u16) -> Result<Vec<usize, MAX_JOINTS>, RejectReason> {
        let n = self.joints.len();
        if n < 16 && mask != u16::MAX && mask >> n != 0 {
            return Err(RejectReason::UnknownJoint);
        }
        Ok((0..n).filter(|j| mask & (1 << j) != 0).collect())
    }

    /// Carry out one command of an accepted session: a thin dispatch to its handler.
    pub(crate) fn command(&mut self, now: Instant, msg: HostMsg) -> Result<(), RejectReason> {
        match msg {
            HostMsg::ConfigureJoint { index, config } => self.configure_joint(now, index, config),
            HostMsg::SetPid { joint, gains } => self.set_pid(joint, gains),
            HostMsg::SetLimits { joint, limits } => self.set_limits(joint, limits),
            HostMsg::SetMode { joints, mode } => self.set_mode(now, joints, mode),
            HostMsg::Waypoint {
                joints,
                duration_us,
                points,
            } => self.waypoint(now, joints, duration_us, &points),
            HostMsg::ClearQueue { joints } => self.clear_queue(now, joints),
            HostMsg::JointCommand { joints, values } => self.joint_command(joints, &values),
            HostMsg::BaseVelocity { v, w, duration_ms } => {
                self.base_velocity(now, v, w, duration_ms)
            }
            HostMsg::SetBaseGeometry {
                left_radius,
                right_radius,
                track,
            } => self.base.set_geometry(left_radius, right_radius, track),
            HostMsg::ResetOdometry => self.reset_odometry(),
            HostMsg::Gripper(cmd) => self.gripper_command(now, cmd),
            HostMsg::SetWatchdog { period_ms } => self.set_watchdog(period_ms),
            HostMsg::Heartbeat => Ok(()),
            HostMsg::EmergencyStop => {
                self.emergency_stop(now);
                Ok(())
            }
            HostMsg::Resume => {
                self.resume();
                Ok(())
            }
            HostMsg::SetTelemetry { period_ms } => {
                self.set_telemetry(now, Duration::from_millis(u64::from(period_ms)));
                Ok(())
            }
            HostMsg::SetLoopPeriod { period_us } => self.set_loop_period(period_us),
            HostMsg::RebootJoint { joint } => self.reboot_joint(now, joint),
            HostMsg::ArmLink { index, count, link } => self.arm_link(index, count, &link),
            // Answered by `handle` before any command; listed so that the match stays
            // exhaustive and a new message without a handler fails to compile.
            HostMsg::Hello { .. } | HostMsg::GetJoint { .. } | HostMsg::GetDiagnostics => {
                Err(RejectReason::Unsupported)
            }
        }
    }

    /// Replace or append one row of the joint table (every joint off); the servos are configured anew and every joint is left off.
    fn configure_joint(
        &mut self,
        now: Instant,
        index: u8,
        config: JointConfig,
    ) -> Result<(), RejectReason> {
        if self.joints.iter().any(|j| j.mode != JointMode::Off) {
            return Err(RejectReason::Busy);
        }
        if !config::joint_is_valid(&config) {
            return Err(RejectReason::InvalidConfig);
        }
        let i = index as usize;
        // A servo belongs to one joint only.
        let ids = |c: &JointConfig| [Some(c.servo_id), c.twin_id];
        let taken = self
            .profile
            .joints
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != i)
            .flat_map(|(_, c)| ids(c))
            .flatten()
            .any(|id| ids(&config).contains(&Some(id)));
        if taken {
            return Err(RejectReason::InvalidConfig);
        }
        match i.cmp(&self.profile.joints.len()) {
            core::cmp::Ordering::Less => {
                if let Some(env) = self.envelope.get_mut(i) {
                    *env = config.limits;
                }
                if let Some(row) = self.profile.joints.get_mut(i) {
                    *row = config;
                }
            }
            core::cmp::Ordering::Equal => {
                self.envelope
                    .push(config.limits)
                    .map_err(|_| RejectReason::UnknownJoint)?;
                self.profile
                    .joints
                    .push(config)
                    .map_err(|_| RejectReason::UnknownJoint)?;
            }
            core::cmp::Ordering::Greater => return Err(RejectReason::UnknownJoint),
        }
        self.rebuild_joints(now);
        // The model was built for the rows as they were.
        self.dynamics.clear();
        for j in self.joints.iter_mut() {
            j.set_mode(now, JointMode::Off);
        }
        self.apply_modes();
        Ok(())
    }

    /// Set one joint's PID gains, within what its servos can use.
    fn set_pid(&mut self, joint: u8, gains: PidGains) -> Result<(), RejectReason> {
        let row = self
            .profile
            .joints
            .get_mut(joint as usize)
            .ok_or(RejectReason::UnknownJoint)?;
        if ranges::gains_beyond_servo(&gains, row).is_some() {
            return Err(RejectReason::InvalidConfig);
        }
        row.pid = gains;
        Ok(())
    }

    /// Narrow one joint's limits within its configured envelope, around where it is.
    fn set_limits(&mut self, joint: u8, limits: JointLimits) -> Result<(), RejectReason> {
        let row = self
            .profile
            .joints
            .get(joint as usize)
            .ok_or(RejectReason::UnknownJoint)?;
        let mut new = row.clone();
        new.limits = limits;
        if !config::joint_is_valid(&new) {
            return Err(RejectReason::InvalidConfig);
        }
        // Limits narrow within the joint's configured envelope, never widen it.
        let env = self
            .envelope
            .get(joint as usize)
            .ok_or(RejectReason::UnknownJoint)?;
        if limits.min < env.min
            || limits.max > env.max
            || limits.velocity > env.velocity
            || limits.effort > env.effort
            || limits.effort < ranges::EFFORT_NARROW_MIN_SHARE * env.effort
        {
            return Err(RejectReason::OutOfLimits);
        }
        // Limits the joint is outside of now cannot hold at once: refused (the host
        // moves it inside first).
        let jc = self
            .joints
            .get_mut(joint as usize)
            .ok_or(RejectReason::UnknownJoint)?;
        let q = jc.state.position;
        if jc.measured && !(limits.min..=limits.max).contains(&q) {
            return Err(RejectReason::OutOfLimits);
        }
        jc.reset_anchor();
        if let Some(r) = self.profile.joints.get_mut(joint as usize) {
            *r = new;
        }
        Ok(())
    }

    /// Switch the selected joints to `mode`; each holds where it is.
    fn set_mode(
        &mut self,
        now: Instant,
        joints: JointMask,
        mode: JointMode,
    ) -> Result<(), RejectReason> {
        let sel = self.selected(joints)?;
        if self.estop && mode != JointMode::Off {
            return Err(RejectReason::EmergencyStop);
        }
        // Teach mode needs a trusted model of the joint's load (and the gripper has its own
        // driver).
        let gripper = self.gripper.as_ref().map(|(j, _)| *j);
        if mode == JointMode::Teach
            && sel
                .iter()
                .any(|&j| !self.dynamics.trusted_for(j) || gripper == Some(j))
        {
            return Err(RejectReason::Unsupported);
        }
        for j in sel {
            if let Some(jc) = self.joints.get_mut(j) {
                jc.set_mode(now, mode);
            }
            if let (Some((gj, g)), Some(cfg)) = (self.gripper.as_mut(), self.profile.gripper) {
                if *gj == j {
                    *g = Gripper::new(cfg);
                }
            }
        }
        self.apply_modes();
        Ok(())
    }

    /// Queue one knot per selected joint, `duration_us` after its last one; all or none.
    fn waypoint(
        &mut self,
        now: Instant,
        joints: JointMask,
        duration_us: u32,
        points: &[JointPoint],
    ) -> Result<(), RejectReason> {
        if self.estop {
            return Err(RejectReason::EmergencyStop);
        }
        let sel = self.selected(joints)?;
        if sel.len() != points.len() {
            return Err(RejectReason::CountMismatch);
        }
        for (&j, p) in sel.iter().zip(points.iter()) {
            let cfg = self
                .profile
                .joints
                .get(j)
                .ok_or(RejectReason::UnknownJoint)?;
            if let Some(e) = ranges::point_error(p, &cfg.limits) {
                return Err(e);
            }
            let jc = self.joints.get(j).ok_or(RejectReason::UnknownJoint)?;
            if !matches!(jc.mode, JointMode::Position | JointMode::Current) {
                return Err(RejectReason::WrongMode);
            }
            if jc.queued() >= joint::QUEUE_LEN {
                return Err(RejectReason::QueueFull);
            }
            if self
                .gripper
                .as_ref()
                .is_some_and(|(gj, g)| *gj == j && g.state != GripperState::Unknown)
            {
                return Err(RejectReason::WrongMode);
            }
        }
        for (&j, p) in sel.iter().zip(points.iter()) {
            if let Some(jc) = self.joints.get_mut(j) {
                jc.push(now, Duration::from_micros(u64::from(duration_us)), p);
            }
        }
        Ok(())
    }

    /// Drop the selected joints' queues; they hold where they are.
    fn clear_queue(&mut self, now: Instant, joints: JointMask) -> Result<(), RejectReason> {
        for j in self.selected(joints)? {
            if let Some(jc) = self.joints.get_mut(j) {
                jc.hold_here(now);
            }
        }
        Ok(())
    }

    /// Direct commands (velocity, effort or PWM, by mode) of the selected joints; all or none.
    fn joint_command(&mut self, joints: JointMask, values: &[f32]) -> Result<(), RejectReason> {
        let sel = self.selected(joints)?;
        if sel.len() != values.len() {
            return Err(RejectReason::CountMismatch);
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(RejectReason::NotFinite);
        }
        if self.estop && values.iter().any(|v| *v != 0.0) {
            return Err(RejectReason::EmergencyStop);
        }
        for (&j, v) in sel.iter().zip(values.iter()) {
            let jc = self.joints.get(j).ok_or(RejectReason::UnknownJoint)?;
            let bound = match jc.mode {
                JointMode::Velocity => ranges::JOINT_SPEED_MAX,
                JointMode::Current => ranges::JOINT_EFFORT_MAX,
                JointMode::Pwm => 1.0,
                _ => return Err(RejectReason::WrongMode),
            };
            if v.abs() > bound {
                return Err(RejectReason::OutOfLimits);
            }
        }
        for (&j, &v) in sel.iter().zip(values.iter()) {
            if let Some(jc) = self.joints.get_mut(j) {
                jc.set_direct(v);
            }
        }
        Ok(())
    }

    /// Drive the base at `v` (m/s) and `w` (rad/s) for `duration_ms`.
    fn base_velocity(
        &mut self,
        now: Instant,
        v: f32,
        w: f32,
        duration_ms: u16,
    ) -> Result<(), RejectReason> {
        if !(v.is_finite() && w.is_finite()) {
            return Err(RejectReason::NotFinite);
        }
        if v.abs() > ranges::BASE_SPEED_MAX || w.abs() > ranges::BASE_TURN_MAX {
            return Err(RejectReason::OutOfLimits);
        }
        if self.estop && (v != 0.0 || w != 0.0) {
            return Err(RejectReason::EmergencyStop);
        }
        self.base
            .set_velocity(now, v, w, Duration::from_millis(u64::from(duration_ms)))?;
        self.base.poll(now);
        Ok(())
    }

    /// Reset the odometry pose to zero.
    fn reset_odometry(&mut self) -> Result<(), RejectReason> {
        if !self.base.present() {
            return Err(RejectReason::NoBase);
        }
        self.base.odom.reset();
        Ok(())
    }

    /// Open or close the gripper.
    fn gripper_command(&mut self, now: Instant, cmd: GripperCommand) -> Result<(), RejectReason> {
        if self.estop {
            return Err(RejectReason::EmergencyStop);
        }
        let (gj, g) = self.gripper.as_mut().ok_or(RejectReason::NoGripper)?;
        g.command(now, cmd);
        let j = *gj;
        if let Some(jc) = self.joints.get_mut(j) {
            if jc.mode == JointMode::Off {
                jc.set_mode(now, JointMode::Position);
            }
        }
        self.apply_modes();
        Ok(())
    }

    /// Set the host watchdog period, ms.
    fn set_watchdog(&mut self, period_ms: u16) -> Result<(), RejectReason> {
        if !(1..=ranges::WATCHDOG_MAX_MS).contains(&period_ms) {
            return Err(RejectReason::InvalidConfig);
        }
        self.watchdog_period = Duration::from_millis(u64::from(period_ms));
        Ok(())
    }

    /// Set the servo-loop period, µs.
    fn set_loop_period(&mut self, period_us: u32) -> Result<(), RejectReason> {
        if !(ranges::LOOP_PERIOD_MIN_US..=ranges::LOOP_PERIOD_MAX_US).contains(&period_us) {
            return Err(RejectReason::InvalidConfig);
        }
        self.loop_period = Duration::from_micros(u64::from(period_us));
        Ok(())
    }

    /// Reboot a joint's servo(s): only a joint that is off or limp from a hardware error.
    fn reboot_joint(&mut self, now: Instant, joint: u8) -> Result<(), RejectReason> {
        let jc = self
            .joints
            .get(joint as usize)
            .ok_or(RejectReason::UnknownJoint)?;
        let (p, t) = self.servo_indices(joint as usize);
        // A rebooting servo is limp: only a joint that is off, or already limp from a
        // hardware error, may be rebooted.
        let faulty = [p, t]
            .into_iter()
            .flatten()
            .any(|i| self.bus.servos.get(i).is_some_and(|s| s.hw_error != 0));
        if jc.mode != JointMode::Off && !faulty {
            return Err(RejectReason::Busy);
        }
        for i in [p, t].into_iter().flatten() {
            self.bus.reboot(i);
        }
        // The reboot leaves the servo limp and then configures it anew: the joint
        // starts again from where it is, as after a mode switch (no load correction,
        // stall or brake carried over from before the fault).
        if let Some(jc) = self.joints.get_mut(joint as usize) {
            let mode = jc.mode;
            jc.set_mode(now, mode);
        }
        Ok(())
    }
}
