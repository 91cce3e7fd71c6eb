//! Errors of planning.

/// What went wrong while planning.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The description or a scene object is not usable.
    #[error("invalid {what}: {why}")]
    Invalid {
        /// What was given.
        what: String,
        /// Why it is refused.
        why: String,
    },
    /// The start configuration is in collision.
    #[error("the start is in collision: {a} touches {b}")]
    StartInCollision {
        /// One body (a link or an object id).
        a: String,
        /// The other.
        b: String,
    },
    /// The goal configuration is in collision.
    #[error("the goal is in collision: {a} touches {b}")]
    GoalInCollision {
        /// One body (a link or an object id).
        a: String,
        /// The other.
        b: String,
    },
    /// No inverse-kinematics solution of the pose is free of collision.
    #[error("no collision-free IK solution: {why}")]
    NoFreeIk {
        /// What was tried.
        why: String,
    },
    /// No path was found within the time limit.
    #[error("no path found within {seconds} s")]
    Timeout {
        /// The time limit, s.
        seconds: f64,
    },
    /// A Cartesian straight line cannot be followed.
    #[error("the straight line cannot be followed: {why}")]
    Cartesian {
        /// Why.
        why: String,
    },
}

/// Result of planning.
pub type Result<T, E = Error> = std::result::Result<T, E>;
