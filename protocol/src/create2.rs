//! iRobot Create 2 Open Interface (115200 baud). Commands are an opcode and its data bytes;
//! 16-bit values are big-endian. The sensor stream sends, every 15 ms,
//! `19 | N | (packet id, data)… | checksum` with the low byte of the sum of all bytes zero.
//! Used by the firmware's Create 2 driver and by the simulated Create 2.

/// Line rate of the Create 2 serial port, bit/s (8N1: 10 bits per byte).
pub const BAUD: u32 = 115_200;

/// Start the Open Interface.
pub const OP_START: u8 = 128;
/// Safe mode.
pub const OP_SAFE: u8 = 131;
/// Full mode.
pub const OP_FULL: u8 = 132;
/// Drive (velocity mm/s, radius mm).
pub const OP_DRIVE: u8 = 137;
/// Drive direct (right mm/s, left mm/s).
pub const OP_DRIVE_DIRECT: u8 = 145;
/// Start a sensor stream.
pub const OP_STREAM: u8 = 148;
/// Pause or resume the stream.
pub const OP_PAUSE_RESUME: u8 = 150;
/// Stop the Open Interface.
pub const OP_STOP: u8 = 173;
/// Stream header byte.
pub const STREAM_HEADER: u8 = 19;
/// Stream period, µs.
pub const STREAM_PERIOD_US: u64 = 15_000;
/// Encoder counts per wheel revolution.
pub const TICKS_PER_REV: f32 = 508.8;
/// Largest wheel speed, mm/s.
pub const MAX_SPEED_MM_S: i16 = 500;

/// Sensor packet ids this project uses.
pub mod packet {
    /// Bumps and wheel drops (1 byte).
    pub const BUMPS_WHEEL_DROPS: u8 = 7;
    /// Cliff left (1 byte).
    pub const CLIFF_LEFT: u8 = 9;
    /// Cliff front left (1 byte).
    pub const CLIFF_FRONT_LEFT: u8 = 10;
    /// Cliff front right (1 byte).
    pub const CLIFF_FRONT_RIGHT: u8 = 11;
    /// Cliff right (1 byte).
    pub const CLIFF_RIGHT: u8 = 12;
    /// Left encoder counts (2 bytes, signed, wrapping).
    pub const LEFT_ENCODER: u8 = 43;
    /// Right encoder counts (2 bytes, signed, wrapping).
    pub const RIGHT_ENCODER: u8 = 44;
}

/// Bits of packet 7.
pub mod bumps {
    /// Right bump.
    pub const BUMP_RIGHT: u8 = 0x01;
    /// Left bump.
    pub const BUMP_LEFT: u8 = 0x02;
    /// Right wheel drop.
    pub const DROP_RIGHT: u8 = 0x04;
    /// Left wheel drop.
    pub const DROP_LEFT: u8 = 0x08;
}

/// Data length of a sensor packet id, for the ids this project streams.
pub fn packet_len(id: u8) -> Option<usize> {
    match id {
        7..=18 => Some(1),
        43 | 44 => Some(2),
        _ => None,
    }
}

/// The stream this project requests: bumps/drops, four cliffs, both encoders.
pub const STREAM_IDS: [u8; 7] = [
    packet::BUMPS_WHEEL_DROPS,
    packet::CLIFF_LEFT,
    packet::CLIFF_FRONT_LEFT,
    packet::CLIFF_FRONT_RIGHT,
    packet::CLIFF_RIGHT,
    packet::LEFT_ENCODER,
    packet::RIGHT_ENCODER,
];

/// Drive-direct command bytes.
pub fn drive_direct(right_mm_s: i16, left_mm_s: i16) -> [u8; 5] {
    let r = right_mm_s.to_be_bytes();
    let l = left_mm_s.to_be_bytes();
    [OP_DRIVE_DIRECT, r[0], r[1], l[0], l[1]]
}

