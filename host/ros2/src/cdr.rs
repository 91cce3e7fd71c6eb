//! CDR, the encoding of ROS 2 messages (OMG XCDR1, little-endian, as rmw writes it): a 4-byte
//! encapsulation header, then each field at its natural alignment counted from the end of the
//! header; strings with their length (terminating NUL included) and a NUL; sequences with
//! their length; fixed arrays bare.
//!
//! Written here rather than taken from a crate: the few messages we write are fixed, and images
//! need their bytes copied in bulk, which the serde-based `cdr` crate (unreleased since 2021)
//! does one element at a time. The tests decode our bytes with rosbags' CDR decoder.

/// The encapsulation header of little-endian plain CDR (`CDR_LE`).
pub const CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// A CDR message being written.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::with_capacity(64)
    }
}

impl CdrWriter {
    /// An empty message with room for `capacity` bytes (header included).
    pub fn with_capacity(capacity: usize) -> CdrWriter {
        let mut buf = Vec::with_capacity(capacity.max(4));
        buf.extend_from_slice(&CDR_LE);
        CdrWriter { buf }
    }

    /// The encoded message, header first.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    /// Pad to a multiple of `n` bytes from the end of the header.
    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - CDR_LE.len();
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// A `uint8` (or `bool`, `byte`, `char`).
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// An `int8`.
    pub fn i8(&mut self, v: i8) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float32`.
    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int8[]`.
    pub fn i8_seq(&mut self, v: &[i8]) {
        self.seq_len(v.len());
        self.buf.extend(v.iter().map(|&x| x as u8));
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `string`.
    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// A sequence's length.
    pub fn seq_len(&mut self, n: usize) {
        self.u32(n as u32);
    }

    /// A `uint8[]`: its length and its bytes.
    pub fn bytes(&mut self, b: &[u8]) {
        self.seq_len(b.len());
        self.buf.extend_from_slice(b);
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self, v: &[f64]) {
        self.seq_len(v.len());
        self.f64_array(v);
    }

    /// A `float64[N]` (no length).
    pub fn f64_array(&mut self, v: &[f64]) {
        for &x in v {
            self.f64(x);
        }
    }

    /// A `string[]`.
    pub fn string_seq<S: AsRef<str>>(&mut self, v: &[S]) {
        self.seq_len(v.len());
        for s in v {
            self.string(s.as_ref());
        }
    }
}

/// Why a CDR message could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// Not little-endian plain CDR.
    #[error("not a little-endian CDR message (encapsulation header {0:02x?})")]
    Header([u8; 4]),
    /// The message ends before a field.
    #[error("the CDR message ends at byte {at} before a field of {need} bytes")]
    Truncated {
        /// Where the field began.
        at: usize,
        /// Its size.
        need: usize,
    },
    /// A string is not UTF-8 or not NUL-terminated.
    #[error("a CDR string at byte {0} is malformed")]
    String(usize),
}

