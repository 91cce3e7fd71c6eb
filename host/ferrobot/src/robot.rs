//! [`Robot`]: one robot, its components and its backend.

use std::sync::Arc;
use std::time::Duration;

use ferrobot_protocol::{Fault, HostMsg, Telemetry};
use parking_lot::{Mutex, MutexGuard};

use crate::arm_parts::ArmParts;
use crate::backend::LinkEvent;
use crate::config::RobotConfig;
use crate::error::{Error, Result};
use crate::frames::Frames;
use crate::goals::{Claim, Goal};
use crate::hub::Hub;
use crate::motion::Motion;

/// Which components to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Use {
    pub(crate) arm: bool,
    pub(crate) gripper: bool,
    pub(crate) camera: bool,
    pub(crate) base: bool,
}

/// A robot: its configuration, its components and the link to its firmware.
///
/// A `Robot` is a handle: clones share one robot, and it is `Send + Sync`, so a teleoperation
/// loop, a monitor and a program can each hold one. Its link sits behind one lock, taken for
/// each call and for each step of time, so calls from several threads interleave and every
/// reply reaches the call that asked for it. Component handles ([`crate::arm::Arm`], [`crate::base::Base`], ...)
/// and motions ([`crate::Motion`]) hold a clone too: nothing borrows the robot while it
/// moves, and the arm, gripper, head and base move at the same time.
#[derive(Clone)]
pub struct Robot {
    pub(crate) inner: Arc<Inner>,
}

/// What a robot's handles share.
pub(crate) struct Inner {
    pub(crate) cfg: RobotConfig,
    pub(crate) uses: Use,
    /// The arm's kinematics (absent without an arm).
    pub(crate) arm: Option<ArmParts>,
    /// The URDF's frames (absent when the URDF's tree cannot be built).
    pub(crate) frames: Result<Frames, String>,
    /// The URDF frame of the camera's images (absent without a camera).
    pub(crate) optical: Option<String>,
    /// The robot's own body (its links' covering spheres), built on first use.
    pub(crate) body: std::sync::OnceLock<crate::sense::SelfBody>,
    /// The simulated world the robot started in (the empty one on hardware).
    #[cfg(feature = "sim")]
    pub(crate) scene: Arc<ferrobot_sim::scene::Scene>,
    /// The world shared with other robots, when the robot joined one.
    #[cfg(feature = "sim")]
    pub(crate) shared: Option<crate::SharedWorld>,
    /// The link's line for the emergency stop beside the I/O lock ([`Link::stop_line`]).
    pub(crate) stop_line: Option<Arc<dyn crate::backend::StopLine>>,
    pub(crate) io: Mutex<Hub>,
}

/// How many times [`Robot::emergency_stop`] sends the stop before it gives up.
pub const ESTOP_ATTEMPTS: usize = 3;

impl std::fmt::Debug for Robot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Robot")
            .field("name", &self.inner.cfg.name)
            .finish_non_exhaustive()
    }
}

impl Robot {
    /// The configuration (immutable once connected).
    pub(crate) fn cfg(&self) -> &RobotConfig {
        &self.inner.cfg
    }

    /// The arm's kinematics; present when the robot uses its arm.
    pub(crate) fn arm_parts(&self) -> Result<&ArmParts> {
        self.inner
            .arm
            .as_ref()
            .filter(|_| self.inner.uses.arm)
            .ok_or_else(|| self.missing("arm"))
    }

