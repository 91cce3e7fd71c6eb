//! The in-process simulator backend: a [`SimHost`] (the protocol's host session in virtual
//! time) on a lockstep simulator built from the robot's configuration (servo chain, gravity
//! from the URDF's link masses, base): waiting for an answer runs the simulation.

use std::sync::Arc;
use std::time::{Duration, Instant};

use ferrobot_protocol::session::{GetDiagnostics, GetJoint};
use ferrobot_protocol::{DeviceInfo, Diagnostics, Fault, HostMsg, JointConfig, Telemetry};
use ferrobot_sim::robots::SimRobot;
use ferrobot_sim::shared::{Seat, SharedHosts};
use ferrobot_sim::{HostSide, LockstepSim, SimError, SimHost};
use parking_lot::{Mutex, MutexGuard};

use super::{rejection, Link};
use crate::config::RobotConfig;
use crate::error::{Error, Result};

/// How far a simulator paced to the wall clock may run ahead of it ([`Link::pace`]).
pub const MAX_LEAD: Duration = Duration::from_millis(100);

/// The simulated robot a configuration describes ([`ferrobot_sim::robots::from_description`]).
pub fn sim_robot(cfg: &RobotConfig) -> SimRobot {
    ferrobot_sim::robots::from_description(cfg)
}

/// What a [`SimLink`] drives: a simulated robot's host side ([`HostSide`]), alone on its
/// simulator ([`SimHost`]) or among others in a shared world ([`SharedSeat`]).
pub trait SimFloor: Send + 'static {
    /// The host side, borrowed for one call.
    type Side<'a>: HostSide
    where
        Self: 'a;
    /// The host side.
    fn side(&mut self) -> Self::Side<'_>;
    /// Simulated time, µs.
    fn now_us(&self) -> u64;
}

impl SimFloor for SimHost {
    type Side<'a> = &'a mut SimHost;
    fn side(&mut self) -> &mut SimHost {
        self
    }
    fn now_us(&self) -> u64 {
        self.sim.now_us()
    }
}

/// A robot's seat in a shared world ([`crate::SharedWorld`]): robot `index` of the world's
/// robots, whose waits pass every robot's time.
pub struct SharedSeat {
    pub(crate) hosts: Arc<Mutex<SharedHosts>>,
    pub(crate) index: usize,
}

impl SimFloor for SharedSeat {
    type Side<'a> = Seat<MutexGuard<'a, SharedHosts>>;
    fn side(&mut self) -> Self::Side<'_> {
        // A seat is made for a robot that joined, and robots never leave a world.
        Seat::new(self.hosts.lock(), self.index).expect("a joined robot keeps its seat")
    }
    fn now_us(&self) -> u64 {
        self.hosts.lock().sim.now_us()
    }
}

/// The simulator backend: a simulated robot's host side ([`SimFloor`]), the protocol's host
/// session in virtual time.
pub struct SimLink<F: SimFloor = SimHost> {
    floor: F,
    info: DeviceInfo,
    realtime: Option<(Instant, u64)>,
}

/// The API's error for a simulator session's, naming `what` was asked.
fn sim_err(what: &str, e: SimError) -> Error {
    match e {
        SimError::Rejected(r) => rejection(what, r),
        SimError::Timeout(waited) => Error::Timeout {
            what: format!("{what} ({waited})"),
            after: Duration::from_millis(200),
        },
        other => Error::Link(other.to_string()),
    }
}

impl SimLink {
    /// Simulate the robot of `cfg` in `scene` (at its start pose) with plants seeded by
    /// `seed`.
    pub fn start(
        cfg: &RobotConfig,
        seed: u64,
        realtime: bool,
        scene: std::sync::Arc<ferrobot_sim::scene::Scene>,
    ) -> Result<Self> {
        let sim = LockstepSim::with_scene(
            sim_robot(cfg),
            ferrobot_profile::firmware_profile(cfg),
            seed,
            scene,
        )?;
        SimLink::connect(SimHost::new(sim), realtime)
    }

