//! Building a [`Robot`]: which robot, which components, which backend, which world
//! ([`RobotBuilder`]); connecting to its firmware and checking the firmware's joint table
//! against the description.

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use ferrobot_protocol::{HostMsg, JointLimits, PidGains};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use parking_lot::Mutex;

use crate::arm_parts::ArmParts;
use crate::backend::serial::SerialLink;
use crate::backend::sim::SimLink;
use crate::backend::{Backend, Link};
use crate::base_state::BaseState;
use crate::camera::CameraDevice;
use crate::config::{ConfigSource, RobotConfig};
use crate::error::{Error, Result};
use crate::frames::Frames;
use crate::goals::Goals;
use crate::hub::Hub;
use crate::robot::{Inner, Robot, Use};
use ferrobot_sim::scene::{Scene, SceneSource};

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
        let world_cfg = RobotConfig::load(&self.source, &self.overrides)?;
        let mut cfg = world_cfg.clone();
        if let Some(path) = &self.camera_calibration {
            let c = ferrobot_description::CameraCalibration::load(path)?;
            cfg.set_camera_mount(&c, path)?;
        }
        let e = self.camera_mount_error;
        let [tmax, rmax] = MAX_CAMERA_MOUNT_ERROR;
        crate::validate::all_in_range("camera mount error (m)", &e[..3], -tmax, tmax)?;
        crate::validate::all_in_range("camera mount error (rad)", &e[3..], -rmax, rmax)?;
        let mount_error = mount_error_pose(&e);
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
                io: Mutex::new(Hub {
                    link,
                    goals: Goals::default(),
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
            .and_then(|b| b.odometry);
        if let Some(g) = geometry {
            robot.base()?.set_odometry_geometry(g)?;
        }
        Ok(robot)
    }

    /// Compare the firmware's robot, base and joint table with the configuration and push
    /// limits and gains.
    fn check_joint_table(&self) -> Result<()> {
        let cfg = self.cfg();
        let mut io = self.lock_hub();
        let info = io.link.info().clone();
        if info.robot.as_str() != cfg.firmware_profile().robot.as_str()
            || info.base != cfg.base_kind()
        {
            return Err(Error::WrongRobot {
                config: cfg.name.clone(),
                config_base: format!("{:?}", cfg.base_kind()),
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
        for (i, ours) in cfg.joints.iter().enumerate() {
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

/// The pose of a camera mount error `[dx, dy, dz, droll, dpitch, dyaw]` (m and rad; the
/// rotation roll-pitch-yaw as in a URDF): the true camera link is the URDF's times this pose
/// ([`RobotBuilder::camera_mount_error`]).
pub fn mount_error_pose(e: &[f64; 6]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(e[0], e[1], e[2]),
        UnitQuaternion::from_euler_angles(e[3], e[4], e[5]),
    )
}
