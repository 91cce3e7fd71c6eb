//! # ferrobot-protocol
//!
//! Everything that crosses a wire in Ferrobot, for both ends of the wire:
//!
//! * [`messages`]: the host ⇄ firmware message set ([`HostMsg`], [`DeviceMsg`]), SI units, `f32`.
//! * [`frame`]: framing of those messages: a postcard body, a CRC-32C, COBS and a `0x00`
//!   delimiter. The frame adds **exactly 6 bytes** to the postcard body (4 CRC, 1 COBS code
//!   byte, 1 delimiter) for every body up to [`MAX_BODY`] bytes; the sequence number and the
//!   message kind travel inside the body. No frame on the wire is longer than [`MAX_WIRE`].
//! * [`ranges`]: the physical range of every number on the wire, the checks both ends apply,
//!   and the safety policy of the protocol (emergency stop, watchdog, refused handshakes).
//! * [`kobuki`] and [`create2`]: the wire formats of the two mobile bases (Kobuki serial
//!   protocol, iRobot Create 2 Open Interface), shared by the firmware's drivers and the
//!   simulated bases.
//! * [`gravity`]: gravity torques on a serial arm from a compact link table (the firmware's
//!   gravity feed-forward, the simulated arm's load).
//! * [`clock`]: the virtual-time link between an emulated board and its simulated plants.
//! * [`dxl`]: a Dynamixel Protocol 2.0 codec (instruction and status packets, byte stuffing,
//!   CRC-16/UMTS), plus the X-series control-table facts both the firmware and the simulated
//!   servos need.
//!
//! The crate is `no_std` and never allocates; no decoder panics on any input (property tests
//! and cargo-fuzz targets exercise that).
#![no_std]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects
    )
)]
#![warn(missing_docs)]

pub mod clock;
pub mod create2;
pub mod dxl;
pub mod frame;
/// Plane geometry (the angle wrap and the exact-arc step): the crate `ferrobot-planar`.
pub use ferrobot_planar as geometry;
pub mod gravity;
pub mod kobuki;
pub mod messages;
pub mod ranges;
pub mod session;

pub use frame::{encode_frame, Frame, FrameDecoder, FrameError, FrameStats};
pub use messages::*;

/// Version of the host ⇄ firmware protocol. Bumped on every incompatible change.
pub const PROTOCOL_VERSION: u16 = 3;

/// Largest postcard body (sequence number plus message) a frame may carry, in bytes.
///
/// Chosen so that body + CRC stays below 254 bytes, where COBS adds exactly one byte.
pub const MAX_BODY: usize = 247;

/// Bytes the framing adds to a postcard body: CRC-32C (4), COBS code byte (1), delimiter (1).
pub const FRAME_OVERHEAD: usize = 6;

/// Largest frame on the wire, delimiter included, in bytes.
pub const MAX_WIRE: usize = MAX_BODY + FRAME_OVERHEAD;

/// Most joints (servo-driven degrees of freedom, gripper and pan-tilt included) a robot has.
pub const MAX_JOINTS: usize = 12;

/// A hash of the structure of the messages both ways ([`HostMsg`] and [`DeviceMsg`], every
/// type they contain, with names, fields, variants and their order), from their
/// [`postcard_schema::Schema`]: any change of a type changes it, a change of a comment does not.
/// Exchanged in the handshake, so a host and a firmware built from different message sets
/// refuse each other even when someone forgot to bump [`PROTOCOL_VERSION`] (which marks changes
/// of meaning that leave the types as they are).
pub const SCHEMA_HASH: u32 = {
    let k = postcard_schema::key::Key::for_path::<(HostMsg, DeviceMsg)>("ferrobot").to_bytes();
    u32::from_le_bytes([k[0] ^ k[4], k[1] ^ k[5], k[2] ^ k[6], k[3] ^ k[7]])
};