    /// The lockstep simulator this link drives.
    pub fn simulator_mut(&mut self) -> &mut LockstepSim {
        &mut self.floor.sim
    }
}

impl SimLink<SharedSeat> {
    /// The robot of `cfg` joining the shared world `hosts` at `pose` (`[x, y, θ]`, m and
    /// rad) with plants seeded by `seed`.
    pub(crate) fn join(
        hosts: &Arc<Mutex<SharedHosts>>,
        cfg: &RobotConfig,
        seed: u64,
        realtime: bool,
        pose: [f64; 3],
    ) -> Result<Self> {
        let index = hosts.lock().join(
            sim_robot(cfg),
            ferrobot_profile::firmware_profile(cfg),
            seed,
            pose,
        )?;
        let seat = SharedSeat {
            hosts: hosts.clone(),
            index,
        };
        SimLink::connect(seat, realtime)
    }

    /// The seat this link drives.
    pub fn seat(&self) -> &SharedSeat {
        &self.floor
    }
}

impl<F: SimFloor> SimLink<F> {
    /// Handshake on `floor` and let the firmware configure its servos; paced to the wall
    /// clock from then on when `realtime`.
    fn connect(mut floor: F, realtime: bool) -> Result<Self> {
        let info = floor.side().handshake().map_err(|e| sim_err("hello", e))?;
        // Let the firmware configure its servos before the first command.
        floor
            .side()
            .wait_telemetry(2_000_000, |t| {
                t.faults & ferrobot_protocol::fault_flags::CONFIGURING == 0
            })
            .map_err(|e| sim_err("servo configuration", e))?;
        let realtime = realtime.then(|| (Instant::now(), floor.now_us()));
        Ok(SimLink {
            floor,
            info,
            realtime,
        })
    }
}

