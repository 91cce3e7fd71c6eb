//! The remote backend: a robot served by another process or machine ([`crate::Server`] with
//! [`crate::ServeOptions::remote`]), driven through the same API as one of one's own
//! ([`connect`]).
//!
//! The client runs the whole API (planning, motions, goals, typed errors); only the firmware's
//! link crosses the network ([`wire`]): commands and their acknowledgements, telemetry and
//! faults. The camera's frames come from the robot's ROS 2 topics.

pub mod camera;
pub mod link;
pub mod service;
pub mod wire;

use std::time::Duration;

use ferrobot::{Robot, RobotBuilder};

pub use camera::RemoteCameraDevice;
pub use link::RemoteLink;
pub use service::{RemoteService, RemoteStats};

use crate::access::{self, Access};
use crate::error::BridgeError;

/// A builder of robot `name` (the description the served robot was built from: `locobot`,
/// `sawyer`, …) served in `namespace` (`/` for none), reached with `access`: waits up to
/// `timeout` for it to answer, then [`RobotBuilder::build`] connects as any backend does
/// (the joint table checked, limits and gains pushed).
pub fn connect(
    name: &str,
    access: &Access,
    namespace: &str,
    timeout: Duration,
) -> Result<RobotBuilder, BridgeError> {
    attach(Robot::builder(name), name, access, namespace, timeout)
}

/// [`connect`], for a builder made elsewhere (from a configuration file, with its components
/// and overrides chosen): `builder` with the served robot's link and camera.
pub fn attach(
    builder: RobotBuilder,
    name: &str,
    access: &Access,
    namespace: &str,
    timeout: Duration,
) -> Result<RobotBuilder, BridgeError> {
    let session = access::open(access)?;
    let prefix = wire::prefix(namespace);
    let link = RemoteLink::connect(&session, &prefix, timeout)?;
    let info = link.remote_info().clone();
    if info.robot != name {
        return Err(BridgeError::Usage(format!(
            "the robot served under {prefix} is a {:?}, not a {name:?}",
            info.robot
        )));
    }
    let mut b = builder.link(Box::new(link));
    match &info.camera {
        Some(c) => {
            let cam =
                RemoteCameraDevice::connect(&session, info.domain, namespace, c, info.lockstep)?;
            b = b.camera_device(Box::new(cam));
        }
        None => b = b.use_camera(false),
    }
    Ok(b)
}