    /// The link, the goals and the components' state, locked. Never held across a call that
    /// locks again.
    pub(crate) fn lock_hub(&self) -> MutexGuard<'_, Hub> {
        self.inner.io.lock()
    }

    /// Prepare a new goal with `claim`, send its first commands with `send`, and put it under
    /// way: one step under one lock, so no other thread's command comes between. Returns the
    /// motion.
    pub(crate) fn start_motion(
        &self,
        claim: Claim,
        what: &str,
        send: impl FnOnce(&mut Hub) -> Result<(Box<dyn Goal>, Duration)>,
    ) -> Result<Motion> {
        let mut io = self.lock_hub();
        io.prepare(self.cfg(), claim);
        let (goal, timeout) = match send(&mut io) {
            Ok(g) => g,
            Err(e) => {
                // Commands sent before the failure (a trajectory's first knots) would move
                // the joints with no motion to follow them: cleared, best effort.
                if claim.joints != 0 {
                    let _ = io.link.command(
                        &HostMsg::ClearQueue {
                            joints: claim.joints,
                        },
                        "clear after a failed start",
                    );
                }
                return Err(e);
            }
        };
        let id = io.start(goal, what, timeout);
        drop(io);
        Ok(Motion::new(self.clone(), id))
    }

    /// The configuration.
    pub fn config(&self) -> &RobotConfig {
        &self.inner.cfg
    }

    /// The robot's name.
    pub fn name(&self) -> &str {
        &self.inner.cfg.name
    }

    /// The error for a component this robot lacks (or was built without).
    pub(crate) fn missing(&self, component: &'static str) -> Error {
        Error::NoComponent {
            robot: self.inner.cfg.name.clone(),
            component,
        }
    }

    /// The URDF's frames.
    pub fn frames(&self) -> Result<&Frames> {
        self.inner.frames.as_ref().map_err(|e| Error::Config {
            file: "robot description".into(),
            key: "urdf".into(),
            problem: e.clone(),
        })
    }

    /// What obstacle scans are made with: the frames, the camera's optical frame, the body.
    pub(crate) fn eyes(&self) -> Result<crate::sense::Eyes> {
        Ok(crate::sense::Eyes {
            frames: self.frames()?.clone(),
            optical: self.optical_frame()?,
            body: self.self_body()?.clone(),
        })
    }

    /// The robot's own body: its links' covering spheres, computed once.
    pub(crate) fn self_body(&self) -> Result<&crate::sense::SelfBody> {
        if let Some(b) = self.inner.body.get() {
            return Ok(b);
        }
        let b = crate::sense::SelfBody::new(self.config())?;
        Ok(self.inner.body.get_or_init(|| b))
    }

    /// How far the arm's links reach from the base's centre across the floor now, m (see
    /// [`crate::sense::SelfBody::reach`]); 0 for a robot without an arm.
    pub(crate) fn arm_reach(&self) -> Result<f64> {
        let cfg = self.config();
        let Some(arm) = &cfg.arm else {
            return Ok(0.0);
        };
        let frames = self.frames()?;
        let poses = frames.poses_in(&self.telemetry()?, crate::frames::BASE_FRAME)?;
        let links = frames.links_moved_by(&arm.joints);
        Ok(self.self_body()?.reach(&poses, &links))
    }

    /// How far the robot's body reaches ahead of the base's centre now, m (from
    /// its body's covering spheres): the largest x in the base's frame of its links'
    /// covering spheres that come down below `below` (m, the base's z): the base, its plates,
    /// the arm as it stands.
    pub fn body_ahead(&self, below: f64) -> Result<f64> {
        let frames = self.frames()?;
        let poses = frames.poses_in(&self.telemetry()?, crate::frames::BASE_FRAME)?;
        Ok(self.self_body()?.ahead(&poses, None, below))
    }

    /// The radius of the circle the robot's body sweeps as the base turns in place, m, in
    /// the pose it holds now: the footprint, and every link's covering spheres that come down
    /// below `below` (m, `base_link`'s z).
    pub fn body_radius(&self, below: f64) -> Result<f64> {
        let frames = self.frames()?;
        let poses = frames.poses_in(&self.telemetry()?, crate::frames::BASE_FRAME)?;
        let footprint = self
            .config()
            .base
            .as_ref()
            .map_or(0.0, |b| b.footprint_radius);
        Ok(self.self_body()?.around(&poses, below).max(footprint))
    }

    /// The camera's optical frame.
    pub fn optical_frame(&self) -> Result<String> {
        self.inner
            .optical
            .clone()
            .ok_or_else(|| self.missing("camera"))
    }

    /// Pose of URDF frame `src` in frame `dst` now (maps points of `src` into `dst`), from the
    /// measured joints: PyRobot's `get_link_transform`. Unknown frames are an error naming
    /// them.
    pub fn link_transform(&self, src: &str, dst: &str) -> Result<nalgebra::Isometry3<f64>> {
        let tel = self.telemetry()?;
        self.frames()?.transform_at(&tel, src, dst)
    }

    /// Emergency stop: the firmware stops the base, holds the arm and refuses motion until
    /// [`Robot::resume`]. On a serial link the stop goes on the wire at once, even while
    /// another thread holds the link (a camera read); the call then waits for the link. Every
    /// motion under way ends with [`Error::EmergencyStop`], even when the firmware does not
    /// acknowledge the stop (the host's own base laws stop sending); the stop is sent up to
    /// [`ESTOP_ATTEMPTS`] times, and the last error is returned when none is acknowledged.
    pub fn emergency_stop(&self) -> Result<()> {
        // At once, on a link whose firmware runs on while another thread holds the I/O lock
        // (a camera read, SLAM, planning's telemetry): the stop must not wait behind them.
        // Sent again below, under the lock, for its acknowledgement.
        if let Some(line) = &self.inner.stop_line {
            let _ = line.emergency_stop();
        }
        let mut io = self.lock_hub();
        let mut sent = io.link.command(&HostMsg::EmergencyStop, "emergency stop");
        for _ in 1..ESTOP_ATTEMPTS {
            if sent.is_ok() {
                break;
            }
            sent = io.link.command(&HostMsg::EmergencyStop, "emergency stop");
        }
        io.goals.end_all(|| Error::EmergencyStop);
        sent
    }

    /// Stop every motion under way where it is (joints hold, the base stops) and end each
    /// with [`Error::Cancelled`]: what a program does when its user interrupts it (Python's
    /// Ctrl-C). Unlike [`Robot::emergency_stop`] nothing latches: the next command runs.
    pub fn cancel_motions(&self) {
        self.lock_hub().cancel_all();
    }

    /// Leave the emergency stop.
    pub fn resume(&self) -> Result<()> {
        self.lock_hub().link.command(&HostMsg::Resume, "resume")
    }

    /// The firmware's link and bus counters.
    pub fn diagnostics(&self) -> Result<ferrobot_protocol::Diagnostics> {
        self.lock_hub().link.diagnostics()
    }

    /// The base commands that host-side base laws have sent: (time s, v m/s, ω rad/s).
    pub fn base_commands(&self) -> Vec<(f64, f64, f64)> {
        self.lock_hub().base.log.clone()
    }

    /// The newest telemetry.
    pub fn telemetry(&self) -> Result<Telemetry> {
        self.lock_hub().link.telemetry()
    }

    /// Faults reported since the last call (the newest [`crate::motion::FAULT_QUEUE`]),
    /// including those that ended motions.
    pub fn take_faults(&self) -> Vec<Fault> {
        let mut io = self.lock_hub();
        io.collect_faults(self.cfg());
        io.goals.take_faults()
    }

    /// What happened to the link since the last call, oldest first (the newest
    /// [`crate::motion::LINK_EVENT_QUEUE`]): lost, and back with whether the firmware's watchdog
    /// stopped the robot meanwhile ([`LinkEvent`]). Always empty on the in-process simulator.
    pub fn take_link_events(&self) -> Vec<LinkEvent> {
        let mut io = self.lock_hub();
        io.collect_faults(self.cfg());
        io.goals.take_link_events()
    }

    /// Let `seconds` pass (simulated time on the simulator): finite, in
    /// `[0, validate::MAX_DURATION_S]`. The motions under way go on meanwhile.
    pub fn wait(&self, seconds: f64) -> Result<()> {
        let dt = crate::validate::seconds("wait time", seconds)?;
        self.wait_for(dt);
        Ok(())
    }

    /// Whether the robot shares its simulated world, and its clock, with other robots
    /// ([`crate::SharedWorld`]): their waits pass its time too.
    pub fn shares_world(&self) -> bool {
        #[cfg(feature = "sim")]
        return self.inner.shared.is_some();
        #[cfg(not(feature = "sim"))]
        false
    }

    /// In a shared world, step the other robots' motions at the present instant, as their
    /// own waits would: one program's wait on one robot drives them all
    /// ([`crate::SharedWorld`]).
    pub(crate) fn step_neighbours(&self) {
        #[cfg(feature = "sim")]
        if let Some(w) = &self.inner.shared {
            w.step_others(&self.inner);
        }
    }

    /// Let `dt` pass in steps of at most [`crate::goals::POLL`], stepping the motions under
    /// way, and let other threads at the link between steps.
    pub(crate) fn wait_for(&self, dt: Duration) {
        let cfg = self.cfg();
        let start = self.lock_hub().link.now();
        let end = start.saturating_add(dt);
        loop {
            let mut io = self.lock_hub();
            let now = io.link.now();
            if now >= end {
                break;
            }
            // At least the links' resolution (1 µs), so that a sub-microsecond rest ends.
            let step = (end - now).clamp(Duration::from_micros(1), crate::goals::POLL);
            io.pump(cfg, step);
            if io.link.now() <= now {
                // A clock that does not move (a link that has lost its firmware): the wait is
                // over; the next call reports the link's state.
                break;
            }
            // A simulator paced to the wall clock waits for it without the lock.
            let rest = io.link.pace();
            MutexGuard::unlock_fair(io);
            self.step_neighbours();
            if !rest.is_zero() {
                std::thread::sleep(rest);
            }
        }
    }

    /// Subscribes to the firmware's telemetry (joints, gripper, odometry, wheels, faults'
    /// flags), in a queue of `queue` reports (in `[1, subscription::MAX_QUEUE]`; a full queue
    /// drops its oldest): every report received from now on, once, oldest first, delivered
    /// each time the robot's time passes (a wait, a motion's wait, a capture). The link keeps
    /// the newest [`ferrobot_protocol::session::REPORTS`] between two such instants.
    ///
    /// [`subscription::MAX_QUEUE`]: crate::subscription::MAX_QUEUE
    pub fn subscribe_telemetry(
        &self,
        queue: usize,
    ) -> Result<crate::subscription::Subscription<Telemetry>> {
        let mut io = self.lock_hub();
        // Reports received before now go to the subscribers of before, not to this one.
        io.publish_telemetry();
        io.streams.telemetry.subscribe("telemetry", queue)
    }

    /// Subscribes to the robot's events ([`crate::events::Event`]: the commands the firmware
    /// acknowledged, faults, link events and SLAM's poses), in a queue of `queue` events (in
    /// `[1, subscription::MAX_QUEUE]`; a full queue drops its oldest). Every event is
    /// delivered, as it happens; reading them takes nothing from [`Robot::take_faults`] or
    /// [`Robot::take_link_events`].
    ///
    /// [`subscription::MAX_QUEUE`]: crate::subscription::MAX_QUEUE
    pub fn subscribe_events(
        &self,
        queue: usize,
    ) -> Result<crate::subscription::Subscription<crate::events::Event>> {
        self.lock_hub()
            .streams
            .events
            .lock()
            .subscribe("events", queue)
    }

    /// Sends one message of the wire protocol to the firmware, as the API's components do,
    /// and waits for its acknowledgement: for tools that replay what a robot was sent
    /// ([`crate::events::Event::Command`]). The firmware checks it as it checks every
    /// message (ranges, limits, the emergency stop) and a refusal is [`crate::Error::Rejected`];
    /// the API's components do not know of it (their goals may overrule it). The faults the
    /// firmware reported before a refusal (often its cause: a bumper pressed, then a drive
    /// forward refused) are on the events' stream ([`Robot::subscribe_events`]) when it returns.
    pub fn send_command(&self, msg: &crate::events::HostMsg) -> Result<()> {
        let mut io = self.lock_hub();
        let r = io.link.command(msg, "a replayed command");
        if matches!(r, Err(Error::Rejected { .. })) {
            io.collect_faults(self.cfg());
        }
        r
    }

    /// The firmware's self-description from its handshake (protocol, robot, joint kinds,
    /// base, loop period): what a tool serving this robot's link tells its clients.
    pub fn device_info(&self) -> ferrobot_protocol::DeviceInfo {
        self.lock_hub().link.info().clone()
    }

    /// The firmware's configuration of joint `index` (its row of the joint table), asked of
    /// the firmware.
    pub fn firmware_joint(&self, index: u8) -> Result<ferrobot_protocol::JointConfig> {
        self.lock_hub().link.joint_config(index)
    }

    /// The backend's clock, s.
    pub fn time(&self) -> f64 {
        self.lock_hub().link.now().as_secs_f64()
    }
}
