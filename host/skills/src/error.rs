//! The skills' error: the robot's own ([`ferrobot::Error`]), or why a grasp could not be made
//! ([`GraspFailure`]).

use crate::grasp::GraspFailure;

/// Why a skill failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The robot refused or failed a call (a value out of range, a fault, a timeout, ...).
    #[error(transparent)]
    Robot(#[from] ferrobot::Error),
    /// A grasp could not be made: no object on the table, no feasible or reachable grasp,
    /// or the gripper closed on nothing.
    #[error("grasp: {0}")]
    Grasp(#[from] GraspFailure),
}

impl From<ferrobot_perception::PerceptionError> for Error {
    fn from(e: ferrobot_perception::PerceptionError) -> Self {
        Error::Robot(e.into())
    }
}

impl From<ferrobot::validate::ValueError> for Error {
    fn from(e: ferrobot::validate::ValueError) -> Self {
        Error::Robot(e.into())
    }
}

impl Error {
    /// Whether the caller's input was at fault (a value out of range, a wrong count), as
    /// [`ferrobot::Error::is_input`]; a grasp's failure is the world's, never the input's.
    pub fn is_input(&self) -> bool {
        match self {
            Error::Robot(e) => e.is_input(),
            Error::Grasp(_) => false,
        }
    }
}

/// The skills' result.
pub type Result<T> = std::result::Result<T, Error>;