/// The sensor values this project streams.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Sensors {
    /// Packet 7 bits.
    pub bumps_drops: u8,
    /// Cliff sensors left, front-left, front-right, right (nonzero: cliff).
    pub cliffs: [u8; 4],
    /// Left encoder counts.
    pub left_encoder: i16,
    /// Right encoder counts.
    pub right_encoder: i16,
}

/// Encode one stream packet of [`STREAM_IDS`] into `out`; returns its length.
pub fn encode_stream(s: &Sensors, out: &mut [u8]) -> Option<usize> {
    let l = s.left_encoder.to_be_bytes();
    let r = s.right_encoder.to_be_bytes();
    let body = [
        packet::BUMPS_WHEEL_DROPS,
        s.bumps_drops,
        packet::CLIFF_LEFT,
        s.cliffs[0],
        packet::CLIFF_FRONT_LEFT,
        s.cliffs[1],
        packet::CLIFF_FRONT_RIGHT,
        s.cliffs[2],
        packet::CLIFF_RIGHT,
        s.cliffs[3],
        packet::LEFT_ENCODER,
        l[0],
        l[1],
        packet::RIGHT_ENCODER,
        r[0],
        r[1],
    ];
    let head = [STREAM_HEADER, body.len() as u8];
    let sum = head
        .iter()
        .chain(&body)
        .fold(0u8, |a, b| a.wrapping_add(*b));
    let mut w = 0;
    for &b in head.iter().chain(&body).chain(&[0u8.wrapping_sub(sum)]) {
        *out.get_mut(w)? = b;
        w = w.saturating_add(1);
    }
    Some(w)
}

/// Stream parser errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamError {
    /// Checksum mismatch.
    Checksum,
    /// A packet id this parser does not know, or a truncated packet.
    Malformed,
    /// A well-formed packet without one of [`STREAM_IDS`].
    Incomplete,
}

/// Streaming parser of sensor-stream packets. Never panics, never allocates.
pub struct StreamParser {
    st: u8,
    len: usize,
    buf: [u8; 255],
    n: usize,
    /// Packets accepted.
    pub ok: u32,
    /// Packets dropped.
    pub bad: u32,
}

impl Default for StreamParser {
    fn default() -> Self {
        Self::new()
    }
}

impl StreamParser {
    /// An idle parser.
    pub const fn new() -> Self {
        Self {
            st: 0,
            len: 0,
            buf: [0; 255],
            n: 0,
            ok: 0,
            bad: 0,
        }
    }

    /// Push a byte; returns decoded sensors at the end of a packet.
    pub fn push(&mut self, b: u8) -> Option<Result<Sensors, StreamError>> {
        match self.st {
            0 => {
                if b == STREAM_HEADER {
                    self.st = 1;
                }
                None
            }
            1 => {
                self.len = b as usize;
                self.n = 0;
                self.st = if self.len == 0 { 3 } else { 2 };
                None
            }
            2 => {
                if let Some(s) = self.buf.get_mut(self.n) {
                    *s = b;
                }
                self.n = self.n.saturating_add(1);
                if self.n >= self.len {
                    self.st = 3;
                }
                None
            }
            _ => {
                self.st = 0;
                let body = self.buf.get(..self.len).unwrap_or(&[]);
                let sum = body
                    .iter()
                    .fold(STREAM_HEADER.wrapping_add(self.len as u8), |a, x| {
                        a.wrapping_add(*x)
                    })
                    .wrapping_add(b);
                if sum != 0 {
                    self.bad = self.bad.saturating_add(1);
                    return Some(Err(StreamError::Checksum));
                }
                let r = parse_body(body);
                match r {
                    Ok(_) => self.ok = self.ok.saturating_add(1),
                    Err(_) => self.bad = self.bad.saturating_add(1),
                }
                Some(r)
            }
        }
    }
}

