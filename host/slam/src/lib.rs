//! Ferrobot's visual SLAM: RGB-D tracking fused with wheel odometry, keyframes, relocalisation
//! and loop closure on a pose graph ([`Slam`]); the maps it builds (a coloured voxel cloud, an
//! occupancy grid in ROS map_server's form); trajectories in the TUM RGB-D format and their
//! absolute trajectory error.
//!
//! Frames: the map's frame is the world's (a robot starts at its known start pose in it);
//! poses are of the body (`base_link`, or the camera for a hand-held sequence) in the map;
//! the camera's optical frame is x right, y down, z forward. SI units.
//!
//! Like every algorithm crate of Ferrobot it knows nothing of wires or backends: it takes
//! images, the camera's pose on the body and odometry readings.

pub mod dataset;
pub mod error;
mod frame;
pub mod map;
mod map_file;
pub mod maps;
pub mod optimise;
pub mod orb;
pub mod slam;
pub mod trajectory;

pub use dataset::{Dataset, DatasetWriter};
pub use error::{Error, Result};
pub use map::{Keyframe, Map};
pub use maps::{
    map_iou, map_iou_seen, reachable_part, GridSettings, MapIou, OccupancyGrid, MAX_SLACK,
};
pub use optimise::Dof;
pub use slam::{RgbdInput, Slam, SlamSettings, TrackReport, TrackState, MAX_INLIERS, MAX_LOOP_AGE};
pub use trajectory::{ate, parse_tum, to_tum, write_tum, Ate, Stamped};
