//! Backends: where the firmware runs. The API talks to all of them through [`Link`]; a program
//! does not know which one it has, except through the configuration it was given.
//!
//! * [`Backend::Sim`] (the default): the firmware core and the simulated plants in-process, in
//!   lockstep on a virtual clock. Waiting advances simulated time, so a 10 s motion takes
//!   milliseconds; `realtime` paces it to the wall clock for viewing and teleoperation.
//! * [`Backend::Serial`]: the firmware behind a serial port (a board over USB, QEMU or a
//!   firmware process behind a PTY). One I/O thread owns the port.
//! * [`Backend::Emulated`]: the real board firmware in QEMU with the simulated plants, started
//!   in one call, over the serial backend.
//! * [`Backend::Direct`]: the host-run firmware on a stock robot's own serial devices;
//!   [`Backend::DirectEmulated`] the same on the simulated plants' emulated devices.

/// `impl Link` for a type that keeps a backend alive around the [`serial::SerialLink`] in its
/// field `serial` (the emulated board, the host-run firmware): every call goes to the serial
/// link, and [`Link::as_any_mut`] gives the type itself. Both users need `direct` (`emulated`
/// implies it), so a build with `serial` alone has no unused macro.
#[cfg(feature = "direct")]
macro_rules! link_through_serial {
    ($t:ty) => {
        impl $crate::backend::Link for $t {
            fn info(&self) -> &ferrobot_protocol::DeviceInfo {
                self.serial.info()
            }
            fn command(
                &mut self,
                msg: &ferrobot_protocol::HostMsg,
                what: &str,
            ) -> $crate::error::Result<()> {
                self.serial.command(msg, what)
            }
            fn joint_config(
                &mut self,
                index: u8,
            ) -> $crate::error::Result<ferrobot_protocol::JointConfig> {
                self.serial.joint_config(index)
            }
            fn diagnostics(&mut self) -> $crate::error::Result<ferrobot_protocol::Diagnostics> {
                self.serial.diagnostics()
            }
            fn telemetry(&mut self) -> $crate::error::Result<ferrobot_protocol::Telemetry> {
                self.serial.telemetry()
            }
            fn take_telemetry(&mut self) -> Vec<ferrobot_protocol::Telemetry> {
                self.serial.take_telemetry()
            }
            fn wait(&mut self, dt: std::time::Duration) {
                self.serial.wait(dt)
            }
            fn now(&self) -> std::time::Duration {
                self.serial.now()
            }
            fn take_faults(&mut self) -> Vec<ferrobot_protocol::Fault> {
                self.serial.take_faults()
            }
            fn take_events(&mut self) -> Vec<$crate::backend::LinkEvent> {
                self.serial.take_events()
            }
            fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
                self
            }
            fn stop_line(&self) -> Option<std::sync::Arc<dyn $crate::backend::StopLine>> {
                self.serial.stop_line()
            }
        }
    };
}

#[cfg(feature = "serial")]
pub mod camera_socket;
pub mod device;
#[cfg(feature = "direct")]
pub mod direct;
#[cfg(feature = "emulated")]
pub mod emulated;
#[cfg(feature = "serial")]
pub mod serial;
#[cfg(feature = "sim")]
pub mod sim;
#[cfg(feature = "serial")]
pub mod timebase;
#[cfg(feature = "sim")]
pub mod world;

#[cfg(feature = "serial")]
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use ferrobot_protocol::{DeviceInfo, Diagnostics, Fault, HostMsg, JointConfig, Telemetry};

use crate::error::Result;

