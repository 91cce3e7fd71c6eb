//! The bridge's errors.

/// Why the bridge could not do what it was asked.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BridgeError {
    /// zenoh refused: a session that could not open (an endpoint in use, credentials refused),
    /// a declaration that failed.
    #[error("zenoh: {what}: {reason}")]
    Zenoh {
        /// What was being done.
        what: String,
        /// zenoh's words.
        reason: String,
    },
    /// A robot served on an endpoint others can reach, without credentials.
    #[error(
        "serving on {endpoint} lets other machines in: give credentials (a user and password) \
         or listen on loopback only"
    )]
    Unauthenticated {
        /// The endpoint beyond loopback.
        endpoint: String,
    },
    /// A setting that cannot be used (an endpoint that is not `tcp/<host>:<port>`, a name ROS
    /// refuses).
    #[error("{0}")]
    Usage(String),
    /// The robot refused.
    #[error(transparent)]
    Robot(#[from] ferrobot::Error),
    /// A type whose hash could not be computed (a definition that does not parse).
    #[error(transparent)]
    TypeHash(#[from] ferrobot_ros2::type_hash::TypeHashError),
}

impl BridgeError {
    /// zenoh's error `e` while doing `what`.
    pub(crate) fn zenoh(what: impl Into<String>, e: impl std::fmt::Display) -> Self {
        BridgeError::Zenoh {
            what: what.into(),
            reason: e.to_string(),
        }
    }
}

/// The API's error for a bridge's: a robot's own stays itself, a setting is a usage error, the
/// network's is the link's.
impl From<BridgeError> for ferrobot::Error {
    fn from(e: BridgeError) -> ferrobot::Error {
        match e {
            BridgeError::Robot(e) => e,
            BridgeError::Usage(w) => ferrobot::Error::Usage(w),
            e @ BridgeError::Unauthenticated { .. } => ferrobot::Error::Usage(e.to_string()),
            e => ferrobot::Error::Link(e.to_string()),
        }
    }
}
