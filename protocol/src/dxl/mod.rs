//! Dynamixel Protocol 2.0: packets, byte stuffing, CRC, and the X-series facts both ends need.
//!
//! Instruction packet: `FF FF FD 00 | ID | LEN_L LEN_H | INST | PARAM… | CRC_L CRC_H`; a status
//! packet has `INST = 0x55` and an error byte before its parameters. `LEN` counts the
//! instruction, the (stuffed) parameters and the CRC. Inside the body (instruction to last
//! parameter) every `FF FF FD` is followed by a stuffed `FD`, removed again on receipt. The CRC
//! is CRC-16/UMTS (polynomial 0x8005, init 0, no reflection) over everything before it, as
//! stuffed. See the ROBOTIS e-manual, "DYNAMIXEL Protocol 2.0"; the unit tests check the
//! e-manual's example packets byte for byte.

use crc::{Crc, CRC_16_UMTS};

mod codes;
mod decoder;
mod servo;
mod writer;

pub use codes::{addr, baud_code, hw_error, inst, mode, status_error, BAUD_RATES};
pub use decoder::{Packet, PacketDecoder, PacketStats};
pub use servo::{units, MotorSpec};
pub use writer::{
    bulk_read, bulk_write, ping, read, reboot, status, sync_read, sync_write, write, PacketWriter,
};

const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_UMTS);

/// The fixed packet header.
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];
/// Broadcast ID: every servo obeys; only instructions that say so get answers.
pub const BROADCAST_ID: u8 = 0xFE;
/// Bytes of a packet besides its instruction and parameters: header 4, ID 1, LEN 2, CRC 2.
pub const PACKET_OVERHEAD: usize = 9;

/// Codec errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum DxlError {
    /// The output buffer is too small.
    BufferTooSmall,
    /// The packet is longer than the decoder's buffer.
    TooLong,
    /// `LEN` is smaller than instruction plus CRC.
    BadLength,
    /// CRC mismatch.
    Crc,
    /// A parameter list that does not fit the instruction.
    BadParams,
}

/// CRC-16/UMTS as the Dynamixel protocol uses it.
pub fn crc16(bytes: &[u8]) -> u16 {
    CRC16.checksum(bytes)
}

/// Little-endian `u16` at `at`, or 0 when out of range.
pub fn le_u16(bytes: &[u8], at: usize) -> u16 {
    match bytes.get(at..at.saturating_add(2)) {
        Some(&[a, b]) => u16::from_le_bytes([a, b]),
        _ => 0,
    }
}

