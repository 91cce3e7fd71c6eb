//! Yujin Kobuki serial protocol (115200 baud): packets `AA 55 | LEN | payload | CS`, the payload
//! a sequence of sub-payloads `(id, length, data)`, CS the XOR of LEN and every payload byte.
//! Multi-byte fields are little-endian. Used by the firmware's Kobuki driver and by the
//! simulated Kobuki.

/// Line rate of the Kobuki serial port, bit/s (8N1: 10 bits per byte).
pub const BAUD: u32 = 115_200;

/// First header byte.
pub const HEADER0: u8 = 0xAA;
/// Second header byte.
pub const HEADER1: u8 = 0x55;
/// Command sub-payload: base control (speed mm/s, radius mm).
pub const CMD_BASE_CONTROL: u8 = 0x01;
/// Feedback sub-payload: basic sensor data (15 bytes).
pub const FB_BASIC_SENSOR_DATA: u8 = 0x01;
/// Feedback sub-payload: inertial sensor (7 bytes).
pub const FB_INERTIA: u8 = 0x04;
/// The heading of an inertial sub-payload ([`FB_INERTIA`]): the gyro's integrated angle,
/// rad, counter-clockwise, from its little-endian signed hundredths of a degree; `None` when
/// the sub-payload is short.
pub fn inertial_angle(data: &[u8]) -> Option<f32> {
    let b: [u8; 2] = data.get(..2)?.try_into().ok()?;
    Some((i16::from_le_bytes(b) as f32 * 0.01).to_radians())
}

/// Encoder ticks per wheel revolution (0.002436917 rad per tick).
pub const TICKS_PER_REV: f32 = 2578.33;

/// Bumper bits of [`BasicSensorData::bumper`].
pub mod bumper {
    /// Right bumper.
    pub const RIGHT: u8 = 0x01;
    /// Centre bumper.
    pub const CENTER: u8 = 0x02;
    /// Left bumper.
    pub const LEFT: u8 = 0x04;
}
/// Wheel-drop bits of [`BasicSensorData::wheel_drop`].
pub mod wheel_drop {
    /// Right wheel.
    pub const RIGHT: u8 = 0x01;
    /// Left wheel.
    pub const LEFT: u8 = 0x02;
}
/// Cliff bits of [`BasicSensorData::cliff`].
pub mod cliff {
    /// Right sensor.
    pub const RIGHT: u8 = 0x01;
    /// Centre sensor.
    pub const CENTER: u8 = 0x02;
    /// Left sensor.
    pub const LEFT: u8 = 0x04;
}

/// The basic sensor data sub-payload (id 0x01, 15 bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BasicSensorData {
    /// Kobuki clock, ms, wrapping.
    pub timestamp_ms: u16,
    /// [`bumper`] bits.
    pub bumper: u8,
    /// [`wheel_drop`] bits.
    pub wheel_drop: u8,
    /// [`cliff`] bits.
    pub cliff: u8,
    /// Left encoder, ticks, wrapping.
    pub left_encoder: u16,
    /// Right encoder, ticks, wrapping.
    pub right_encoder: u16,
    /// Left motor PWM, %.
    pub left_pwm: i8,
    /// Right motor PWM, %.
    pub right_pwm: i8,
    /// Buttons.
    pub buttons: u8,
    /// Charger state.
    pub charger: u8,
    /// Battery voltage, 0.1 V.
    pub battery: u8,
    /// Over-current flags.
    pub over_current: u8,
}

impl BasicSensorData {
    /// Data length.
    pub const LEN: usize = 15;

    /// Encode the data bytes.
    pub fn to_bytes(&self) -> [u8; 15] {
        let t = self.timestamp_ms.to_le_bytes();
        let l = self.left_encoder.to_le_bytes();
        let r = self.right_encoder.to_le_bytes();
        [
            t[0],
            t[1],
            self.bumper,
            self.wheel_drop,
            self.cliff,
            l[0],
            l[1],
            r[0],
            r[1],
            self.left_pwm as u8,
            self.right_pwm as u8,
            self.buttons,
            self.charger,
            self.battery,
            self.over_current,
        ]
    }

    /// Decode from data bytes; `None` when the length is wrong.
    pub fn from_bytes(d: &[u8]) -> Option<Self> {
        let d: &[u8; 15] = d.try_into().ok()?;
        Some(Self {
            timestamp_ms: u16::from_le_bytes([d[0], d[1]]),
            bumper: d[2],
            wheel_drop: d[3],
            cliff: d[4],
            left_encoder: u16::from_le_bytes([d[5], d[6]]),
            right_encoder: u16::from_le_bytes([d[7], d[8]]),
            left_pwm: d[9] as i8,
            right_pwm: d[10] as i8,
            buttons: d[11],
            charger: d[12],
            battery: d[13],
            over_current: d[14],
        })
    }
}

