//! [`Robot`]: one robot, its components and its backend.

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use ferrobot_protocol::{Fault, HostMsg, JointLimits, JointMode, JointPoint, PidGains, Telemetry};
use parking_lot::{MappedMutexGuard, Mutex, MutexGuard};

use crate::arm::{Arm, ArmParts, ArmState};
use crate::backend::serial::SerialLink;
use crate::backend::sim::SimLink;
use crate::backend::{Backend, Link, LinkEvent};
use crate::base::{Base, BaseState};
use crate::camera::{Camera, CameraDevice};
use crate::config::{ConfigSource, RobotConfig};
use crate::error::{Error, Result};
use crate::frames::Frames;
use crate::gripper::Gripper;
use crate::head::Head;
use crate::motion::{Claim, Goal, Goals, Motion};
use ferrobot_sim::scene::{Scene, SceneSource};

/// Which components to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Use {
    arm: bool,
    gripper: bool,
    camera: bool,
    base: bool,
}

/// Builds a [`Robot`]: which robot, which components, which backend, which overrides.
pub struct RobotBuilder {
    source: ConfigSource,
    backend: Backend,
    uses: Use,
    overrides: Vec<(String, toml::Value)>,
    scene: SceneSource,
    /// A scene already loaded (and perhaps changed), used instead of `scene`.
    loaded_scene: Option<Scene>,
    depth_noise: bool,
    camera_device: Option<Box<dyn CameraDevice>>,
    start_pose: Option<[f64; 3]>,
    camera_mount_error: [f64; 6],
    camera_calibration: Option<std::path::PathBuf>,
    marker: bool,
}

/// Largest camera mount error the simulator takes: 0.1 m along each axis, 0.5 rad about each.
pub const MAX_CAMERA_MOUNT_ERROR: [f64; 2] = [0.1, 0.5];

/// The simulated world a robot is connected to: the scene, the camera's depth noise and how
/// far the camera truly sits off its URDF mount, and the description the world is built from
/// (the URDF's, whatever calibration the host believes).
struct World {
    scene: Arc<Scene>,
    depth_noise: bool,
    mount_error: nalgebra::Isometry3<f64>,
    marker: bool,
    cfg: RobotConfig,
}

impl RobotBuilder {
    /// Start the simulated robot at `[x, y, θ]` (m, m, rad) in the scene's world frame instead
    /// of the scene's own start pose.
    pub fn start_pose(mut self, pose: [f64; 3]) -> Self {
        self.start_pose = Some(pose);
        self
    }
    /// The simulated world the robot lives in: a bundled scene (`empty`, `tabletop`,
    /// `apartment`, `shelf`, `clutter`) or the path of a scene file (default `empty`: an empty world, as
    /// before scenes existed). The simulator backend renders its camera from this world.
    pub fn scene(mut self, scene: &str) -> Self {
        self.scene = SceneSource::from_arg(scene);
        self
    }
    /// The simulated world as a scene already loaded (and perhaps changed: objects placed at
    /// random for a benchmark's trial), instead of [`RobotBuilder::scene`].
    pub fn with_scene(mut self, scene: Scene) -> Self {
        self.loaded_scene = Some(scene);
        self
    }

    /// Mount the simulated camera off its URDF pose by `[dx, dy, dz, droll, dpitch, dyaw]`
    /// (m and rad, in the camera link's frame: the true camera link is the URDF's times this
    /// pose, the rotation roll-pitch-yaw as in a URDF) for hand-eye calibration studies; on
    /// the sim and emulated backends. The host keeps believing the URDF (or the calibration
    /// of [`RobotBuilder::camera_calibration`]). Checked by [`RobotBuilder::build`]: finite,
    /// within [`MAX_CAMERA_MOUNT_ERROR`].
    pub fn camera_mount_error(mut self, error: [f64; 6]) -> Self {
        self.camera_mount_error = error;
        self
    }

    /// Draw the description's hand-eye marker (`[camera.marker]`) on the simulated robot, on
    /// the sim and emulated backends (default off: with the arm at home its corners sit fixed
    /// in the camera's view and visual SLAM takes them for features of the world;
    /// [`Robot::calibrate_camera`] needs it on).
    pub fn calibration_marker(mut self, on: bool) -> Self {
        self.marker = on;
        self
    }

