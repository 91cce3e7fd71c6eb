//! Logging of notable events (handshakes, rejected commands, faults) through defmt when the
//! board enables the crate's `defmt` feature; without it the macros compile to nothing.
//!
//! Names go out as interned strings (`{=istr}`), which cost an index on the wire and nothing
//! in flash.

#[cfg(feature = "defmt")]
macro_rules! log_info {
    ($s:literal $(, $x:expr)* $(,)?) => { ::defmt::info!($s $(, $x)*) };
}
#[cfg(not(feature = "defmt"))]
macro_rules! log_info {
    ($s:literal $(, $x:expr)* $(,)?) => {{ $( let _ = &$x; )* }};
}

#[cfg(feature = "defmt")]
macro_rules! log_warn {
    ($s:literal $(, $x:expr)* $(,)?) => { ::defmt::warn!($s $(, $x)*) };
}
#[cfg(not(feature = "defmt"))]
macro_rules! log_warn {
    ($s:literal $(, $x:expr)* $(,)?) => {{ $( let _ = &$x; )* }};
}

pub(crate) use {log_info, log_warn};

/// A fault kind's name, for the log.
#[cfg(feature = "defmt")]
pub(crate) fn fault_name(kind: ferrobot_protocol::FaultKind) -> defmt::Str {
    use ferrobot_protocol::FaultKind as K;
    match kind {
        K::ServoLost => defmt::intern!("ServoLost"),
        K::ServoRecovered => defmt::intern!("ServoRecovered"),
        K::ServoHardware => defmt::intern!("ServoHardware"),
        K::ServoConfig => defmt::intern!("ServoConfig"),
        K::Watchdog => defmt::intern!("Watchdog"),
        K::EmergencyStop => defmt::intern!("EmergencyStop"),
        K::Bumper => defmt::intern!("Bumper"),
        K::Cliff => defmt::intern!("Cliff"),
        K::WheelDrop => defmt::intern!("WheelDrop"),
        K::BaseLost => defmt::intern!("BaseLost"),
        K::BaseRecovered => defmt::intern!("BaseRecovered"),
        K::LimitClamped => defmt::intern!("LimitClamped"),
        K::UnsafeGoal => defmt::intern!("UnsafeGoal"),
        K::LimitStop => defmt::intern!("LimitStop"),
        K::OutsideLimits => defmt::intern!("OutsideLimits"),
        _ => defmt::intern!("(another fault)"),
    }
}

/// Without defmt there is nothing to name.
#[cfg(not(feature = "defmt"))]
pub(crate) fn fault_name(_kind: ferrobot_protocol::FaultKind) {}

/// A rejection's name, for the log.
#[cfg(feature = "defmt")]
pub(crate) fn reject_name(reason: ferrobot_protocol::RejectReason) -> defmt::Str {
    use ferrobot_protocol::RejectReason as R;
    match reason {
        R::VersionMismatch => defmt::intern!("VersionMismatch"),
        R::UnknownJoint => defmt::intern!("UnknownJoint"),
        R::CountMismatch => defmt::intern!("CountMismatch"),
        R::NotFinite => defmt::intern!("NotFinite"),
        R::OutOfLimits => defmt::intern!("OutOfLimits"),
        R::QueueFull => defmt::intern!("QueueFull"),
        R::EmergencyStop => defmt::intern!("EmergencyStop"),
        R::WrongMode => defmt::intern!("WrongMode"),
        R::Unsupported => defmt::intern!("Unsupported"),
        R::NoBase => defmt::intern!("NoBase"),
        R::NoGripper => defmt::intern!("NoGripper"),
        R::Busy => defmt::intern!("Busy"),
        R::InvalidConfig => defmt::intern!("InvalidConfig"),
        R::BaseSafety => defmt::intern!("BaseSafety"),
        _ => defmt::intern!("(another reason)"),
    }
}

/// Without defmt there is nothing to name.
#[cfg(not(feature = "defmt"))]
pub(crate) fn reject_name(_reason: ferrobot_protocol::RejectReason) {}
