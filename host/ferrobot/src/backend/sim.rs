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
    /// Simulate the robot of `cfg` with plants seeded by `seed`.
    pub fn start(cfg: &RobotConfig, seed: u64, realtime: bool) -> Result<Self> {
        let sim = LockstepSim::with(sim_robot(cfg), cfg.firmware_profile(), seed);
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

    fn wait(&mut self, dt: Duration) {
        self.session.run_for(dt.as_micros() as u64);
        if let Some((wall0, sim0)) = self.realtime {
            let due = Duration::from_micros(self.session.sim.now_us() - sim0);
            if let Some(rest) = due.checked_sub(wall0.elapsed()) {
                std::thread::sleep(rest);
            }
        }
    }

    fn now(&self) -> Duration {
        Duration::from_micros(self.session.sim.now_us())
    }

    fn take_faults(&mut self) -> Vec<Fault> {
        self.session.take_faults()
    }

    fn simulator(&mut self) -> Option<&mut LockstepSim> {
        Some(&mut self.session.sim)
    }
}
