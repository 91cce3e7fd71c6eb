//! Building a [`Robot`]: which robot, which components, which backend ([`RobotBuilder`]); on
//! the simulated backends also which world (see [`crate::world_options`]). Connecting checks
//! the firmware's joint table against the description and pushes its limits and gains.

use std::path::Path;
use std::sync::Arc;

use ferrobot_protocol::{HostMsg, JointLimits, PidGains};
use parking_lot::Mutex;

use crate::arm_parts::ArmParts;
use crate::backend::device::CameraDevice;
use crate::backend::{Backend, Link};
use crate::base_state::BaseState;
use crate::config::{ConfigSource, RobotConfig};
use crate::error::{Error, Result};
use crate::frames::Frames;
use crate::goals::Goals;
use crate::hub::Hub;
use crate::robot::{Inner, Robot, Use};

/// How long connecting waits, of robot time, for the firmware to trust the arm's gravity
/// model (it needs the arm held still and settled for a fifth of a second).
pub const MODEL_WAIT: std::time::Duration = std::time::Duration::from_secs(1);

/// Builds a [`Robot`]: which robot, which components, which backend, which overrides.
pub struct RobotBuilder {
    pub(crate) source: ConfigSource,
    /// The backend; the in-process simulator when `None` (with the `sim` feature).
    pub(crate) backend: Option<Backend>,
    pub(crate) uses: Use,
    pub(crate) overrides: Vec<(String, toml::Value)>,
    pub(crate) camera_device: Option<Box<dyn CameraDevice>>,
    /// A link the caller made ([`RobotBuilder::link`]), in place of the backend's.
    pub(crate) link: Option<Box<dyn Link>>,
    pub(crate) camera_calibration: Option<std::path::PathBuf>,
    /// The simulated world, on the sim and emulated backends.
    #[cfg(feature = "sim")]
    pub(crate) world: crate::world_options::WorldOptions,
    /// What a serial link's timeouts count ([`RobotBuilder::board_clock`]).
    #[cfg(feature = "serial")]
    pub(crate) link_time: crate::backend::timebase::Timebase,
}

impl RobotBuilder {
    fn for_source(source: ConfigSource) -> RobotBuilder {
        RobotBuilder {
            source,
            backend: None,
            uses: Use {
                arm: true,
                gripper: true,
                camera: true,
                base: true,
            },
            overrides: Vec::new(),
            camera_device: None,
            link: None,
            camera_calibration: None,
            #[cfg(feature = "sim")]
            world: Default::default(),
            #[cfg(feature = "serial")]
            link_time: Default::default(),
        }
    }

    /// On [`Backend::Serial`](crate::backend::Backend::Serial) to an emulated board whose
    /// emulator runs in this program: count the link's timeouts (replies, the firmware's
    /// silence) on `clock`, the board's time in µs, instead of the wall clock, so that a busy
    /// machine slows the board without the link calling it lost. Ferrobot's own emulated
    /// backends do this by themselves.
    #[cfg(feature = "serial")]
    pub fn board_clock(mut self, clock: impl Fn() -> u64 + Send + Sync + 'static) -> Self {
        self.link_time = crate::backend::timebase::Timebase::board(std::sync::Arc::new(clock));
        self
    }

