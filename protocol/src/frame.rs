//! Framing of host ⇄ firmware messages.
//!
//! On the wire a frame is `COBS(body ‖ CRC-32C(body)) ‖ 0x00`, where `body` is the postcard
//! encoding of [`Frame`] (a sequence number and the message; the message's enum tag is its
//! kind). For bodies of at most [`MAX_BODY`] bytes the framing adds exactly
//! [`FRAME_OVERHEAD`](crate::FRAME_OVERHEAD) = 6 bytes: 4 CRC, 1 COBS code byte, 1 delimiter.

use crc::{Crc, CRC_32_ISCSI};
use serde::{de::DeserializeOwned, Deserialize, Serialize};

use crate::{MAX_BODY, MAX_WIRE};

const CRC32C: Crc<u32> = Crc::<u32>::new(&CRC_32_ISCSI);

/// A framed message: sequence number and message.
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq)]
pub struct Frame<M> {
    /// Sender's sequence number, incremented per frame, wrapping.
    pub seq: u16,
    /// The message.
    pub msg: M,
}

/// Why a frame could not be encoded or was dropped by the decoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FrameError {
    /// The message does not fit in [`MAX_BODY`] bytes (encoder), or the frame on the wire
    /// exceeds [`MAX_WIRE`] bytes (decoder).
    TooLong,
    /// The output buffer is too small (encoder).
    BufferTooSmall,
    /// The COBS structure is broken.
    Cobs,
    /// Shorter than a CRC.
    TooShort,
    /// The CRC does not match.
    Crc,
    /// The body is not a valid message (or has trailing bytes).
    Body,
}

/// Encode `msg` with sequence number `seq` into `out`; returns the number of bytes written,
/// delimiter included.
pub fn encode_frame<M: Serialize>(seq: u16, msg: &M, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_BODY + 4];
    let body_len = {
        let body = raw.get_mut(..MAX_BODY).ok_or(FrameError::TooLong)?;
        postcard::to_slice(&Frame { seq, msg }, body)
            .map_err(|_| FrameError::TooLong)?
            .len()
    };
    let crc = CRC32C.checksum(raw.get(..body_len).ok_or(FrameError::TooLong)?);
    raw.get_mut(body_len..body_len.saturating_add(4))
        .ok_or(FrameError::TooLong)?
        .copy_from_slice(&crc.to_le_bytes());
    let raw = raw
        .get(..body_len.saturating_add(4))
        .ok_or(FrameError::TooLong)?;
    let n = cobs_encode(raw, out)?;
    *out.get_mut(n).ok_or(FrameError::BufferTooSmall)? = 0;
    Ok(n.saturating_add(1))
}

/// COBS-encode `input` into `out` (no delimiter); returns the encoded length.
fn cobs_encode(input: &[u8], out: &mut [u8]) -> Result<usize, FrameError> {
    let mut code_at = 0usize;
    let mut w = 1usize;
    let mut code: u8 = 1;
    for &b in input {
        if b == 0 {
            *out.get_mut(code_at).ok_or(FrameError::BufferTooSmall)? = code;
            code_at = w;
            w = w.saturating_add(1);
            code = 1;
        } else {
            *out.get_mut(w).ok_or(FrameError::BufferTooSmall)? = b;
            w = w.saturating_add(1);
            code = code.saturating_add(1);
            if code == 0xFF {
                *out.get_mut(code_at).ok_or(FrameError::BufferTooSmall)? = code;
                code_at = w;
                w = w.saturating_add(1);
                code = 1;
            }
        }
    }
    *out.get_mut(code_at).ok_or(FrameError::BufferTooSmall)? = code;
    Ok(w)
}

/// Walk the COBS block chain of `src` without copying; the decoded length if the chain ends
/// exactly at the end of `src`.
fn cobs_decoded_len(src: &[u8]) -> Option<usize> {
    let mut r = 0usize;
    let mut n = 0usize;
    while r < src.len() {
        let code = *src.get(r)? as usize;
        if code == 0 {
            return None;
        }
        r = r.saturating_add(code);
        n = n.saturating_add(code.saturating_sub(1));
        if code != 0xFF && r < src.len() {
            n = n.saturating_add(1);
        }
    }
    (r == src.len()).then_some(n)
}

/// COBS-decode `src` into `dst`; returns the decoded length.
fn cobs_decode(src: &[u8], dst: &mut [u8]) -> Result<usize, FrameError> {
    let len = src.len();
    let mut r = 0usize;
    let mut w = 0usize;
    while r < len {
        let code = *src.get(r).ok_or(FrameError::Cobs)? as usize;
        if code == 0 {
            return Err(FrameError::Cobs);
        }
        r = r.saturating_add(1);
        let end = r.saturating_add(code).saturating_sub(1);
        let run = src.get(r..end).ok_or(FrameError::Cobs)?;
        dst.get_mut(w..w.saturating_add(run.len()))
            .ok_or(FrameError::Cobs)?
            .copy_from_slice(run);
        w = w.saturating_add(run.len());
        r = end;
        if code != 0xFF && r < len {
            *dst.get_mut(w).ok_or(FrameError::Cobs)? = 0;
            w = w.saturating_add(1);
        }
    }
    Ok(w)
}

/// Counters of a [`FrameDecoder`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Frames decoded.
    pub ok: u32,
    /// Frames dropped for being longer than [`MAX_WIRE`].
    pub too_long: u32,
    /// Frames dropped for bad COBS or being too short.
    pub cobs: u32,
    /// Frames dropped for a CRC mismatch.
    pub crc: u32,
    /// Frames dropped for an undecodable body.
    pub body: u32,
}

impl FrameStats {
    /// All dropped frames.
    pub fn dropped(&self) -> u32 {
        self.too_long
            .saturating_add(self.cobs)
            .saturating_add(self.crc)
            .saturating_add(self.body)
    }
}

