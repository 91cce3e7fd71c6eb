//! The simulated world behind a link, for what only a simulator has: ground truth and the
//! lockstep simulator itself (fault injection, the camera's renderer). An extension of the sim
//! and emulated backends (cargo feature `sim`), reached by downcasting the link, so that
//! [`Link`] names no simulator type and a robot built without `sim` has none of this.

use ferrobot_sim::lockstep::Truth;
use ferrobot_sim::LockstepSim;

use super::sim::{SharedSeat, SimLink};
use super::Link;

/// The in-process simulator behind `link`, when it is the sim backend's.
pub fn simulator_of(link: &mut dyn Link) -> Option<&mut LockstepSim> {
    link.as_any_mut()
        .downcast_mut::<SimLink>()
        .map(|l| l.simulator_mut())
}

/// The simulated world's ground truth now, when `link`'s plants are simulated (in-process,
/// alone or in a shared world, or behind an emulated board); `None` on a real robot.
pub fn truth_of(link: &mut dyn Link) -> Option<Truth> {
    if let Some(sim) = simulator_of(link) {
        return Some(sim.truth());
    }
    if let Some(l) = link.as_any_mut().downcast_mut::<SimLink<SharedSeat>>() {
        let seat = l.seat();
        return seat.hosts.lock().sim.truth(seat.index);
    }
    #[cfg(feature = "emulated")]
    if let Some(e) = link
        .as_any_mut()
        .downcast_mut::<super::emulated::EmulatedLink>()
    {
        return Some(e.truth());
    }
    None
}

/// The scene and the robot's body of `link`'s in-process simulator (alone or in a shared
/// world): what its camera renders.
pub fn scene_and_body_of(
    link: &mut dyn Link,
) -> Option<(
    std::sync::Arc<ferrobot_sim::scene::Scene>,
    Option<std::sync::Arc<ferrobot_sim::body::RobotBody>>,
)> {
    if let Some(sim) = simulator_of(link) {
        return Some((sim.scene().clone(), sim.body().cloned()));
    }
    let l = link.as_any_mut().downcast_mut::<SimLink<SharedSeat>>()?;
    let seat = l.seat();
    let hosts = seat.hosts.lock();
    let body = hosts.sim.station(seat.index)?.body().cloned();
    Some((hosts.sim.scene().clone(), body))
}