    /// Use the camera mount measured by hand-eye calibration (a file of
    /// [`ferrobot_description::CameraCalibration`]) instead of the URDF's: every camera pose
    /// and cloud the host computes then uses it.
    pub fn camera_calibration(mut self, path: impl AsRef<Path>) -> Self {
        self.camera_calibration = Some(path.as_ref().to_path_buf());
        self
    }

    /// Simulate the depth camera's noise (default on: the D435's stereo noise model); off for
    /// exact depth.
    pub fn depth_noise(mut self, on: bool) -> Self {
        self.depth_noise = on;
        self
    }
    /// Use this camera device instead of the backend's (a real driver, a recording).
    pub fn camera_device(mut self, device: Box<dyn CameraDevice>) -> Self {
        self.camera_device = Some(device);
        self
    }
    /// Use the arm (default: when the robot has one).
    pub fn use_arm(mut self, on: bool) -> Self {
        self.uses.arm = on;
        self
    }
    /// Use the gripper (default: when the robot has one).
    pub fn use_gripper(mut self, on: bool) -> Self {
        self.uses.gripper = on;
        self
    }
    /// Use the camera and its pan-tilt head (default: when the robot has them).
    pub fn use_camera(mut self, on: bool) -> Self {
        self.uses.camera = on;
        self
    }
    /// Use the base (default: when the robot has one).
    pub fn use_base(mut self, on: bool) -> Self {
        self.uses.base = on;
        self
    }
    /// Choose the backend (default: the in-process simulator).
    pub fn backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self
    }
    /// Override one configuration value by its dotted key, e.g. `("arm.joint_tolerance", 0.005)`.
    pub fn set(mut self, key: &str, value: impl Into<toml::Value>) -> Self {
        self.overrides.push((key.to_string(), value.into()));
        self
    }

    /// Load, connect, configure.
    pub fn build(self) -> Result<Robot> {
        let world_cfg = ferrobot_profile::load(&self.source, &self.overrides)?;
        let mut cfg = world_cfg.clone();
        if let Some(path) = &self.camera_calibration {
            let c = ferrobot_description::CameraCalibration::load(path)?;
            cfg.set_camera_mount(&c, path)?;
        }
        let e = self.camera_mount_error;
        let [tmax, rmax] = MAX_CAMERA_MOUNT_ERROR;
        crate::validate::all_in_range("camera mount error (m)", &e[..3], -tmax, tmax)?;
        crate::validate::all_in_range("camera mount error (rad)", &e[3..], -rmax, rmax)?;
        let mount_error = crate::hand_eye::mount_error_pose(&e);
        let mut scene = match self.loaded_scene {
            Some(s) => s,
            None => Scene::load(&self.scene)?,
        };
        if let Some(p) = self.start_pose {
            let m = crate::validate::MAX_BASE_COORDINATE;
            crate::validate::all_in_range("start position", &p[..2], -m, m)?;
            crate::validate::in_range("start heading", p[2], -m, m)?;
            scene.robot_pose = p;
        }
        let world = World {
            scene: Arc::new(scene),
            depth_noise: self.depth_noise,
            mount_error,
            marker: self.marker,
            cfg: world_cfg,
        };
        Robot::connect(cfg, self.backend, self.uses, world, self.camera_device)
    }
}

/// A robot: its configuration, its components and the link to its firmware.
///
/// A `Robot` is a handle: clones share one robot, and it is `Send + Sync`, so a teleoperation
/// loop, a monitor and a program can each hold one. Its link sits behind one lock, taken for
/// each call and for each step of time, so calls from several threads interleave and every
/// reply reaches the call that asked for it. Component handles ([`Arm`], [`Base`], ...) and
/// motions ([`Motion`](crate::Motion)) hold a clone too: nothing borrows the robot while it
/// moves, and the arm, gripper, head and base move at the same time.
#[derive(Clone)]
pub struct Robot {
    inner: Arc<Inner>,
}