/// Encode a packet around `payload` into `out`; returns its length.
pub fn encode_packet(payload: &[u8], out: &mut [u8]) -> Option<usize> {
    let len = u8::try_from(payload.len()).ok()?;
    let cs = payload.iter().fold(len, |a, b| a ^ b);
    let mut w = 0;
    for &b in [HEADER0, HEADER1, len].iter().chain(payload).chain(&[cs]) {
        *out.get_mut(w)? = b;
        w = w.saturating_add(1);
    }
    Some(w)
}

/// A base-control command packet.
pub fn encode_base_control(speed_mm_s: i16, radius_mm: i16, out: &mut [u8]) -> Option<usize> {
    let s = speed_mm_s.to_le_bytes();
    let r = radius_mm.to_le_bytes();
    encode_packet(&[CMD_BASE_CONTROL, 4, s[0], s[1], r[0], r[1]], out)
}

/// Kobuki's (speed, radius) encoding of a body velocity (`v` m/s, `w` rad/s) for wheel
/// separation `bias` m, as the Kobuki driver computes it: radius 0 drives straight, radius 1
/// spins in place with `speed` the wheel speed, otherwise `speed` is the outer wheel's speed.
pub fn speed_radius(v: f32, w: f32, bias: f32) -> (i16, i16) {
    const EPS: f32 = 1e-4;
    let sat = |x: f32| x.clamp(i16::MIN as f32, i16::MAX as f32) as i16;
    if w.abs() < EPS {
        return (sat(1000.0 * v), 0);
    }
    let radius = v * 1000.0 / w;
    if v.abs() < EPS || radius.abs() <= 1.0 {
        return (sat(1000.0 * bias * w / 2.0), 1);
    }
    let speed = if radius > 0.0 {
        (radius + 1000.0 * bias / 2.0) * w
    } else {
        (radius - 1000.0 * bias / 2.0) * w
    };
    (sat(speed), sat(radius))
}

/// Wheel speeds (left, right), m/s, that a (speed, radius) command asks for.
pub fn wheel_speeds(speed_mm_s: i16, radius_mm: i16, bias: f32) -> (f32, f32) {
    let s = speed_mm_s as f32 / 1000.0;
    match radius_mm {
        0 => (s, s),
        1 => (-s, s),
        r => {
            let r = r as f32 / 1000.0;
            let w = if r > 0.0 {
                s / (r + bias / 2.0)
            } else {
                s / (r - bias / 2.0)
            };
            let v = w * r;
            (v - w * bias / 2.0, v + w * bias / 2.0)
        }
    }
}

/// Parser errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KobukiError {
    /// XOR checksum mismatch.
    Checksum,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum St {
    H0,
    H1,
    Len,
    Body,
    Cs,
}

/// Streaming packet parser (either direction). Never panics, never allocates.
pub struct Parser {
    st: St,
    len: usize,
    buf: [u8; 255],
    n: usize,
    /// Packets accepted.
    pub ok: u32,
    /// Packets dropped.
    pub bad: u32,
}

impl Default for Parser {
    fn default() -> Self {
        Self::new()
    }
}

impl Parser {
    /// An idle parser.
    pub const fn new() -> Self {
        Self {
            st: St::H0,
            len: 0,
            buf: [0; 255],
            n: 0,
            ok: 0,
            bad: 0,
        }
    }

    /// Push a byte; returns the payload of a complete packet, or an error.
    pub fn push(&mut self, b: u8) -> Option<Result<&[u8], KobukiError>> {
        match self.st {
            St::H0 => {
                if b == HEADER0 {
                    self.st = St::H1;
                }
            }
            St::H1 => {
                self.st = match b {
                    HEADER1 => St::Len,
                    HEADER0 => St::H1,
                    _ => St::H0,
                }
            }
            St::Len => {
                self.len = b as usize;
                self.n = 0;
                self.st = if self.len == 0 { St::Cs } else { St::Body };
            }
            St::Body => {
                if let Some(s) = self.buf.get_mut(self.n) {
                    *s = b;
                }
                self.n = self.n.saturating_add(1);
                if self.n >= self.len {
                    self.st = St::Cs;
                }
            }
            St::Cs => {
                self.st = St::H0;
                let payload = self.buf.get(..self.len).unwrap_or(&[]);
                let cs = payload.iter().fold(self.len as u8, |a, x| a ^ x);
                if cs != b {
                    self.bad = self.bad.saturating_add(1);
                    return Some(Err(KobukiError::Checksum));
                }
                self.ok = self.ok.saturating_add(1);
                return Some(Ok(payload));
            }
        }
        None
    }
}

/// Iterate the `(id, data)` sub-payloads of a payload; stops at a truncated one.
pub fn sub_payloads(payload: &[u8]) -> impl Iterator<Item = (u8, &[u8])> {
    let mut rest = payload;
    core::iter::from_fn(move || {
        let (&id, r) = rest.split_first()?;
        let (&len, r) = r.split_first()?;
        let data = r.get(..len as usize)?;
        rest = r.get(len as usize..).unwrap_or(&[]);
        Some((id, data))
    })
}
