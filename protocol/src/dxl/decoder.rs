//! Decoding packets from a byte stream: headers are found anywhere, length and CRC are
//! checked, parameters destuffed; bad packets are dropped and counted, and the decoder
//! resynchronises at the next header. Never panics, never allocates.

use super::codes::inst;
use super::{crc16, DxlError};

/// A decoded packet, borrowing the decoder's buffer; parameters are destuffed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Packet<'a> {
    /// Servo ID (sender of a status, addressee of an instruction).
    pub id: u8,
    /// Instruction code ([`inst::STATUS`] for status packets).
    pub instruction: u8,
    /// Parameters; for a status packet the first is the error byte.
    pub params: &'a [u8],
}

impl<'a> Packet<'a> {
    /// Whether this is a status packet.
    pub fn is_status(&self) -> bool {
        self.instruction == inst::STATUS
    }
    /// The error byte of a status packet.
    pub fn error(&self) -> u8 {
        self.params.first().copied().unwrap_or(0)
    }
    /// The data of a status packet (after the error byte).
    pub fn data(&self) -> &'a [u8] {
        self.params.get(1..).unwrap_or(&[])
    }
}

/// Counters of a [`PacketDecoder`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PacketStats {
    /// Packets decoded.
    pub ok: u32,
    /// Packets with a CRC mismatch.
    pub crc: u32,
    /// Packets too long for the buffer or with an impossible length.
    pub length: u32,
}

/// Streaming packet decoder with an `N`-byte buffer. Finds headers anywhere in the stream, checks
/// length and CRC, destuffs parameters. Never panics, never allocates.
pub struct PacketDecoder<const N: usize> {
    buf: [u8; N],
    len: usize,
    total: usize,
    stats: PacketStats,
}

impl<const N: usize> Default for PacketDecoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// What one byte did to the decoder.
enum Step {
    More,
    Complete,
    Bad(DxlError),
}