/// Where the robot's firmware runs.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Backend {
    /// In-process lockstep simulation (cargo feature `sim`, on by default).
    #[cfg(feature = "sim")]
    Sim {
        /// Seed of the plants' noise.
        seed: u64,
        /// Pace simulated time to the wall clock.
        realtime: bool,
    },
    /// A serial port (PTY or USB; cargo feature `serial`).
    #[cfg(feature = "serial")]
    Serial {
        /// Port path, e.g. `/dev/ttyACM0` or `/dev/pts/3`.
        path: PathBuf,
    },
    /// The real firmware for the `mps2-an386` board in QEMU, with the simulated plants behind
    /// pseudo-terminals, over the serial backend: one call. `firmware` is the board's release
    /// ELF (`scripts/build-boards.sh` builds it; cargo feature `emulated`).
    #[cfg(feature = "emulated")]
    Emulated {
        /// Path of the board's ELF, e.g. [`emulated::DEFAULT_FIRMWARE`].
        firmware: PathBuf,
    },
    /// The host-run firmware on a stock robot's own cables (cargo feature `direct`): the
    /// firmware core on this computer, its servo bus and base on the serial devices of the
    /// description's `[direct]` section (a U2D2, the base's cable), after the hardware check
    /// has passed ([`direct::check`]).
    #[cfg(feature = "direct")]
    Direct {
        /// The servo bus's device, if not the description's.
        servo: Option<PathBuf>,
        /// The base's device, if not the description's.
        base: Option<PathBuf>,
        /// The Unix socket of a camera server (a RealSense served by
        /// `host/peers/realsense/serve_realsense.py`), if the robot's camera is to be read.
        camera: Option<PathBuf>,
    },
    /// The host-run firmware on emulated devices: the simulated plants behind
    /// pseudo-terminals at the stock robot's rates, on one clock with the firmware (cargo
    /// feature `emulated`). What `Direct` does on a robot, on none.
    #[cfg(feature = "emulated")]
    DirectEmulated,
}

#[cfg(feature = "sim")]
impl Default for Backend {
    fn default() -> Self {
        Backend::Sim {
            seed: 1,
            realtime: false,
        }
    }
}

/// What the API needs from a backend. Every link drives the one host-side session of the
/// protocol ([`ferrobot_protocol::session::HostSession`]): it only moves bytes and waits.
pub trait Link: Send {
    /// The firmware's self-description from the handshake.
    fn info(&self) -> &DeviceInfo;
    /// Send a command and wait for its acknowledgement; a rejection is an error naming `what`.
    fn command(&mut self, msg: &HostMsg, what: &str) -> Result<()>;
    /// The firmware's configuration of joint `index` (a typed request).
    fn joint_config(&mut self, index: u8) -> Result<JointConfig>;
    /// The firmware's link and bus counters (a typed request).
    fn diagnostics(&mut self) -> Result<Diagnostics>;
    /// The newest telemetry.
    fn telemetry(&mut self) -> Result<Telemetry>;
    /// Every telemetry report received since the last call, oldest first (the session keeps
    /// the newest [`ferrobot_protocol::session::REPORTS`]); by default the newest alone.
    fn take_telemetry(&mut self) -> Vec<Telemetry> {
        self.telemetry().into_iter().collect()
    }
    /// Let `dt` pass (simulated time in the simulator, wall time otherwise).
    fn wait(&mut self, dt: Duration);
    /// The backend's clock.
    fn now(&self) -> Duration;
    /// How long a base velocity command stays valid on the firmware (it is resent every
    /// 100 ms while a velocity goal runs, and the base stops when one is not renewed in time):
    /// 250 ms on a link whose host steps goals beside the firmware. A link over a network
    /// (the remote backend) may say more, its own watchdog standing in for the lost renewal.
    fn command_horizon(&self) -> Duration {
        Duration::from_millis(250)
    }
    /// How far the link's clock is ahead of the wall clock it is paced to (the simulator run
    /// in real time): the caller sleeps this long *after* releasing the robot's lock, so that
    /// other threads reach the link meanwhile; zero for a link whose clock is the wall's or
    /// is not paced.
    fn pace(&mut self) -> Duration {
        Duration::ZERO
    }
    /// Faults received since the last call.
    fn take_faults(&mut self) -> Vec<Fault>;
    /// What happened to the link itself since the last call (lost, back), oldest first;
    /// nothing on a link that cannot be lost (the in-process simulator).
    fn take_events(&mut self) -> Vec<LinkEvent> {
        Vec::new()
    }
    /// The link as [`std::any::Any`], for what only one backend has (the simulator's world:
    /// [`world`]), so that `Link` itself names no backend's types.
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any;
    /// A line that sends the emergency stop without this link's owner, for a firmware whose
    /// clock runs on while another thread holds the link (a camera read, SLAM): `None` where
    /// time only passes while the link is driven (the in-process simulator).
    fn stop_line(&self) -> Option<Arc<dyn StopLine>> {
        None
    }
}