fn parse_body(mut body: &[u8]) -> Result<Sensors, StreamError> {
    let mut s = Sensors::default();
    // Bit k: STREAM_IDS[k] was in the packet.
    const ALL: u8 = 0x7f;
    const _: () = assert!(STREAM_IDS.len() == 7);
    let mut seen = 0u8;
    while let Some((&id, rest)) = body.split_first() {
        let n = packet_len(id).ok_or(StreamError::Malformed)?;
        let d = rest.get(..n).ok_or(StreamError::Malformed)?;
        if let Some(k) = STREAM_IDS.iter().position(|&x| x == id) {
            seen |= 1u8.checked_shl(k as u32).unwrap_or(0);
        }
        match (id, d) {
            (packet::BUMPS_WHEEL_DROPS, [v]) => s.bumps_drops = *v,
            (9..=12, [v]) => {
                if let Some(c) = s.cliffs.get_mut(id.wrapping_sub(9) as usize) {
                    *c = *v;
                }
            }
            (packet::LEFT_ENCODER, [a, b]) => s.left_encoder = i16::from_be_bytes([*a, *b]),
            (packet::RIGHT_ENCODER, [a, b]) => s.right_encoder = i16::from_be_bytes([*a, *b]),
            _ => {}
        }
        body = rest.get(n..).unwrap_or(&[]);
    }
    // A value missing would read as zero: no bump, no cliff, an encoder jumped to 0.
    if seen != ALL {
        return Err(StreamError::Incomplete);
    }
    Ok(s)
}

/// Data bytes that follow each opcode, for a command parser; `None` for an unknown opcode.
/// For [`OP_STREAM`] the first data byte is a count N of further bytes.
pub fn command_len(opcode: u8) -> Option<usize> {
    match opcode {
        OP_START | OP_SAFE | OP_FULL | OP_STOP => Some(0),
        OP_DRIVE | OP_DRIVE_DIRECT => Some(4),
        OP_STREAM | OP_PAUSE_RESUME => Some(1),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stream_round_trip() {
        let s = Sensors {
            bumps_drops: bumps::BUMP_LEFT,
            cliffs: [0, 1, 0, 0],
            left_encoder: -32000,
            right_encoder: 1234,
        };
        let mut b = [0u8; 64];
        let n = encode_stream(&s, &mut b).unwrap_or(0);
        let mut p = StreamParser::new();
        let mut got = None;
        for &x in &b[..n] {
            if let Some(r) = p.push(x) {
                got = r.ok();
            }
        }
        assert_eq!(got, Some(s));
    }

    /// The stream's bytes for `body` (packet ids and data), with header, count and checksum.
    fn packet(body: &[u8]) -> heapless::Vec<u8, 64> {
        let mut out = heapless::Vec::new();
        let _ = out.push(STREAM_HEADER);
        let _ = out.push(body.len() as u8);
        let _ = out.extend_from_slice(body);
        let sum = out.iter().fold(0u8, |a, b| a.wrapping_add(*b));
        let _ = out.push(0u8.wrapping_sub(sum));
        out
    }

    /// A packet missing one of the requested sensors is refused, with a good checksum: its
    /// value would read as zero (a bump or a cliff not seen, an encoder jumped to 0). Extra
    /// known packets are allowed.
    #[test]
    fn a_packet_missing_a_requested_sensor_is_refused() {
        let full = [7, 0, 9, 0, 10, 0, 11, 0, 12, 0, 43, 1, 2, 44, 3, 4];
        let parse = |bytes: &[u8]| {
            let mut p = StreamParser::new();
            bytes.iter().filter_map(|&b| p.push(b)).last()
        };
        assert!(matches!(parse(&packet(&full)), Some(Ok(_))));
        let mut extra = heapless::Vec::<u8, 32>::from_slice(&full).unwrap_or_default();
        let _ = extra.extend_from_slice(&[13, 0]);
        assert!(matches!(parse(&packet(&extra)), Some(Ok(_))));
        // Without the bumps, a cliff, or the right encoder.
        for cut in [0..2, 4..6, 13..16] {
            let body: heapless::Vec<u8, 32> = full
                .iter()
                .enumerate()
                .filter(|(i, _)| !cut.contains(i))
                .map(|(_, &b)| b)
                .collect();
            assert_eq!(
                parse(&packet(&body)),
                Some(Err(StreamError::Incomplete)),
                "{body:?}"
            );
        }
    }
}
