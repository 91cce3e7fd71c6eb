//! The in-process simulator backend: a [`SimHost`] (the protocol's host session in virtual
//! time) on a lockstep simulator built from the robot's configuration (servo chain, gravity
//! from the URDF's link masses, base): waiting for an answer runs the simulation.

use std::time::{Duration, Instant};

use ferrobot_protocol::session::{GetDiagnostics, GetJoint};
use ferrobot_protocol::{DeviceInfo, Diagnostics, Fault, HostMsg, JointConfig, Telemetry};
use ferrobot_sim::robots::SimRobot;
use ferrobot_sim::{LockstepSim, SimError, SimHost};

use super::{rejection, Link};
use crate::config::RobotConfig;
use crate::error::{Error, Result};

/// How far a simulator paced to the wall clock may run ahead of it ([`Link::pace`]).
pub const MAX_LEAD: Duration = Duration::from_millis(100);

/// The simulated robot a configuration describes ([`ferrobot_sim::robots::from_description`]).
pub fn sim_robot(cfg: &RobotConfig) -> SimRobot {
    ferrobot_sim::robots::from_description(cfg)
}

/// The simulator backend: the lockstep simulator driven by [`SimHost`], the protocol's host
/// session in virtual time.
pub struct SimLink {
    session: SimHost,
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
        let mut session = SimHost::new(sim);
        let info = session.handshake().map_err(|e| sim_err("hello", e))?;
        let mut link = SimLink {
            session,
            info,
            realtime: None,
        };
        // Let the firmware configure its servos before the first command.
        link.session
            .wait_telemetry(2_000_000, |t| {
                t.faults & ferrobot_protocol::fault_flags::CONFIGURING == 0
            })
            .map_err(|e| sim_err("servo configuration", e))?;
        if realtime {
            link.realtime = Some((Instant::now(), link.session.sim.now_us()));
        }
        Ok(link)
    }
}

impl SimLink {
    /// The lockstep simulator this link drives.
    pub fn simulator_mut(&mut self) -> &mut LockstepSim {
        &mut self.session.sim
    }
}

impl Link for SimLink {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }

    fn command(&mut self, msg: &HostMsg, what: &str) -> Result<()> {
        self.session.command(msg).map_err(|e| sim_err(what, e))
    }

    fn joint_config(&mut self, index: u8) -> Result<JointConfig> {
        self.session
            .request(&GetJoint(index))
            .map_err(|e| sim_err("joint configuration", e))
    }

    fn diagnostics(&mut self) -> Result<Diagnostics> {
        self.session
            .request(&GetDiagnostics)
            .map_err(|e| sim_err("diagnostics", e))
    }

    fn telemetry(&mut self) -> Result<Telemetry> {
        self.session
            .wait_telemetry(200_000, |_| true)
            .map_err(|_| Error::Link("no telemetry".into()))
    }

    fn take_telemetry(&mut self) -> Vec<Telemetry> {
        std::iter::from_fn(|| self.session.session.take_report()).collect()
    }

    fn wait(&mut self, dt: Duration) {
        self.session.run_for(dt.as_micros() as u64);
    }

    fn pace(&mut self) -> Duration {
        let Some((wall0, sim0)) = &mut self.realtime else {
            return Duration::ZERO;
        };
        let due = Duration::from_micros(self.session.sim.now_us() - *sim0);
        let lead = due.saturating_sub(wall0.elapsed());
        // Commands are acknowledged in the simulator's own time (a millisecond each): a flood
        // of them runs its clock ahead of the wall's. It leads by at most MAX_LEAD; beyond, the
        // pace starts again from there rather than stopping the world to let the wall catch up.
        if lead > MAX_LEAD {
            *wall0 = Instant::now();
            *sim0 = self
                .session
                .sim
                .now_us()
                .saturating_sub(MAX_LEAD.as_micros() as u64);
            return MAX_LEAD;
        }
        lead
    }

    fn now(&self) -> Duration {
        Duration::from_micros(self.session.sim.now_us())
    }

    fn take_faults(&mut self) -> Vec<Fault> {
        self.session.take_faults()
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
    /// The camera of `section` in the simulator `sim` (its scene and the robot's body), depth
    /// noise on or off, seeded by `seed`, at the section's rate (frames at whole multiples of
    /// the period on the simulator's clock; each capture takes the next one not yet taken),
    /// mounted off its URDF pose by `mount_error` (the camera link's frame; identity for
    /// none), the hand-eye marker drawn or not (`marker`).
    pub fn new(
        sim: &LockstepSim,
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
        let body = sim
            .body()
            .ok_or_else(|| bad("the simulated robot has no body to mount a camera on".into()))?;
        let mut camera =
            ferrobot_sim::camera::BandedCamera::new(sim.scene(), body, section, seed, noise)
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
        let sim = super::world::simulator_of(link).ok_or_else(|| {
            Error::Link("the simulated camera needs the simulator backend".into())
        })?;
        let truth = sim.truth();
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