/// What happened to a link that comes and goes (a serial port whose cable is pulled, a
/// firmware that falls silent), in the order it happened ([`crate::Robot::take_link_events`]).
///
/// A reconnection is a new session with the firmware. Motions under way when the link was
/// lost end with [`crate::Error::Link`], and so does every call made while it is down. When
/// the link is back, the robot accepts motions again from where it stands; what the firmware's
/// watchdog did meanwhile is said once, here, and never reaches a later motion as a fault.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum LinkEvent {
    /// The link was lost, for the reason given.
    Lost {
        /// Why: the port's error, or the firmware's silence.
        why: String,
    },
    /// The firmware answered a new handshake, `down_for` (wall time) after the link was lost.
    Reconnected {
        /// How long the link was down, wall time.
        down_for: Duration,
        /// Whether the firmware's host watchdog had stopped the robot meanwhile (the link was
        /// down for longer than its period, 500 ms on the bundled robots): the base stopped
        /// and every joint held where it was. The handshake ended that state; the joints go on
        /// holding until commanded.
        watchdog_stopped: bool,
    },
}

/// Sends the emergency stop at once, beside whatever holds the [`Link`]
/// ([`Link::stop_line`]); its acknowledgement is not waited for.
pub trait StopLine: Send + Sync {
    /// Put the emergency stop on the wire.
    fn emergency_stop(&self) -> Result<()>;
}

/// Map a firmware rejection to the API's error.
pub(crate) fn rejection(what: &str, reason: ferrobot_protocol::RejectReason) -> crate::Error {
    match reason {
        ferrobot_protocol::RejectReason::EmergencyStop => crate::Error::EmergencyStop,
        reason => crate::Error::Rejected {
            what: what.to_string(),
            reason,
        },
    }
}

#[cfg(feature = "serial")]
/// A device description until the handshake brings the real one.
pub(crate) fn placeholder_info() -> DeviceInfo {
    DeviceInfo {
        protocol_version: 0,
        schema_hash: 0,
        firmware_version: [0; 3],
        board: Default::default(),
        robot: Default::default(),
        joints: Default::default(),
        base: ferrobot_protocol::BaseKind::None,
        loop_period_us: 0,
        accepted: false,
        watchdog_tripped: false,
    }
}

#[cfg(feature = "serial")]
/// A command's answer as the API's result.
pub(crate) fn acked(what: &str, answer: ferrobot_protocol::session::Answer) -> Result<()> {
    use ferrobot_protocol::session::Answer;
    match answer {
        Answer::Ack => Ok(()),
        Answer::Rejected(reason) => Err(rejection(what, reason)),
        _ => Err(rejection(
            what,
            ferrobot_protocol::RejectReason::Unsupported,
        )),
    }
}

#[cfg(feature = "serial")]
/// A typed request's answer as its reply.
pub(crate) fn replied<R: ferrobot_protocol::session::Request>(
    what: &str,
    answer: ferrobot_protocol::session::Answer,
) -> Result<R::Reply> {
    match answer {
        ferrobot_protocol::session::Answer::Rejected(reason) => Err(rejection(what, reason)),
        a => R::reply(a).ok_or_else(|| crate::Error::Link(format!("{what}: unexpected answer"))),
    }
}