/// What a robot's handles share.
struct Inner {
    cfg: RobotConfig,
    uses: Use,
    /// The arm's kinematics (absent without an arm).
    arm: Option<ArmParts>,
    /// The URDF's frames (absent when the URDF's tree cannot be built).
    frames: Result<Frames, String>,
    /// The URDF frame of the camera's images (absent without a camera).
    optical: Option<String>,
    /// The robot's own body (its links' covering spheres), built on first use.
    body: std::sync::OnceLock<crate::sense::SelfBody>,
    /// The simulated world the robot started in (the empty one on hardware).
    scene: Arc<Scene>,
    /// The link's line for the emergency stop beside the I/O lock ([`Link::stop_line`]).
    stop_line: Option<Arc<dyn crate::backend::StopLine>>,
    io: Mutex<Io>,
}

/// The link and what changes with it: the goals under way and each component's state.
pub(crate) struct Io {
    /// The link to the firmware.
    pub(crate) link: Box<dyn Link>,
    /// The goals under way, their results, the faults.
    pub(crate) goals: Goals,
    /// The arm's state.
    pub(crate) arm: ArmState,
    /// The base's state.
    pub(crate) base: BaseState,
    /// The RGB-D camera, when the robot has and uses one.
    pub(crate) camera: Option<Box<dyn CameraDevice>>,
    /// SLAM beside the robot, once started.
    pub(crate) slam: Option<crate::slam::SlamRunner>,
    /// What the camera and SLAM tell the base's goals.
    pub(crate) sense: crate::sense::Sense,
}

impl std::fmt::Debug for Robot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Robot")
            .field("name", &self.inner.cfg.name)
            .finish_non_exhaustive()
    }
}

/// How many times [`Robot::emergency_stop`] sends the stop before it gives up.
pub const ESTOP_ATTEMPTS: usize = 3;

impl Robot {
    /// A bundled robot (`locobot`, `locobot_lite`, `sawyer`) on the in-process simulator.
    pub fn new(name: &str) -> Result<Robot> {
        Self::builder(name).build()
    }

    /// A robot from a TOML configuration file, on the in-process simulator.
    pub fn from_config(path: impl AsRef<Path>) -> Result<Robot> {
        Self::builder_from_config(path).build()
    }

    /// A builder for a bundled robot.
    pub fn builder(name: &str) -> RobotBuilder {
        RobotBuilder {
            source: ConfigSource::Bundled(name.to_string()),
            backend: Backend::default(),
            uses: Use {
                arm: true,
                gripper: true,
                camera: true,
                base: true,
            },
            overrides: Vec::new(),
            scene: SceneSource::default(),
            loaded_scene: None,
            depth_noise: true,
            camera_device: None,
            start_pose: None,
            camera_mount_error: [0.0; 6],
            camera_calibration: None,
            marker: false,
        }
    }

    /// A builder for a robot described by a TOML file.
    pub fn builder_from_config(path: impl AsRef<Path>) -> RobotBuilder {
        RobotBuilder {
            source: ConfigSource::File(path.as_ref().to_path_buf()),
            backend: Backend::default(),
            uses: Use {
                arm: true,
                gripper: true,
                camera: true,
                base: true,
            },
            overrides: Vec::new(),
            scene: SceneSource::default(),
            loaded_scene: None,
            depth_noise: true,
            camera_device: None,
            start_pose: None,
            camera_mount_error: [0.0; 6],
            camera_calibration: None,
            marker: false,
        }
    }

