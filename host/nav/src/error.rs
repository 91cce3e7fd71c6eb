//! The error of this crate.

pub use ferrobot_geometry::ValueError;

/// Everything that can go wrong here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A number that is not valid where it was given (not finite, or out of range).
    #[error(transparent)]
    Value(#[from] ValueError),
    /// An occupancy-grid map that cannot be used.
    #[error("invalid map: {why}")]
    InvalidMap {
        /// Why.
        why: String,
    },
    /// A map file (map_server's YAML or its image) that cannot be read or written.
    #[error("map file {}: {why}", path.display())]
    MapFile {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        why: String,
    },
    /// A path's end outside the map.
    #[error("the {what} {at:?} (m) is outside the map")]
    OutsideMap {
        /// `"start"` or `"goal"`.
        what: &'static str,
        /// Where, m.
        at: [f64; 2],
    },
    /// A path's end too near an obstacle for the robot.
    #[error("the {what} {at:?} (m) is {clearance:.3} m from an obstacle, nearer than the robot's radius {radius} m")]
    Blocked {
        /// `"start"` or `"goal"`.
        what: &'static str,
        /// Where, m.
        at: [f64; 2],
        /// Its clearance, m.
        clearance: f64,
        /// The robot's radius, m.
        radius: f64,
    },
    /// No collision-free path between the ends on the map.
    #[error("no path from {from:?} to {to:?} (m) for a robot of radius {radius} m on this map")]
    NoPath {
        /// Start, m.
        from: [f64; 2],
        /// Goal, m.
        to: [f64; 2],
        /// The robot's radius, m.
        radius: f64,
    },
    /// The base made no progress towards the goal, recoveries included.
    #[error("no progress towards the goal at {at:?} (m), {left:.2} m of the way left, after {recoveries} recoveries")]
    Stalled {
        /// Where the base stopped, m.
        at: [f64; 2],
        /// The way left along the path, m.
        left: f64,
        /// Recoveries tried.
        recoveries: u32,
    },
}

impl Error {
    /// Whether the caller's input is at fault (a value, a map file, an end off the map or in
    /// an obstacle) rather than the map having no way through.
    pub fn is_input(&self) -> bool {
        !matches!(self, Error::NoPath { .. } | Error::Stalled { .. })
    }
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