/// Little-endian `u32` at `at`, or 0 when out of range.
pub fn le_u32(bytes: &[u8], at: usize) -> u32 {
    match bytes.get(at..at.saturating_add(4)) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode_one(bytes: &[u8]) -> Option<(u8, u8, heapless::Vec<u8, 64>)> {
        let mut d = PacketDecoder::<128>::new();
        let mut out = None;
        for &b in bytes {
            if let Some(Ok(p)) = d.push(b) {
                out = Some((
                    p.id,
                    p.instruction,
                    heapless::Vec::from_slice(p.params).ok()?,
                ));
            }
        }
        out
    }

    // Example packets from the ROBOTIS e-manual, "DYNAMIXEL Protocol 2.0".
    #[test]
    fn emanual_ping() {
        let mut b = [0u8; 32];
        let n = ping(&mut b, 1).unwrap_or(0);
        assert_eq!(
            &b[..n],
            &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E]
        );
        // The e-manual's example reply: model number 0x0406, firmware version 0x26.
        let n = status(&mut b, 1, 0, &[0x06, 0x04, 0x26]).unwrap_or(0);
        assert_eq!(
            &b[..n],
            &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D]
        );
    }

    #[test]
    fn emanual_read_and_status() {
        let mut b = [0u8; 32];
        let n = read(&mut b, 1, 132, 4).unwrap_or(0);
        assert_eq!(
            &b[..n],
            &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15]
        );
        let n = status(&mut b, 1, 0, &[0xA6, 0x00, 0x00, 0x00]).unwrap_or(0);
        assert_eq!(
            &b[..n],
            &[
                0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x55, 0x00, 0xA6, 0x00, 0x00, 0x00, 0x8C,
                0xC0
            ]
        );
    }

    #[test]
    fn emanual_write() {
        let mut b = [0u8; 32];
        let n = write(&mut b, 1, 116, &512u32.to_le_bytes()).unwrap_or(0);
        assert_eq!(
            &b[..n],
            &[
                0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x03, 0x74, 0x00, 0x00, 0x02, 0x00, 0x00,
                0xCA, 0x89
            ]
        );
    }

    #[test]
    fn emanual_sync_read_and_write() {
        let mut b = [0u8; 64];
        let n = sync_read(&mut b, 132, 4, &[1, 2]).unwrap_or(0);
        assert_eq!(
            &b[..n],
            &[
                0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x09, 0x00, 0x82, 0x84, 0x00, 0x04, 0x00, 0x01, 0x02,
                0xCE, 0xFA
            ]
        );
        let a = 150u32.to_le_bytes();
        let c = 170u32.to_le_bytes();
        let n = sync_write(&mut b, 116, 4, [(1u8, &a[..]), (2u8, &c[..])]).unwrap_or(0);
        assert_eq!(
            &b[..n],
            &[
                0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x11, 0x00, 0x83, 0x74, 0x00, 0x04, 0x00, 0x01, 0x96,
                0x00, 0x00, 0x00, 0x02, 0xAA, 0x00, 0x00, 0x00, 0x82, 0x87
            ]
        );
    }

    #[test]
    fn emanual_bulk_read() {
        let mut b = [0u8; 64];
        let n = bulk_read(&mut b, &[(1, 144, 2), (2, 146, 1)]).unwrap_or(0);
        assert_eq!(
            &b[..n],
            &[
                0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x0D, 0x00, 0x92, 0x01, 0x90, 0x00, 0x02, 0x00, 0x02,
                0x92, 0x00, 0x01, 0x00, 0x1A, 0x05
            ]
        );
    }

    #[test]
    fn stuffing_round_trip() {
        let mut b = [0u8; 64];
        let data = [0xFF, 0xFF, 0xFD, 0x01, 0xFF, 0xFF, 0xFD, 0xFD];
        let n = write(&mut b, 3, 0x10, &data).unwrap_or(0);
        // Two stuffed FDs: LEN = inst 1 + addr 2 + data 8 + stuffing 2 + crc 2.
        assert_eq!(le_u16(&b, 5), 15);
        assert_eq!(n, 7 + 15);
        let (id, ins, params) = decode_one(&b[..n]).unwrap_or_default();
        assert_eq!((id, ins), (3, inst::WRITE));
        assert_eq!(&params[2..], &data[..]);
    }

    #[test]
    fn push_slice_agrees_with_push() {
        let mut stream: heapless::Vec<u8, 256> = heapless::Vec::new();
        let mut b = [0u8; 64];
        let _ = stream.extend_from_slice(&[0x00, 0xFF, 0x13]);
        for (id, data) in [
            (1u8, &[1u8, 2, 3][..]),
            (2, &[0xFF, 0xFF, 0xFD, 0x07]),
            (3, &[]),
        ] {
            let n = status(&mut b, id, 0, data).unwrap_or(0);
            let _ = stream.extend_from_slice(&b[..n]);
        }
        let mut a = PacketDecoder::<128>::new();
        let mut by_byte: heapless::Vec<(u8, heapless::Vec<u8, 16>), 8> = heapless::Vec::new();
        for &x in &stream {
            if let Some(Ok(p)) = a.push(x) {
                let _ = by_byte.push((
                    p.id,
                    heapless::Vec::from_slice(p.params).unwrap_or_default(),
                ));
            }
        }
        let mut c = PacketDecoder::<128>::new();
        let mut by_slice: heapless::Vec<(u8, heapless::Vec<u8, 16>), 8> = heapless::Vec::new();
        let mut rest = &stream[..];
        while !rest.is_empty() {
            let (n, r) = c.push_slice(rest);
            if let Some(Ok(p)) = r {
                let _ = by_slice.push((
                    p.id,
                    heapless::Vec::from_slice(p.params).unwrap_or_default(),
                ));
            }
            rest = &rest[n..];
        }
        assert_eq!(by_byte.len(), 3);
        assert_eq!(by_byte, by_slice);
    }

    #[test]
    fn decoder_resyncs_after_garbage() {
        let mut b = [0u8; 32];
        let n = ping(&mut b, 7).unwrap_or(0);
        let mut stream: heapless::Vec<u8, 64> = heapless::Vec::new();
        let _ = stream.extend_from_slice(&[0xFF, 0xFF, 0xFF, 0xFD, 0x01, 0xFF, 0x00, 0x12]);
        let _ = stream.extend_from_slice(&b[..n]);
        let (id, ins, _) = decode_one(&stream).unwrap_or_default();
        assert_eq!((id, ins), (7, inst::PING));
    }
}