impl<const N: usize> PacketDecoder<N> {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            total: 0,
            stats: PacketStats {
                ok: 0,
                crc: 0,
                length: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> PacketStats {
        self.stats
    }

    /// Forget any partial packet.
    pub fn reset(&mut self) {
        self.len = 0;
    }

    /// Whether a packet is partly received.
    pub fn in_packet(&self) -> bool {
        self.len > 0
    }

    fn set(&mut self, i: usize, b: u8) {
        if let Some(s) = self.buf.get_mut(i) {
            *s = b;
        }
    }

    fn restart_with(&mut self, b: u8) {
        self.len = 0;
        if b == 0xFF {
            self.set(0, b);
            self.len = 1;
        }
    }

    /// The header and length state machine, one byte.
    fn step(&mut self, b: u8) -> Step {
        match self.len {
            0 | 1 => {
                if b == 0xFF {
                    self.set(self.len, b);
                    self.len = self.len.saturating_add(1);
                } else {
                    self.len = 0;
                }
                return Step::More;
            }
            2 => {
                match b {
                    0xFD => {
                        self.set(2, b);
                        self.len = 3;
                    }
                    0xFF => {} // FF FF FF: still two FFs in hand
                    _ => self.len = 0,
                }
                return Step::More;
            }
            3 => {
                if b == 0x00 {
                    self.set(3, b);
                    self.len = 4;
                } else {
                    self.restart_with(b);
                }
                return Step::More;
            }
            _ => {}
        }
        if self.len >= N {
            self.len = 0;
            self.stats.length = self.stats.length.saturating_add(1);
            return Step::Bad(DxlError::TooLong);
        }
        self.set(self.len, b);
        self.len = self.len.saturating_add(1);
        if self.len == 7 {
            let declared = u16::from_le_bytes([
                self.buf.get(5).copied().unwrap_or(0),
                self.buf.get(6).copied().unwrap_or(0),
            ]) as usize;
            if declared < 3 {
                self.restart_with(b);
                self.stats.length = self.stats.length.saturating_add(1);
                return Step::Bad(DxlError::BadLength);
            }
            self.total = declared.saturating_add(7);
            if self.total > N {
                self.len = 0;
                self.stats.length = self.stats.length.saturating_add(1);
                return Step::Bad(DxlError::TooLong);
            }
        }
        if self.len >= 7 && self.len == self.total {
            Step::Complete
        } else {
            Step::More
        }
    }

    /// Check the CRC of the complete packet in the buffer and destuff its body.
    fn finish(&mut self) -> Result<Packet<'_>, DxlError> {
        let total = self.total;
        self.len = 0;
        let body_end = total.saturating_sub(2);
        let crc_ok = match (self.buf.get(..body_end), self.buf.get(body_end..total)) {
            (Some(body), Some(c)) => {
                crc16(body)
                    == u16::from_le_bytes([
                        c.first().copied().unwrap_or(0),
                        c.get(1).copied().unwrap_or(0),
                    ])
            }
            _ => false,
        };
        if !crc_ok {
            self.stats.crc = self.stats.crc.saturating_add(1);
            return Err(DxlError::Crc);
        }
        // Destuff the body (instruction and parameters) in place; most bodies hold no 0xFD.
        let mut w = body_end;
        if self.buf.get(7..body_end).is_some_and(|b| b.contains(&0xFD)) {
            w = 7;
            let mut r = 7usize;
            let mut tail = [0u8; 3];
            while r < body_end {
                let c = self.buf.get(r).copied().unwrap_or(0);
                r = r.saturating_add(1);
                if tail == [0xFF, 0xFF, 0xFD] && c == 0xFD {
                    tail = [0; 3];
                    continue;
                }
                self.set(w, c);
                w = w.saturating_add(1);
                tail = [tail[1], tail[2], c];
            }
        }
        self.stats.ok = self.stats.ok.saturating_add(1);
        let id = self.buf.get(4).copied().unwrap_or(0);
        let instruction = self.buf.get(7).copied().unwrap_or(0);
        let params = self.buf.get(8..w).unwrap_or(&[]);
        Ok(Packet {
            id,
            instruction,
            params,
        })
    }

    /// Push one byte; returns a packet when it completes one, or an error when a packet that
    /// had a complete header turned out bad.
    pub fn push(&mut self, b: u8) -> Option<Result<Packet<'_>, DxlError>> {
        match self.step(b) {
            Step::More => None,
            Step::Bad(e) => Some(Err(e)),
            Step::Complete => Some(self.finish()),
        }
    }

    /// Push bytes until a packet completes or a bad one is dropped; returns how many bytes were
    /// consumed and that outcome (call again with the rest). Once a packet's length is known
    /// its body is copied in one go, much cheaper than [`PacketDecoder::push`] byte by byte.
    pub fn push_slice(&mut self, bytes: &[u8]) -> (usize, Option<Result<Packet<'_>, DxlError>>) {
        let mut i = 0;
        while i < bytes.len() {
            if self.len >= 7 && self.total > self.len {
                let want = self
                    .total
                    .saturating_sub(self.len)
                    .min(bytes.len().saturating_sub(i));
                if let (Some(dst), Some(src)) = (
                    self.buf.get_mut(self.len..self.len.saturating_add(want)),
                    bytes.get(i..i.saturating_add(want)),
                ) {
                    dst.copy_from_slice(src);
                }
                self.len = self.len.saturating_add(want);
                i = i.saturating_add(want);
                if self.len == self.total {
                    return (i, Some(self.finish()));
                }
                continue;
            }
            let b = bytes.get(i).copied().unwrap_or(0);
            i = i.saturating_add(1);
            match self.step(b) {
                Step::More => {}
                Step::Bad(e) => return (i, Some(Err(e))),
                Step::Complete => return (i, Some(self.finish())),
            }
        }
        (i, None)
    }
}