    fn connect(
        cfg: RobotConfig,
        backend: Backend,
        uses: Use,
        world: World,
        camera_device: Option<Box<dyn CameraDevice>>,
    ) -> Result<Robot> {
        let World {
            scene,
            depth_noise,
            mount_error,
            marker,
            cfg: world_cfg,
        } = world;
        // The link, and the socket of a camera served from the backend's world, if any.
        let (mut link, served_camera): (Box<dyn Link>, Option<std::path::PathBuf>) = match &backend
        {
            Backend::Sim { seed, realtime } => (
                Box::new(SimLink::start(&world_cfg, *seed, *realtime, scene.clone())?),
                None,
            ),
            // `ferrobot sim-firmware` serves its world's camera beside the port.
            Backend::Serial { path } => {
                let socket = ferrobot_sim::camera_server::socket_beside(path);
                (
                    Box::new(SerialLink::open(path, Duration::from_secs(10))?),
                    socket.exists().then_some(socket),
                )
            }
            Backend::Emulated { firmware } => {
                let camera = cfg
                    .camera
                    .clone()
                    .filter(|_| uses.camera && camera_device.is_none())
                    .map(|section| ferrobot_sim::camera_server::CameraOptions {
                        section,
                        seed: 1,
                        noise: depth_noise,
                        mount_error,
                        marker,
                    });
                let link = crate::backend::emulated::EmulatedLink::start_in(
                    &cfg.name,
                    firmware,
                    scene.clone(),
                    camera,
                )?;
                let socket = link.camera.as_ref().map(|c| c.path.clone());
                (Box::new(link), socket)
            }
        };
        let uses = Use {
            arm: uses.arm && cfg.arm.is_some(),
            gripper: uses.gripper && cfg.gripper.is_some(),
            camera: uses.camera && cfg.camera.is_some(),
            base: uses.base && cfg.base.is_some(),
        };
        let arm = ArmParts::new(&cfg)?;
        let base = BaseState::new(&cfg);
        let camera = match (&cfg.camera, uses.camera, camera_device) {
            (Some(_), true, Some(d)) => Some(d),
            (Some(section), true, None) => match (&backend, link.simulator(), served_camera) {
                (Backend::Sim { seed, .. }, Some(sim), _) => {
                    Some(Box::new(crate::backend::sim::SimCameraDevice::new(
                        sim,
                        section,
                        depth_noise,
                        *seed,
                        &mount_error,
                        marker,
                    )?) as Box<dyn CameraDevice>)
                }
                (_, _, Some(socket)) => Some(Box::new(
                    crate::backend::camera_socket::SocketCamera::connect(socket)?,
                ) as Box<dyn CameraDevice>),
                _ => None,
            },
            _ => None,
        };
        let frames = Frames::new(&cfg).map_err(|e| e.to_string());
        let optical = cfg.camera.as_ref().map(|c| c.frame.clone());
        let stop_line = link.stop_line();
        let robot = Robot {
            inner: Arc::new(Inner {
                stop_line,
                io: Mutex::new(Io {
                    link,
                    goals: Goals::default(),
                    arm: ArmState::default(),
                    base,
                    camera,
                    slam: None,
                    sense: Default::default(),
                }),
                cfg,
                uses,
                arm,
                frames,
                optical,
                body: std::sync::OnceLock::new(),
                scene: scene.clone(),
            }),
        };
        robot.check_joint_table()?;
        let geometry = robot
            .inner
            .cfg
            .base
            .as_ref()
            .filter(|_| robot.inner.uses.base)
            .and_then(ferrobot_profile::odometry_geometry);
        if let Some(g) = geometry {
            robot.base()?.set_odometry_geometry(g)?;
        }
        Ok(robot)
    }

