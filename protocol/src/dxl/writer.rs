//! Building packets: a writer that stuffs the body as it goes and closes the packet with its
//! length and CRC, and one builder per instruction (and the status a servo sends), each
//! writing into a caller's buffer and returning the packet's length in bytes.

use super::codes::inst;
use super::{crc16, DxlError, BROADCAST_ID, HEADER};

/// Builds one packet in a caller's buffer, stuffing the body as it goes.
pub struct PacketWriter<'a> {
    buf: &'a mut [u8],
    w: usize,
    tail: [u8; 3],
    overflow: bool,
}

impl<'a> PacketWriter<'a> {
    /// Start a packet for servo `id` with `instruction`.
    pub fn new(buf: &'a mut [u8], id: u8, instruction: u8) -> Self {
        let mut p = Self {
            buf,
            w: 0,
            tail: [0; 3],
            overflow: false,
        };
        for b in HEADER {
            p.raw(b);
        }
        p.raw(id);
        p.raw(0);
        p.raw(0);
        p.push(instruction);
        p
    }

    fn raw(&mut self, b: u8) {
        match self.buf.get_mut(self.w) {
            Some(slot) => {
                *slot = b;
                self.w = self.w.saturating_add(1);
            }
            None => self.overflow = true,
        }
    }

    /// Append one body byte (stuffed when it completes `FF FF FD`).
    pub fn push(&mut self, b: u8) {
        self.raw(b);
        self.tail = [self.tail[1], self.tail[2], b];
        if self.tail == [0xFF, 0xFF, 0xFD] {
            self.raw(0xFD);
            self.tail = [0; 3];
        }
    }

    /// Append body bytes.
    pub fn extend(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.push(b);
        }
    }

    /// Append a little-endian u16.
    pub fn u16(&mut self, v: u16) {
        self.extend(&v.to_le_bytes());
    }

    /// Write length and CRC; returns the packet length in bytes.
    pub fn finish(mut self) -> Result<usize, DxlError> {
        let len = self.w.saturating_sub(7).saturating_add(2);
        let len = u16::try_from(len).map_err(|_| DxlError::TooLong)?;
        if let Some(l) = self.buf.get_mut(5..7) {
            l.copy_from_slice(&len.to_le_bytes());
        }
        let crc = crc16(self.buf.get(..self.w).unwrap_or(&[]));
        self.raw(crc as u8);
        self.raw((crc >> 8) as u8);
        if self.overflow {
            return Err(DxlError::BufferTooSmall);
        }
        Ok(self.w)
    }
}

/// Ping `id`.
pub fn ping(out: &mut [u8], id: u8) -> Result<usize, DxlError> {
    PacketWriter::new(out, id, inst::PING).finish()
}

/// Read `len` bytes at `address` of servo `id`.
pub fn read(out: &mut [u8], id: u8, address: u16, len: u16) -> Result<usize, DxlError> {
    let mut p = PacketWriter::new(out, id, inst::READ);
    p.u16(address);
    p.u16(len);
    p.finish()
}

/// Write `data` at `address` of servo `id`.
pub fn write(out: &mut [u8], id: u8, address: u16, data: &[u8]) -> Result<usize, DxlError> {
    let mut p = PacketWriter::new(out, id, inst::WRITE);
    p.u16(address);
    p.extend(data);
    p.finish()
}

/// Reboot servo `id`.
pub fn reboot(out: &mut [u8], id: u8) -> Result<usize, DxlError> {
    PacketWriter::new(out, id, inst::REBOOT).finish()
}

/// Sync read of `len` bytes at `address` from each of `ids`, answered in that order.
pub fn sync_read(out: &mut [u8], address: u16, len: u16, ids: &[u8]) -> Result<usize, DxlError> {
    let mut p = PacketWriter::new(out, BROADCAST_ID, inst::SYNC_READ);
    p.u16(address);
    p.u16(len);
    p.extend(ids);
    p.finish()
}

/// Sync write of `len` bytes at `address`: one `(id, data)` per servo, `data.len() == len`.
pub fn sync_write<'d>(
    out: &mut [u8],
    address: u16,
    len: u16,
    entries: impl IntoIterator<Item = (u8, &'d [u8])>,
) -> Result<usize, DxlError> {
    let mut p = PacketWriter::new(out, BROADCAST_ID, inst::SYNC_WRITE);
    p.u16(address);
    p.u16(len);
    for (id, data) in entries {
        if data.len() != len as usize {
            return Err(DxlError::BadParams);
        }
        p.push(id);
        p.extend(data);
    }
    p.finish()
}

/// Bulk read: `(id, address, len)` per servo, answered in that order.
pub fn bulk_read(out: &mut [u8], entries: &[(u8, u16, u16)]) -> Result<usize, DxlError> {
    let mut p = PacketWriter::new(out, BROADCAST_ID, inst::BULK_READ);
    for &(id, address, len) in entries {
        p.push(id);
        p.u16(address);
        p.u16(len);
    }
    p.finish()
}

/// Bulk write: `(id, address, data)` per servo.
pub fn bulk_write(out: &mut [u8], entries: &[(u8, u16, &[u8])]) -> Result<usize, DxlError> {
    let mut p = PacketWriter::new(out, BROADCAST_ID, inst::BULK_WRITE);
    for &(id, address, data) in entries {
        p.push(id);
        p.u16(address);
        p.u16(u16::try_from(data.len()).map_err(|_| DxlError::BadParams)?);
        p.extend(data);
    }
    p.finish()
}

/// A status packet from servo `id` with error byte `error` and `params`.
pub fn status(out: &mut [u8], id: u8, error: u8, params: &[u8]) -> Result<usize, DxlError> {
    let mut p = PacketWriter::new(out, id, inst::STATUS);
    p.push(error);
    p.extend(params);
    p.finish()
}