impl<F: SimFloor> Link for SimLink<F> {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }

    fn command(&mut self, msg: &HostMsg, what: &str) -> Result<()> {
        self.floor.side().command(msg).map_err(|e| sim_err(what, e))
    }

    fn joint_config(&mut self, index: u8) -> Result<JointConfig> {
        self.floor
            .side()
            .request(&GetJoint(index))
            .map_err(|e| sim_err("joint configuration", e))
    }

    fn diagnostics(&mut self) -> Result<Diagnostics> {
        self.floor
            .side()
            .request(&GetDiagnostics)
            .map_err(|e| sim_err("diagnostics", e))
    }

    fn telemetry(&mut self) -> Result<Telemetry> {
        self.floor
            .side()
            .wait_telemetry(200_000, |_| true)
            .map_err(|_| Error::Link("no telemetry".into()))
    }

    fn take_telemetry(&mut self) -> Vec<Telemetry> {
        let mut side = self.floor.side();
        std::iter::from_fn(|| side.end().session.take_report()).collect()
    }

    fn wait(&mut self, dt: Duration) {
        self.floor.side().run_for(dt.as_micros() as u64);
    }

    fn pace(&mut self) -> Duration {
        let now = self.floor.now_us();
        let Some((wall0, sim0)) = &mut self.realtime else {
            return Duration::ZERO;
        };
        let due = Duration::from_micros(now - *sim0);
        let lead = due.saturating_sub(wall0.elapsed());
        // Commands are acknowledged in the simulator's own time (a millisecond each): a flood
        // of them runs its clock ahead of the wall's. It leads by at most MAX_LEAD; beyond, the
        // pace starts again from there rather than stopping the world to let the wall catch up.
        if lead > MAX_LEAD {
            *wall0 = Instant::now();
            *sim0 = now.saturating_sub(MAX_LEAD.as_micros() as u64);
            return MAX_LEAD;
        }
        lead
    }

    fn now(&self) -> Duration {
        Duration::from_micros(self.floor.now_us())
    }

    fn take_faults(&mut self) -> Vec<Fault> {
        self.floor.side().take_faults()
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

/// The simulated world's RGB-D camera ([`ferrobot_sim::camera::BandedCamera`]: two bands of
/// rows on two threads) as a [`super::device::CameraDevice`]: frames come at the description's rate, on the
/// simulator's clock; a capture lets simulated time reach the next frame instant and renders
/// the world's ground truth there (the true joint angles and base pose, the scene's bodies).
pub struct SimCameraDevice {
    camera: ferrobot_sim::camera::BandedCamera,
    intrinsics: ferrobot_perception::Intrinsics,
    clock: ferrobot_sim::camera::FrameClock,
}

impl SimCameraDevice {
    /// The camera of `section` on the robot's `body` in `scene` (a simulated world, whose
    /// other robots it sees too: [`ferrobot_sim::lockstep::Truth::others`]), depth noise on or
    /// off, seeded by `seed`, at the section's rate (frames at whole multiples of
    /// the period on the simulator's clock; each capture takes the next one not yet taken),
    /// mounted off its URDF pose by `mount_error` (the camera link's frame; identity for
    /// none), the hand-eye marker drawn or not (`marker`).
    pub fn new(
        scene: &ferrobot_sim::scene::Scene,
        body: Option<&Arc<ferrobot_sim::body::RobotBody>>,
        section: &ferrobot_description::CameraSection,
        noise: bool,
        seed: u64,
        mount_error: &nalgebra::Isometry3<f64>,
        marker: bool,
    ) -> Result<Self> {
        let intrinsics = ferrobot_perception::Intrinsics::new(
            section.width,
            section.height,
            section.fx,
            section.fy,
            section.cx,
            section.cy,
        )?;
        let bad = |problem: String| Error::Config {
            file: "robot description".into(),
            key: "camera".into(),
            problem,
        };
        let body =
            body.ok_or_else(|| bad("the simulated robot has no body to mount a camera on".into()))?;
        let mut camera = ferrobot_sim::camera::BandedCamera::new(scene, body, section, seed, noise)
            .ok_or_else(|| {
                bad(format!(
                    "the URDF has no optical frame {:?}, or the image is under 4 rows",
                    section.frame
                ))
            })?;
        camera.set_mount_error(body, mount_error);
        camera.show_decals(marker);
        let clock = ferrobot_sim::camera::FrameClock::new(section.rate)
            .ok_or_else(|| bad(format!("rate {} Hz (need (0, 1000])", section.rate)))?;
        Ok(SimCameraDevice {
            camera,
            intrinsics,
            clock,
        })
    }
}

impl super::device::CameraDevice for SimCameraDevice {
    fn intrinsics(&self) -> ferrobot_perception::Intrinsics {
        self.intrinsics
    }

    fn rate(&self) -> f64 {
        self.clock.rate()
    }

    fn knows_frame_instants(&self) -> bool {
        true
    }

    fn until_next(&self, now: Duration) -> Duration {
        let now_us = now.as_micros() as u64;
        Duration::from_micros(self.clock.peek(now_us).saturating_sub(now_us))
    }

    fn capture(&mut self, link: &mut dyn Link) -> Result<super::device::RawFrame> {
        // The next frame instant not yet captured.
        let now = link.now().as_micros() as u64;
        let next = self.clock.next(now);
        if next > now {
            link.wait(Duration::from_micros(next - now));
        }
        let truth = super::world::truth_of(link).ok_or_else(|| {
            Error::Link("the simulated camera needs the simulator backend".into())
        })?;
        let (rgb, depth) = self.camera.capture(&truth);
        let (w, h) = self.camera.width_height();
        Ok(super::device::RawFrame {
            rgb: ferrobot_perception::RgbImage::new(w, h, rgb)?,
            depth: ferrobot_perception::DepthImage::new(w, h, depth)?,
            time: Duration::from_micros(truth.time_us),
            device_time: None,
        })
    }
}