/// A CDR message being read, field by field, in the order it was written.
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    /// A reader of `buf`, which must begin with the `CDR_LE` header.
    pub fn new(buf: &'a [u8]) -> Result<CdrReader<'a>, CdrError> {
        let head: [u8; 4] = buf
            .get(..4)
            .and_then(|h| h.try_into().ok())
            .ok_or(CdrError::Truncated { at: 0, need: 4 })?;
        if head != CDR_LE {
            return Err(CdrError::Header(head));
        }
        Ok(CdrReader { buf, pos: 4 })
    }

    fn take(&mut self, n: usize, align: usize) -> Result<&'a [u8], CdrError> {
        let rel = self.pos - CDR_LE.len();
        let start = self.pos + (align - rel % align) % align;
        let end = start
            .checked_add(n)
            .filter(|&e| e <= self.buf.len())
            .ok_or(CdrError::Truncated { at: start, need: n })?;
        self.pos = end;
        Ok(&self.buf[start..end])
    }

    /// A `uint8`.
    pub fn u8(&mut self) -> Result<u8, CdrError> {
        Ok(self.take(1, 1)?[0])
    }

    /// An `int8`.
    pub fn i8(&mut self) -> Result<i8, CdrError> {
        Ok(self.take(1, 1)?[0] as i8)
    }

    /// A `uint32`.
    pub fn u32(&mut self) -> Result<u32, CdrError> {
        let b = self.take(4, 4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// An `int32`.
    pub fn i32(&mut self) -> Result<i32, CdrError> {
        Ok(self.u32()? as i32)
    }

    /// A `float64`.
    pub fn f64(&mut self) -> Result<f64, CdrError> {
        let b = self.take(8, 8)?;
        let mut a = [0; 8];
        a.copy_from_slice(b);
        Ok(f64::from_le_bytes(a))
    }

    /// A `string`.
    pub fn string(&mut self) -> Result<String, CdrError> {
        let n = self.u32()? as usize;
        let at = self.pos;
        let b = self.take(n, 1)?;
        match b.split_last() {
            Some((0, s)) => std::str::from_utf8(s)
                .map(str::to_string)
                .map_err(|_| CdrError::String(at)),
            _ => Err(CdrError::String(at)),
        }
    }

    /// A `uint8[]`.
    pub fn bytes(&mut self) -> Result<&'a [u8], CdrError> {
        let n = self.u32()? as usize;
        self.take(n, 1)
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self) -> Result<Vec<f64>, CdrError> {
        let n = self.u32()? as usize;
        self.f64_array(n)
    }

    /// A `float64[n]`.
    pub fn f64_array(&mut self, n: usize) -> Result<Vec<f64>, CdrError> {
        // No allocation beyond what the message can hold.
        let room = self.buf.len().saturating_sub(self.pos) / 8;
        let mut v = Vec::with_capacity(n.min(room));
        for _ in 0..n {
            v.push(self.f64()?);
        }
        Ok(v)
    }

    /// A `string[]`.
    pub fn string_seq(&mut self) -> Result<Vec<String>, CdrError> {
        let n = self.u32()? as usize;
        let room = self.buf.len().saturating_sub(self.pos) / 5;
        let mut v = Vec::with_capacity(n.min(room));
        for _ in 0..n {
            v.push(self.string()?);
        }
        Ok(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_align_from_the_end_of_the_header_and_read_back() {
        let mut w = CdrWriter::default();
        w.u8(7);
        w.f64(1.5);
        w.string("ab");
        w.i32(-3);
        w.f64_seq(&[2.0, -4.0]);
        w.string_seq(&["x"]);
        w.bytes(&[1, 2, 3]);
        let b = w.into_bytes();
        // u8 at 0, f64 at 8 (7 bytes of padding), string length at 16, "ab\0" at 20..23.
        assert_eq!(&b[..4], &CDR_LE);
        assert_eq!(b[4], 7);
        assert_eq!(&b[12..20], &1.5f64.to_le_bytes());
        assert_eq!(&b[20..24], &3u32.to_le_bytes());
        assert_eq!(&b[24..27], b"ab\0");
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.u8().unwrap(), 7);
        assert_eq!(r.f64().unwrap(), 1.5);
        assert_eq!(r.string().unwrap(), "ab");
        assert_eq!(r.i32().unwrap(), -3);
        assert_eq!(r.f64_seq().unwrap(), vec![2.0, -4.0]);
        assert_eq!(r.string_seq().unwrap(), vec!["x".to_string()]);
        assert_eq!(r.bytes().unwrap(), &[1, 2, 3]);
        assert!(matches!(r.u8(), Err(CdrError::Truncated { .. })));
    }

    #[test]
    fn malformed_messages_are_errors_not_panics() {
        assert!(matches!(
            CdrReader::new(&[]),
            Err(CdrError::Truncated { .. })
        ));
        assert!(matches!(
            CdrReader::new(&[1, 0, 0, 0]),
            Err(CdrError::Header(_))
        ));
        // A sequence claiming u32::MAX elements in a short message.
        let mut b = CDR_LE.to_vec();
        b.extend_from_slice(&u32::MAX.to_le_bytes());
        assert!(CdrReader::new(&b).unwrap().f64_seq().is_err());
        assert!(CdrReader::new(&b).unwrap().string_seq().is_err());
        assert!(CdrReader::new(&b).unwrap().bytes().is_err());
        // A string without its NUL.
        let mut b = CDR_LE.to_vec();
        b.extend_from_slice(&2u32.to_le_bytes());
        b.extend_from_slice(b"ab");
        assert!(matches!(
            CdrReader::new(&b).unwrap().string(),
            Err(CdrError::String(_))
        ));
    }
}
