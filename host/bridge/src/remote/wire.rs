//! The remote backend's wire: a served robot's firmware link, forwarded over zenoh. A client's
//! [`Call`]s go to the server's queryable and are answered with a [`Reply`]; the firmware's
//! telemetry and faults are published as they arrive; each client puts a heartbeat every
//! [`HEARTBEAT`]. All in the wire protocol's own encoding, postcard. The camera's frames go on
//! the robot's ROS 2 topics, decoded by the client.
//!
//! A robot served in lockstep ([`RemoteInfo::lockstep`]: a simulator whose time passes only
//! while someone waits) has its time passed by its clients' [`Call::Advance`], as the
//! in-process simulator's is by its program's waits: virtual time, the same on a busy machine
//! as on a quiet one. Its server says it is there on `alive` every [`HEARTBEAT`], telemetry
//! flowing only while time passes.
//!
//! Keys, under the robot's prefix ([`prefix`]: `ferrobot` and its namespace):
//!
//! | key | what |
//! |---|---|
//! | `<prefix>/remote/call` | queryable: a [`Request`] in, a [`Reply`] out |
//! | `<prefix>/remote/telemetry` | each [`ferrobot::Telemetry`] report |
//! | `<prefix>/remote/fault` | each [`ferrobot::Fault`] |
//! | `<prefix>/remote/heartbeat` | each client's id, every [`HEARTBEAT`] |
//! | `<prefix>/remote/alive` | the server's robot clock (µs), every [`HEARTBEAT`] |

use std::time::Duration;

use ferrobot::Diagnostics;
use ferrobot_protocol::{DeviceInfo, HostMsg, JointConfig, RejectReason};
use serde::{Deserialize, Serialize};

/// How often a client says it is there.
pub const HEARTBEAT: Duration = Duration::from_millis(100);
/// How long a client that has commanded the robot may be silent before the server stops the
/// robot (the joints hold, the base stops), as the firmware's watchdog does for its host.
pub const WATCHDOG: Duration = Duration::from_millis(500);
/// How long a call waits for its reply.
pub const CALL_TIMEOUT: Duration = Duration::from_secs(2);
/// The most one [`Call::Advance`] lets pass, µs: a longer wait is several calls, so that no
/// call holds the served robot longer than about this much simulated time.
pub const MAX_ADVANCE_US: u64 = 1_000_000;

/// The key prefix of the robot served in `namespace` (`/` for none).
pub fn prefix(namespace: &str) -> String {
    match namespace.trim_matches('/') {
        "" => "ferrobot".into(),
        ns => format!("ferrobot/{ns}"),
    }
}

/// The call queryable's key.
pub fn call_key(prefix: &str) -> String {
    format!("{prefix}/remote/call")
}

/// The telemetry's key.
pub fn telemetry_key(prefix: &str) -> String {
    format!("{prefix}/remote/telemetry")
}

/// The faults' key.
pub fn fault_key(prefix: &str) -> String {
    format!("{prefix}/remote/fault")
}

/// The heartbeats' key.
pub fn heartbeat_key(prefix: &str) -> String {
    format!("{prefix}/remote/heartbeat")
}

/// The server's liveness key.
pub fn alive_key(prefix: &str) -> String {
    format!("{prefix}/remote/alive")
}

/// What a client asks of the served robot's link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Call {
    /// The served robot: [`Answer::Info`].
    Info,
    /// Send a message to the firmware and wait for its acknowledgement: [`Answer::Done`].
    Command(HostMsg),
    /// The firmware's configuration of joint `index`: [`Answer::Joint`].
    JointConfig(u8),
    /// The firmware's counters: [`Answer::Diagnostics`].
    Diagnostics,
    /// Let the served robot's time pass until its clock reads `until_us` µs (at most
    /// [`MAX_ADVANCE_US`] from where it stands; nothing if it is there already):
    /// [`Answer::Advanced`]. Only a robot served in lockstep accepts it.
    Advance {
        /// The clock to reach, µs.
        until_us: u64,
    },
    /// The client leaves: the server forgets it, and its silence from now on stops nothing
    /// ([`Answer::Done`]).
    Bye,
}