    /// The world the robot was built in (a bundled or file scene; `empty` unless
    /// [`RobotBuilder::scene`] named one), with its start pose.
    pub fn scene(&self) -> Arc<Scene> {
        self.inner.scene.clone()
    }

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
    pub(crate) fn lock_io(&self) -> MutexGuard<'_, Io> {
        self.inner.io.lock()
    }

    /// Prepare a new goal with `claim`, send its first commands with `send`, and put it under
    /// way: one step under one lock, so no other thread's command comes between. Returns the
    /// motion.
    pub(crate) fn start_motion(
        &self,
        claim: Claim,
        what: &str,
        send: impl FnOnce(&mut Io) -> Result<(Box<dyn Goal>, Duration)>,
    ) -> Result<Motion> {
        let mut io = self.lock_io();
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

    /// Compare the firmware's robot, base and joint table with the configuration and push
    /// limits and gains.
    fn check_joint_table(&self) -> Result<()> {
        let cfg = self.cfg();
        let mut io = self.lock_io();
        let info = io.link.info().clone();
        if info.robot.as_str() != ferrobot_profile::firmware_profile(cfg).robot.as_str()
            || info.base != ferrobot_profile::base_kind(cfg)
        {
            return Err(Error::WrongRobot {
                config: cfg.name.clone(),
                config_base: format!("{:?}", ferrobot_profile::base_kind(cfg)),
                firmware: info.robot.as_str().to_string(),
                firmware_base: format!("{:?}", info.base),
            });
        }
        let n = cfg.joints.len();
        if info.joints.len() != n {
            return Err(Error::JointTableMismatch(format!(
                "the firmware has {} joints, the configuration {n}",
                info.joints.len()
            )));
        }
        for (i, ours) in ferrobot_profile::joint_table(cfg).iter().enumerate() {
            let fw = io.link.joint_config(i as u8)?;
            if fw.name != ours.name
                || fw.servo_id != ours.servo_id
                || fw.twin_id != ours.twin_id
                || fw.sign != ours.sign
            {
                return Err(Error::JointTableMismatch(format!(
                    "joint {i}: firmware has {:?} (servo {}, twin {:?}, sign {}), configuration {:?} (servo {}, twin {:?}, sign {})",
                    fw.name.as_str(),
                    fw.servo_id,
                    fw.twin_id,
                    fw.sign,
                    ours.name.as_str(),
                    ours.servo_id,
                    ours.twin_id,
                    ours.sign
                )));
            }
            if fw.limits != ours.limits {
                let limits: JointLimits = ours.limits;
                io.link.command(
                    &HostMsg::SetLimits {
                        joint: i as u8,
                        limits,
                    },
                    "joint limits",
                )?;
            }
            if fw.pid != ours.pid {
                let gains: PidGains = ours.pid;
                io.link.command(
                    &HostMsg::SetPid {
                        joint: i as u8,
                        gains,
                    },
                    "joint gains",
                )?;
            }
        }
        Ok(())
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

    /// The arm.
    pub fn arm(&self) -> Result<Arm> {
        if !self.inner.uses.arm {
            return Err(self.missing("arm"));
        }
        Ok(Arm::new(self.clone()))
    }

    /// The gripper.
    pub fn gripper(&self) -> Result<Gripper> {
        if !self.inner.uses.gripper {
            return Err(self.missing("gripper"));
        }
        Ok(Gripper::new(self.clone()))
    }

    /// The pan-tilt head that carries the camera.
    pub fn head(&self) -> Result<Head> {
        if !self.inner.uses.camera {
            return Err(self.missing("pan-tilt head"));
        }
        Head::new(self.clone())
    }

    /// The RGB-D camera: PyRobot's camera API. An error naming the robot when it has no
    /// camera, was built without it, or its backend serves no images.
    pub fn camera(&self) -> Result<Camera> {
        if !self.inner.uses.camera || self.lock_io().camera.is_none() {
            return Err(self.missing("camera"));
        }
        Ok(Camera::new(self.clone()))
    }

    /// The URDF's frames.
    pub(crate) fn frames(&self) -> Result<&Frames> {
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

    /// How far the robot's body reaches ahead of the base's centre now, m (see
    /// [`crate::sense::SelfBody::ahead`]): the largest x in the base's frame of its links'
    /// covering spheres that come down below `below` (m, the base's z): the base, its plates,
    /// the arm as it stands.
    pub(crate) fn body_ahead(&self, below: f64) -> Result<f64> {
        let frames = self.frames()?;
        let poses = frames.poses_in(&self.telemetry()?, crate::frames::BASE_FRAME)?;
        Ok(self.self_body()?.ahead(&poses, None, below))
    }

    /// The radius of the circle the robot's body sweeps as the base turns in place, m, in
    /// the pose it holds now: the footprint, and every link's covering spheres that come down
    /// below `below` (m, `base_link`'s z).
    pub(crate) fn body_radius(&self, below: f64) -> Result<f64> {
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
    pub(crate) fn optical_frame(&self) -> Result<String> {
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

    /// The mobile base.
    pub fn base(&self) -> Result<Base> {
        if !self.inner.uses.base {
            return Err(self.missing("base"));
        }
        Ok(Base::new(self.clone()))
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
        let mut io = self.lock_io();
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

    /// Leave the emergency stop.
    pub fn resume(&self) -> Result<()> {
        self.lock_io().link.command(&HostMsg::Resume, "resume")
    }

    /// The firmware's link and bus counters.
    pub fn diagnostics(&self) -> Result<ferrobot_protocol::Diagnostics> {
        self.lock_io().link.diagnostics()
    }

    /// The base commands that host-side base laws have sent: (time s, v m/s, ω rad/s).
    pub fn base_commands(&self) -> Vec<(f64, f64, f64)> {
        self.lock_io().base.log.clone()
    }

    /// The newest telemetry.
    pub fn telemetry(&self) -> Result<Telemetry> {
        self.lock_io().link.telemetry()
    }

    /// Faults reported since the last call (the newest [`crate::motion::FAULT_QUEUE`]),
    /// including those that ended motions.
    pub fn take_faults(&self) -> Vec<Fault> {
        let mut io = self.lock_io();
        io.collect_faults(self.cfg());
        io.goals.take_faults()
    }

    /// What happened to the link since the last call, oldest first (the newest
    /// [`crate::motion::LINK_EVENT_QUEUE`]): lost, and back with whether the firmware's watchdog
    /// stopped the robot meanwhile ([`LinkEvent`]). Always empty on the in-process simulator.
    pub fn take_link_events(&self) -> Vec<LinkEvent> {
        let mut io = self.lock_io();
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

    /// Let `dt` pass in steps of at most [`crate::motion::POLL`], stepping the motions under
    /// way, and let other threads at the link between steps.
    pub(crate) fn wait_for(&self, dt: Duration) {
        let cfg = self.cfg();
        let start = self.lock_io().link.now();
        let end = start.saturating_add(dt);
        loop {
            let mut io = self.lock_io();
            let now = io.link.now();
            if now >= end {
                break;
            }
            // At least the links' resolution (1 µs), so that a sub-microsecond rest ends.
            let step = (end - now).clamp(Duration::from_micros(1), crate::motion::POLL);
            io.pump(cfg, step);
            if io.link.now() <= now {
                // A clock that does not move (a link that has lost its firmware): the wait is
                // over; the next call reports the link's state.
                break;
            }
            MutexGuard::unlock_fair(io);
        }
    }

    /// The backend's clock, s.
    pub fn time(&self) -> f64 {
        self.lock_io().link.now().as_secs_f64()
    }

    /// The simulated world's ground truth now (the servos' true angles, the base's true pose,
    /// every scene body's pose in the world), on the simulator and on the emulated board; an
    /// error on hardware, which has none.
    pub fn truth(&self) -> Result<ferrobot_sim::lockstep::Truth> {
        self.lock_io()
            .link
            .truth()
            .ok_or_else(|| self.missing("ground truth (a simulated world)"))
    }

    /// The simulator behind this robot, when it is simulated (ground truth, fault injection).
    /// The guard holds the robot's link: drop it before calling the robot again (from this
    /// thread or waiting on another).
    pub fn simulator(&self) -> Option<MappedMutexGuard<'_, ferrobot_sim::LockstepSim>> {
        MutexGuard::try_map(self.lock_io(), |io| io.link.simulator()).ok()
    }
}

impl Io {
    /// Switch joints to a mode.
    pub(crate) fn set_mode(&mut self, joints: &[usize], mode: JointMode) -> Result<()> {
        let mask = crate::motion::joint_mask(joints.iter().copied());
        self.link
            .command(&HostMsg::SetMode { joints: mask, mode }, "mode change")
    }

    /// Queue one trajectory knot at rest (zero velocity and effort) for the joints in `mask`,
    /// at `positions` (rad, lowest joint first), `seconds` after the previous knot.
    pub(crate) fn send_rest_waypoint(
        &mut self,
        mask: u16,
        positions: impl IntoIterator<Item = f64>,
        seconds: f64,
        what: &str,
    ) -> Result<()> {
        let points = positions
            .into_iter()
            .map(|p| JointPoint::at_rest(p as f32))
            .collect();
        self.link.command(
            &HostMsg::Waypoint {
                joints: mask,
                duration_us: (seconds * 1e6) as u32,
                points,
            },
            what,
        )
    }
}
