//! The arm's own state: its joints, IK solvers, chains to its frames, planning scene and
//! joint mode, built once the robot is connected and shared by every [`crate::Arm`] handle.

use std::collections::HashMap;
use std::sync::Arc;

use ferrobot_planning::{CollisionModel, PlanningScene};
use ferrobot_protocol::JointMode;
use parking_lot::Mutex;

use crate::config::{IkKind, RobotConfig};
use crate::error::Result;
use crate::kinematics::ik::{IkSolver, NumericalIk};
use crate::kinematics::locobot_ik::LocobotIk;
use crate::kinematics::Chain;

/// The arm's kinematics, fixed once the robot is connected: its joints, its IK solvers and
/// the chains to its frames.
pub(crate) struct ArmParts {
    /// Firmware indices of the arm's joints, base to tip.
    pub(crate) joints: Vec<usize>,
    /// The solver the configuration chose.
    pub(crate) ik: Box<dyn IkSolver>,
    /// The closed-form pitch-roll solver, on LoCoBot-type arms.
    pub(crate) locobot_ik: Option<LocobotIk>,
    /// The arm's chain, base frame to end effector.
    pub(crate) chain: Chain,
    /// Chains from the arm's base frame to other frames, built when first asked for.
    pub(crate) chains: Mutex<HashMap<String, Arc<Chain>>>,
    /// The planning scene and collision model.
    pub(crate) planning: Mutex<ArmPlanning>,
    /// The mode the arm's joints were last switched to (`None`: as the firmware started,
    /// position mode). Changed only under the hub's lock, with the command that sets it.
    pub(crate) mode: Mutex<Option<JointMode>>,
}

impl ArmParts {
    /// The arm of `cfg`; `None` when it has none.
    pub(crate) fn new(cfg: &RobotConfig) -> Result<Option<ArmParts>> {
        let (Some(a), Some(chain)) = (&cfg.arm, ferrobot_profile::arm_chain(cfg)) else {
            return Ok(None);
        };
        let (ik, locobot_ik): (Box<dyn IkSolver>, Option<LocobotIk>) = match a.ik {
            IkKind::LocobotPitchRoll => {
                let l = LocobotIk::from_chain(&chain)?;
                (Box::new(l), Some(l))
            }
            IkKind::Numerical => (Box::new(NumericalIk), None),
        };
        Ok(Some(ArmParts {
            joints: a.joints.iter().filter_map(|n| cfg.joint_index(n)).collect(),
            ik,
            locobot_ik,
            chain,
            chains: Mutex::new(HashMap::new()),
            planning: Mutex::new(Default::default()),
            mode: Mutex::new(None),
        }))
    }

    /// The firmware joint mask of the arm.
    pub(crate) fn mask(&self) -> u16 {
        crate::goals::joint_mask(self.joints.iter().copied())
    }
}

/// The arm's planning state: the collision model (built when first needed) and the scene.
#[derive(Default)]
pub(crate) struct ArmPlanning {
    pub(crate) model: Option<Arc<CollisionModel>>,
    pub(crate) scene: PlanningScene,
}