    /// Use the camera mount measured by hand-eye calibration (a file of
    /// [`ferrobot_description::CameraCalibration`]) instead of the URDF's: every camera pose
    /// and cloud the host computes then uses it.
    pub fn camera_calibration(mut self, path: impl AsRef<Path>) -> Self {
        self.camera_calibration = Some(path.as_ref().to_path_buf());
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
    /// Choose the backend (default: the in-process simulator, with the `sim` feature; without
    /// it a backend must be chosen).
    pub fn backend(mut self, backend: Backend) -> Self {
        self.backend = Some(backend);
        self
    }

    /// Drive the robot through `link`, a backend made outside this crate (the remote backend
    /// of `ferrobot-bridge`: a robot served by another process or machine), in place of
    /// [`RobotBuilder::backend`]'s; its camera, if any, given with
    /// [`RobotBuilder::camera_device`].
    pub fn link(mut self, link: Box<dyn Link>) -> Self {
        self.link = Some(link);
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
        let uses = self.uses;
        let connected = crate::connect::connect(self, &cfg, world_cfg)?;
        Robot::assemble(cfg, uses, connected)
    }
}

/// What connecting to a backend gives: the link, the camera device (when the robot uses one
/// and the backend or the caller gives it), and the simulated world's scene.
pub(crate) struct Connected {
    pub(crate) link: Box<dyn Link>,
    pub(crate) camera: Option<Box<dyn CameraDevice>>,
    #[cfg(feature = "sim")]
    pub(crate) scene: Arc<ferrobot_sim::scene::Scene>,
    /// The shared world the robot joined, if any.
    #[cfg(feature = "sim")]
    pub(crate) shared: Option<crate::SharedWorld>,
}

impl Robot {
    /// A bundled robot (`locobot`, `locobot_lite`, `sawyer`) on the in-process simulator.
    #[cfg(feature = "sim")]
    pub fn new(name: &str) -> Result<Robot> {
        Self::builder(name).build()
    }
    /// A robot from a TOML configuration file, on the in-process simulator.
    #[cfg(feature = "sim")]
    pub fn from_config(path: impl AsRef<Path>) -> Result<Robot> {
        Self::builder_from_config(path).build()
    }
    /// A builder for a bundled robot.
    pub fn builder(name: &str) -> RobotBuilder {
        RobotBuilder::for_source(ConfigSource::Bundled(name.to_string()))
    }
    /// A builder for a robot described by a TOML file.
    pub fn builder_from_config(path: impl AsRef<Path>) -> RobotBuilder {
        RobotBuilder::for_source(ConfigSource::File(path.as_ref().to_path_buf()))
    }

    /// The robot of `cfg` on a connected backend: its components' state, its joint table
    /// checked, its odometry geometry pushed.
    fn assemble(cfg: RobotConfig, uses: Use, connected: Connected) -> Result<Robot> {
        let uses = Use {
            arm: uses.arm && cfg.arm.is_some(),
            gripper: uses.gripper && cfg.gripper.is_some(),
            camera: uses.camera && cfg.camera.is_some(),
            base: uses.base && cfg.base.is_some(),
        };
        let arm = ArmParts::new(&cfg)?;
        let base = BaseState::new(&cfg);
        let frames = Frames::new(&cfg).map_err(|e| e.to_string());
        let optical = cfg.camera.as_ref().map(|c| c.frame.clone());
        let stop_line = connected.link.stop_line();
        let streams = crate::sensing::Streams::new(stop_line.is_none());
        let link = crate::events::Tapped::new(connected.link, streams.events.clone());
        let robot = Robot {
            inner: Arc::new(Inner {
                stop_line,
                io: Mutex::new(Hub {
                    link: Box::new(link),
                    goals: Goals::default(),
                    base,
                    camera: connected.camera,
                    slam: None,
                    sense: Default::default(),
                    streams,
                }),
                cfg,
                uses,
                arm,
                frames,
                optical,
                body: std::sync::OnceLock::new(),
                #[cfg(feature = "sim")]
                scene: connected.scene,
                #[cfg(feature = "sim")]
                shared: connected.shared.clone(),
            }),
        };
        #[cfg(feature = "sim")]
        if let Some(w) = &connected.shared {
            w.admit(&robot.inner);
        }
        robot.check_joint_table()?;
        if robot.inner.uses.arm {
            robot.send_arm_model()?;
        }
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

    /// Send the firmware the arm's gravity model from the description, link by link (see
    /// [`HostMsg::ArmLink`]); it trusts it once the arm, held still, bears it out. Waits up
    /// to [`MODEL_WAIT`] of robot time for that, so that the first motion already has its
    /// gravity compensation; an arm at rest unloaded, or one that contradicts the model
    /// (a payload, wrong masses), goes on without it.
    fn send_arm_model(&self) -> Result<()> {
        let Some(links) = ferrobot_profile::arm_model(self.cfg()) else {
            return Ok(());
        };
        let count = links.len() as u8;
        let mut io = self.lock_hub();
        for (index, link) in (0u8..).zip(links) {
            io.link.command(
                &HostMsg::ArmLink { index, count, link },
                "the arm's gravity model",
            )?;
        }
        let start = io.link.now();
        while io.link.telemetry()?.faults & ferrobot_protocol::fault_flags::ARM_MODEL == 0
            && io.link.now().saturating_sub(start) < MODEL_WAIT
        {
            io.link.wait(std::time::Duration::from_millis(10));
        }
        Ok(())
    }

    /// Compare the firmware's robot, base and joint table with the configuration and push
    /// limits and gains.
    fn check_joint_table(&self) -> Result<()> {
        let cfg = self.cfg();
        let mut io = self.lock_hub();
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
}