/// A streaming frame decoder: feed it bytes as they arrive; it yields decoded frames, drops
/// bad ones (counting them) and resynchronises at the next `0x00`. Never panics, never
/// allocates; fixed buffers of 3 × [`MAX_WIRE`] bytes.
///
/// Garbage that reaches the decoder without a delimiter of its own is glued to the front of the
/// next frame. When a frame fails, the decoder therefore also tries each of its suffixes (at
/// most [`MAX_WIRE`] of them, only on the error path), so the good frame behind the garbage is
/// still recovered; the garbage is counted as one dropped frame.
pub struct FrameDecoder {
    buf: [u8; 2 * MAX_WIRE],
    scratch: [u8; MAX_WIRE],
    len: usize,
    overflow: bool,
    stats: FrameStats,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            buf: [0; 2 * MAX_WIRE],
            scratch: [0; MAX_WIRE],
            len: 0,
            overflow: false,
            stats: FrameStats {
                ok: 0,
                too_long: 0,
                cobs: 0,
                crc: 0,
                body: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> FrameStats {
        self.stats
    }

    /// Push one byte; returns a frame or an error when `byte` ends a frame (a `0x00`).
    /// Empty frames (two delimiters in a row) are skipped silently.
    pub fn push<M: DeserializeOwned>(&mut self, byte: u8) -> Option<Result<Frame<M>, FrameError>> {
        if byte != 0 {
            if self.len == self.buf.len() {
                // Keep the newest MAX_WIRE bytes: a good frame behind long garbage survives.
                self.buf.copy_within(self.len.saturating_sub(MAX_WIRE).., 0);
                self.len = MAX_WIRE;
                self.overflow = true;
            }
            if let Some(slot) = self.buf.get_mut(self.len) {
                *slot = byte;
                self.len = self.len.saturating_add(1);
            }
            return None;
        }
        let len = core::mem::replace(&mut self.len, 0);
        let overflow = core::mem::replace(&mut self.overflow, false);
        if len == 0 {
            return None;
        }
        let result = if overflow || len >= MAX_WIRE {
            Err(FrameError::TooLong)
        } else {
            self.decode(0, len)
        };
        match result {
            Ok(_) => self.stats.ok = self.stats.ok.saturating_add(1),
            Err(FrameError::Crc) => self.stats.crc = self.stats.crc.saturating_add(1),
            Err(FrameError::Body) => self.stats.body = self.stats.body.saturating_add(1),
            Err(FrameError::TooLong) => self.stats.too_long = self.stats.too_long.saturating_add(1),
            Err(_) => self.stats.cobs = self.stats.cobs.saturating_add(1),
        }
        if result.is_err() {
            // Garbage glued to the front of a good frame: recover the frame.
            let first = len.saturating_sub(MAX_WIRE - 1).max(1);
            for start in first..len.saturating_sub(5) {
                let plausible = self
                    .buf
                    .get(start..len)
                    .and_then(cobs_decoded_len)
                    .is_some_and(|n| n >= 5);
                if !plausible {
                    continue;
                }
                if let Ok(frame) = self.decode(start, len) {
                    self.stats.ok = self.stats.ok.saturating_add(1);
                    return Some(Ok(frame));
                }
            }
        }
        Some(result)
    }

    /// Push a slice, calling `f` for each frame or error.
    pub fn feed<M: DeserializeOwned>(
        &mut self,
        bytes: &[u8],
        mut f: impl FnMut(Result<Frame<M>, FrameError>),
    ) {
        for &b in bytes {
            if let Some(r) = self.push(b) {
                f(r);
            }
        }
    }

    fn decode<M: DeserializeOwned>(
        &mut self,
        start: usize,
        len: usize,
    ) -> Result<Frame<M>, FrameError> {
        let enc = self.buf.get(start..len).ok_or(FrameError::TooLong)?;
        let n = cobs_decode(enc, &mut self.scratch)?;
        if n < 5 {
            return Err(FrameError::TooShort);
        }
        let body_len = n.saturating_sub(4);
        let body = self.scratch.get(..body_len).ok_or(FrameError::TooShort)?;
        let crc_bytes = self.scratch.get(body_len..n).ok_or(FrameError::TooShort)?;
        let mut crc = [0u8; 4];
        crc.copy_from_slice(crc_bytes);
        if CRC32C.checksum(body) != u32::from_le_bytes(crc) {
            return Err(FrameError::Crc);
        }
        match postcard::take_from_bytes::<Frame<M>>(body) {
            Ok((frame, [])) => Ok(frame),
            _ => Err(FrameError::Body),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{HostMsg, FRAME_OVERHEAD};

    #[test]
    fn overhead_is_six_bytes() {
        let msg = HostMsg::SetWatchdog { period_ms: 300 };
        let mut body = [0u8; MAX_BODY];
        let body_len = postcard::to_slice(
            &Frame {
                seq: 7,
                msg: msg.clone(),
            },
            &mut body,
        )
        .map(|b| b.len())
        .unwrap_or(usize::MAX);
        let mut out = [0u8; MAX_WIRE];
        let n = encode_frame(7, &msg, &mut out).unwrap_or(0);
        assert_eq!(n, body_len + FRAME_OVERHEAD);
    }

    #[test]
    fn cobs_handles_runs_of_254() {
        let input = [0x11u8; 251];
        let mut enc = [0u8; 260];
        let n = cobs_encode(&input, &mut enc).unwrap_or(0);
        assert_eq!(n, 252);
        let mut dec = [0u8; 260];
        let m = cobs_decode(&enc[..n], &mut dec).unwrap_or(0);
        assert_eq!(&dec[..m], &input[..]);
    }
}