/// A call, with the id of the client making it (random, per connection).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Request {
    /// The client.
    pub client: u64,
    /// The call.
    pub call: Call,
}

/// The served robot, as a client needs to know it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RemoteInfo {
    /// The description's name (`locobot`, `sawyer`, …).
    pub robot: String,
    /// The firmware's self-description from its handshake.
    pub device: DeviceInfo,
    /// The camera, when the robot serves one.
    pub camera: Option<RemoteCamera>,
    /// The ROS domain the robot's topics are on.
    pub domain: u32,
    /// The robot's time passes only through its clients' [`Call::Advance`] (a simulator served
    /// in lockstep); otherwise it runs by itself (paced to the wall clock, or a real robot).
    pub lockstep: bool,
    /// The robot shares its simulated world, and its clock, with other robots
    /// ([`ferrobot::SharedWorld`]): their clients pass its time too, so a lockstep client
    /// asks where the clock stands before it waits.
    pub shared: bool,
}

/// The served camera: its intrinsics and rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RemoteCamera {
    /// Image width and height, px.
    pub size: [u32; 2],
    /// Focal lengths fx, fy and principal point cx, cy, px.
    pub pinhole: [f64; 4],
    /// Frames per second.
    pub rate: f64,
}

/// A call's answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Answer {
    /// The served robot.
    Info(RemoteInfo),
    /// Acknowledged, when the served robot's clock (the firmware's) read `time_us` µs.
    Done {
        /// The served robot's clock after the acknowledgement, µs.
        time_us: u64,
    },
    /// A joint's configuration.
    Joint(JointConfig),
    /// The counters.
    Diagnostics(Diagnostics),
    /// Time has passed: the served robot's clock, and the time of its newest telemetry report
    /// (published before or soon after this answer), µs.
    Advanced {
        /// The served robot's clock, µs.
        time_us: u64,
        /// Its newest telemetry report's time, µs.
        telemetry_us: u64,
    },
}

/// Why a call was refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Refusal {
    /// The emergency stop is active.
    EmergencyStop,
    /// The firmware rejected the message.
    Rejected(RejectReason),
    /// The served robot's own link to its firmware is down.
    Link(String),
    /// The request did not decode, or another error; its words.
    Other(String),
}

/// A call's reply.
pub type Reply = Result<Answer, Refusal>;

impl Refusal {
    /// The server's error `e` for the wire.
    pub fn of(e: &ferrobot::Error) -> Refusal {
        match e {
            ferrobot::Error::EmergencyStop => Refusal::EmergencyStop,
            ferrobot::Error::Rejected { reason, .. } => Refusal::Rejected(*reason),
            ferrobot::Error::Link(why) => Refusal::Link(why.clone()),
            e => Refusal::Other(e.to_string()),
        }
    }

    /// The API's error for a refusal of `what`.
    pub fn to_error(&self, what: &str) -> ferrobot::Error {
        match self {
            Refusal::EmergencyStop => ferrobot::Error::EmergencyStop,
            Refusal::Rejected(reason) => ferrobot::Error::Rejected {
                what: what.to_string(),
                reason: *reason,
            },
            Refusal::Link(why) => ferrobot::Error::Link(format!("the served robot's link: {why}")),
            Refusal::Other(why) => ferrobot::Error::Link(format!("the served robot: {why}")),
        }
    }
}

/// `v` in postcard.
pub fn encode<T: Serialize>(v: &T) -> Vec<u8> {
    postcard::to_allocvec(v).unwrap_or_default()
}

/// A `T` from postcard bytes.
pub fn decode<'a, T: Deserialize<'a>>(b: &'a [u8]) -> Result<T, postcard::Error> {
    postcard::from_bytes(b)
}
