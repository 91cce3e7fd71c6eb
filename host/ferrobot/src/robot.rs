//! [`Robot`]: one robot, its components and its backend.

use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;

use ferrobot_protocol::{
    DeviceMsg, Fault, HostMsg, JointLimits, JointMode, JointPoint, PidGains, Telemetry,
};

use crate::arm::Arm;
use crate::backend::serial::SerialLink;
use crate::backend::sim::SimLink;
use crate::backend::{Backend, Link};
use crate::base::Base;
use crate::config::{ConfigSource, IkKind, RobotConfig};
use crate::error::{Error, Result};
use crate::gripper::Gripper;
use crate::kinematics::ik::{IkSolver, NumericalIk};
use crate::kinematics::locobot_ik::LocobotIk;
use crate::kinematics::Chain;
use crate::pan_tilt::PanTilt;

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
}

impl RobotBuilder {
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
    /// Use the camera's pan-tilt head (default: when the robot has one).
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
        let cfg = RobotConfig::load(&self.source, &self.overrides)?;
        Robot::connect(cfg, self.backend, self.uses)
    }
}

/// A robot: its configuration, its components and the link to its firmware.
pub struct Robot {
    pub(crate) cfg: RobotConfig,
    pub(crate) link: Box<dyn Link>,
    uses: Use,
    pub(crate) arm_mode: JointMode,
    pub(crate) ik: Option<Box<dyn IkSolver>>,
    pub(crate) locobot_ik: Option<LocobotIk>,
    pub(crate) chains: HashMap<String, Chain>,
    pub(crate) arm_joints: Vec<usize>,
    /// Base commands sent by the trajectory tracker: (time s, v m/s, ω rad/s).
    pub(crate) base_log: Vec<(f64, f64, f64)>,
    /// While recording: the wheel angles `[left, right]` (rad) of each telemetry frame a
    /// motion has seen, with the frame's firmware time (µs).
    pub(crate) wheel_log: Option<Vec<(u64, [f64; 2])>>,
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
        }
    }

    fn connect(cfg: RobotConfig, backend: Backend, uses: Use) -> Result<Robot> {
        let link: Box<dyn Link> = match &backend {
            Backend::Sim { seed, realtime } => Box::new(SimLink::start(&cfg, *seed, *realtime)?),
            Backend::Serial { path } => Box::new(SerialLink::open(path, Duration::from_secs(10))?),
            Backend::Emulated { firmware } => Box::new(
                crate::backend::emulated::EmulatedLink::start(&cfg.name, firmware)?,
            ),
        };
        let uses = Use {
            arm: uses.arm && cfg.arm.is_some(),
            gripper: uses.gripper && cfg.gripper.is_some(),
            camera: uses.camera && cfg.camera.is_some(),
            base: uses.base && cfg.base.is_some(),
        };
        let (ik, locobot_ik): (Option<Box<dyn IkSolver>>, Option<LocobotIk>) =
            match (&cfg.arm, &cfg.arm_chain) {
                (Some(a), Some(chain)) => match a.ik {
                    IkKind::LocobotPitchRoll => {
                        let l = LocobotIk::from_chain(chain)?;
                        (Some(Box::new(l)), Some(l))
                    }
                    IkKind::Numerical => (Some(Box::new(NumericalIk)), None),
                },
                _ => (None, None),
            };
        let arm_joints = cfg
            .arm
            .as_ref()
            .map(|a| a.joints.iter().filter_map(|n| cfg.joint_index(n)).collect())
            .unwrap_or_default();
        let mut robot = Robot {
            cfg,
            link,
            uses,
            arm_mode: JointMode::Position,
            ik,
            locobot_ik,
            chains: HashMap::new(),
            arm_joints,
            base_log: Vec::new(),
            wheel_log: None,
        };
        robot.check_joint_table()?;
        let geometry = robot
            .cfg
            .base
            .as_ref()
            .filter(|_| robot.uses.base)
            .and_then(|b| b.odometry);
        if let Some(g) = geometry {
            robot.base()?.set_odometry_geometry(g)?;
        }
        Ok(robot)
    }

    /// Compare the firmware's robot, base and joint table with the configuration and push
    /// limits and gains.
    fn check_joint_table(&mut self) -> Result<()> {
        let info = self.link.info();
        if info.robot.as_str() != self.cfg.firmware_profile().robot.as_str()
            || info.base != self.cfg.base_kind()
        {
            return Err(Error::WrongRobot {
                config: self.cfg.name.clone(),
                config_base: format!("{:?}", self.cfg.base_kind()),
                firmware: info.robot.as_str().to_string(),
                firmware_base: format!("{:?}", info.base),
            });
        }
        let n = self.cfg.joints.len();
        if self.link.info().joints.len() != n {
            return Err(Error::JointTableMismatch(format!(
                "the firmware has {} joints, the configuration {n}",
                self.link.info().joints.len()
            )));
        }
        for i in 0..n {
            let reply = self.link.request(
                &HostMsg::GetJoint { index: i as u8 },
                &|m| matches!(m, DeviceMsg::Joint { index, .. } if *index as usize == i),
            )?;
            let DeviceMsg::Joint { config: fw, .. } = reply else {
                continue;
            };
            let ours = &self.cfg.joints[i];
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
                self.link.command(
                    &HostMsg::SetLimits {
                        joint: i as u8,
                        limits,
                    },
                    "joint limits",
                )?;
            }
            if fw.pid != ours.pid {
                let gains: PidGains = ours.pid;
                self.link.command(
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
        &self.cfg
    }

    /// The robot's name.
    pub fn name(&self) -> &str {
        &self.cfg.name
    }

    /// The error for a component this robot lacks (or was built without).
    pub(crate) fn missing(&self, component: &'static str) -> Error {
        Error::NoComponent {
            robot: self.cfg.name.clone(),
            component,
        }
    }

    /// The arm.
    pub fn arm(&mut self) -> Result<Arm<'_>> {
        if !self.uses.arm {
            return Err(self.missing("arm"));
        }
        Ok(Arm::new(self))
    }

    /// The gripper.
    pub fn gripper(&mut self) -> Result<Gripper<'_>> {
        if !self.uses.gripper {
            return Err(self.missing("gripper"));
        }
        Ok(Gripper::new(self))
    }

    /// The camera's pan-tilt head.
    pub fn camera(&mut self) -> Result<PanTilt<'_>> {
        if !self.uses.camera {
            return Err(self.missing("camera"));
        }
        Ok(PanTilt::new(self))
    }

    /// The mobile base.
    pub fn base(&mut self) -> Result<Base<'_>> {
        if !self.uses.base {
            return Err(self.missing("base"));
        }
        Ok(Base::new(self))
    }

    /// Emergency stop: the firmware stops the base, holds the arm and refuses motion until
    /// [`Robot::resume`].
    pub fn emergency_stop(&mut self) -> Result<()> {
        self.link.command(&HostMsg::EmergencyStop, "emergency stop")
    }

    /// Leave the emergency stop.
    pub fn resume(&mut self) -> Result<()> {
        self.link.command(&HostMsg::Resume, "resume")
    }

    /// The firmware's link and bus counters.
    pub fn diagnostics(&mut self) -> Result<ferrobot_protocol::Diagnostics> {
        match self.link.request(&HostMsg::GetDiagnostics, &|m| {
            matches!(m, DeviceMsg::Diagnostics(_))
        })? {
            DeviceMsg::Diagnostics(d) => Ok(d),
            _ => Err(Error::Link("unexpected reply".into())),
        }
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

    /// While a wheel log is kept, add the wheel angles of telemetry frame `t` unless it is the
    /// frame logged last.
    pub(crate) fn log_wheels(&mut self, t: &Telemetry) {
        if let Some(log) = &mut self.wheel_log {
            if log.last().map(|l| l.0) != Some(t.time_us) {
                log.push((t.time_us, [t.wheels.left as f64, t.wheels.right as f64]));
            }
        }
    }

    /// The base commands the trajectory tracker has sent: (time s, v m/s, ω rad/s).
    pub fn base_commands(&self) -> &[(f64, f64, f64)] {
        &self.base_log
    }

    /// The newest telemetry.
    pub fn telemetry(&mut self) -> Result<Telemetry> {
        self.link.telemetry()
    }

    /// Faults reported since the last call.
    pub fn take_faults(&mut self) -> Vec<Fault> {
        self.link.take_faults()
    }

    /// Let `seconds` pass (simulated time on the simulator): finite, in
    /// `[0, validate::MAX_DURATION_S]`.
    pub fn wait(&mut self, seconds: f64) -> Result<()> {
        let dt = crate::validate::seconds("wait time", seconds)?;
        self.link.wait(dt);
        Ok(())
    }

    /// The backend's clock, s.
    pub fn time(&self) -> f64 {
        self.link.now().as_secs_f64()
    }

    /// The simulator behind this robot, when it is simulated (ground truth, fault injection).
    pub fn simulator(&mut self) -> Option<&mut ferrobot_sim::LockstepSim> {
        self.link.simulator()
    }

    /// A chain from the arm's base frame to `frame`, cached.
    pub(crate) fn chain_to(&mut self, frame: &str) -> Result<&Chain> {
        let base = self
            .cfg
            .arm
            .as_ref()
            .map(|a| a.base_frame.clone())
            .ok_or_else(|| self.missing("arm"))?;
        if !self.chains.contains_key(frame) {
            let c = Chain::from_urdf(&self.cfg.urdf, &base, frame)?;
            self.chains.insert(frame.to_string(), c);
        }
        self.chains.get(frame).ok_or_else(|| Error::UnknownName {
            what: "frame",
            name: frame.into(),
        })
    }

    /// Switch joints to a mode.
    pub(crate) fn set_mode(&mut self, joints: &[usize], mode: JointMode) -> Result<()> {
        let mask = joints.iter().fold(0u16, |m, &j| m | (1 << j));
        self.link
            .command(&HostMsg::SetMode { joints: mask, mode }, "mode change")
    }
}
