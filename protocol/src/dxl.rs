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

use crate::messages::{ServoGains, ServoModel};

const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_UMTS);

/// The fixed packet header.
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];
/// Broadcast ID: every servo obeys; only instructions that say so get answers.
pub const BROADCAST_ID: u8 = 0xFE;
/// Bytes of a packet besides its instruction and parameters: header 4, ID 1, LEN 2, CRC 2.
pub const PACKET_OVERHEAD: usize = 9;

/// Instruction codes.
pub mod inst {
    /// Ping.
    pub const PING: u8 = 0x01;
    /// Read.
    pub const READ: u8 = 0x02;
    /// Write.
    pub const WRITE: u8 = 0x03;
    /// Registered write.
    pub const REG_WRITE: u8 = 0x04;
    /// Action (execute registered writes).
    pub const ACTION: u8 = 0x05;
    /// Factory reset.
    pub const FACTORY_RESET: u8 = 0x06;
    /// Reboot.
    pub const REBOOT: u8 = 0x08;
    /// Clear multi-turn or errors.
    pub const CLEAR: u8 = 0x10;
    /// Status packet (servo to master).
    pub const STATUS: u8 = 0x55;
    /// Sync read.
    pub const SYNC_READ: u8 = 0x82;
    /// Sync write.
    pub const SYNC_WRITE: u8 = 0x83;
    /// Fast sync read.
    pub const FAST_SYNC_READ: u8 = 0x8A;
    /// Bulk read.
    pub const BULK_READ: u8 = 0x92;
    /// Bulk write.
    pub const BULK_WRITE: u8 = 0x93;
}

/// Status-packet error byte: the alert bit (a hardware error is latched in address 70) and the
/// 7-bit error number.
pub mod status_error {
    /// A hardware error is present; read Hardware Error Status (70).
    pub const ALERT: u8 = 0x80;
    /// Result fail.
    pub const RESULT_FAIL: u8 = 0x01;
    /// Undefined instruction.
    pub const INSTRUCTION: u8 = 0x02;
    /// CRC mismatch.
    pub const CRC: u8 = 0x03;
    /// Value out of range.
    pub const DATA_RANGE: u8 = 0x04;
    /// Data shorter than the item.
    pub const DATA_LENGTH: u8 = 0x05;
    /// Value beyond a limit.
    pub const DATA_LIMIT: u8 = 0x06;
    /// Read-only item, undefined address, or write to an EEPROM item with torque on.
    pub const ACCESS: u8 = 0x07;
}

/// Hardware Error Status (address 70) bits.
pub mod hw_error {
    /// Input voltage out of range.
    pub const INPUT_VOLTAGE: u8 = 1 << 0;
    /// Overheating.
    pub const OVERHEATING: u8 = 1 << 2;
    /// Motor encoder failure.
    pub const ENCODER: u8 = 1 << 3;
    /// Electrical shock.
    pub const ELECTRICAL_SHOCK: u8 = 1 << 4;
    /// Persistent load beyond the maximum.
    pub const OVERLOAD: u8 = 1 << 5;
}

/// X-series control-table addresses (XM430 and XL430 share these).
pub mod addr {
    /// Model number, 2 bytes.
    pub const MODEL_NUMBER: u16 = 0;
    /// Firmware version, 1 byte.
    pub const FIRMWARE_VERSION: u16 = 6;
    /// ID, 1 byte.
    pub const ID: u16 = 7;
    /// Baud rate index, 1 byte.
    pub const BAUD_RATE: u16 = 8;
    /// Return delay time, 1 byte, 2 µs units.
    pub const RETURN_DELAY_TIME: u16 = 9;
    /// Drive mode, 1 byte.
    pub const DRIVE_MODE: u16 = 10;
    /// Operating mode, 1 byte.
    pub const OPERATING_MODE: u16 = 11;
    /// PWM limit, 2 bytes.
    pub const PWM_LIMIT: u16 = 36;
    /// Current limit, 2 bytes (XM only).
    pub const CURRENT_LIMIT: u16 = 38;
    /// Velocity limit, 4 bytes.
    pub const VELOCITY_LIMIT: u16 = 44;
    /// Max position limit, 4 bytes.
    pub const MAX_POSITION_LIMIT: u16 = 48;
    /// Min position limit, 4 bytes.
    pub const MIN_POSITION_LIMIT: u16 = 52;
    /// Torque enable, 1 byte.
    pub const TORQUE_ENABLE: u16 = 64;
    /// LED, 1 byte.
    pub const LED: u16 = 65;
    /// Status return level, 1 byte.
    pub const STATUS_RETURN_LEVEL: u16 = 68;
    /// Hardware error status, 1 byte.
    pub const HARDWARE_ERROR_STATUS: u16 = 70;
    /// Velocity I gain, 2 bytes.
    pub const VELOCITY_I_GAIN: u16 = 76;
    /// Velocity P gain, 2 bytes.
    pub const VELOCITY_P_GAIN: u16 = 78;
    /// Position D gain, 2 bytes.
    pub const POSITION_D_GAIN: u16 = 80;
    /// Position I gain, 2 bytes.
    pub const POSITION_I_GAIN: u16 = 82;
    /// Position P gain, 2 bytes.
    pub const POSITION_P_GAIN: u16 = 84;
    /// Bus watchdog, 1 byte, 20 ms units.
    pub const BUS_WATCHDOG: u16 = 98;
    /// Goal PWM, 2 bytes.
    pub const GOAL_PWM: u16 = 100;
    /// Goal current, 2 bytes (XM only).
    pub const GOAL_CURRENT: u16 = 102;
    /// Goal velocity, 4 bytes.
    pub const GOAL_VELOCITY: u16 = 104;
    /// Profile acceleration, 4 bytes.
    pub const PROFILE_ACCELERATION: u16 = 108;
    /// Profile velocity, 4 bytes.
    pub const PROFILE_VELOCITY: u16 = 112;
    /// Goal position, 4 bytes.
    pub const GOAL_POSITION: u16 = 116;
    /// Moving, 1 byte.
    pub const MOVING: u16 = 122;
    /// Present PWM, 2 bytes.
    pub const PRESENT_PWM: u16 = 124;
    /// Present current (XM) or present load (XL), 2 bytes.
    pub const PRESENT_CURRENT: u16 = 126;
    /// Present velocity, 4 bytes.
    pub const PRESENT_VELOCITY: u16 = 128;
    /// Present position, 4 bytes.
    pub const PRESENT_POSITION: u16 = 132;
    /// Present input voltage, 2 bytes, 0.1 V.
    pub const PRESENT_INPUT_VOLTAGE: u16 = 144;
    /// Present temperature, 1 byte, °C.
    pub const PRESENT_TEMPERATURE: u16 = 146;
    /// Size of the modelled control table (RAM area up to the temperature).
    pub const TABLE_SIZE: usize = 147;
}

/// Operating-mode values (address 11).
pub mod mode {
    /// Current control (XM only).
    pub const CURRENT: u8 = 0;
    /// Velocity control.
    pub const VELOCITY: u8 = 1;
    /// Position control.
    pub const POSITION: u8 = 3;
    /// Extended (multi-turn) position control.
    pub const EXTENDED_POSITION: u8 = 4;
    /// Current-based position control (XM only).
    pub const CURRENT_BASED_POSITION: u8 = 5;
    /// PWM (voltage) control.
    pub const PWM: u8 = 16;
}

/// Unit conversions of the X series.
pub mod units {
    use core::f32::consts::PI;
    /// Position ticks per revolution.
    pub const TICKS_PER_REV: f32 = 4096.0;
    /// Tick that corresponds to 0 rad.
    pub const CENTER_TICK: i32 = 2048;
    /// rad per position tick.
    pub const RAD_PER_TICK: f32 = 2.0 * PI / TICKS_PER_REV;
    /// rad/s per velocity unit (0.229 rpm).
    pub const RAD_S_PER_VELOCITY_UNIT: f32 = 0.229 * 2.0 * PI / 60.0;
    /// A per current unit (XM430: 2.69 mA).
    pub const AMP_PER_CURRENT_UNIT: f32 = 0.00269;
    /// Goal-PWM units at 100 % duty.
    pub const PWM_MAX: f32 = 885.0;
    /// Present-load units (XL430) at 100 % of stall torque (0.1 % units).
    pub const LOAD_FULL_SCALE: f32 = 1000.0;
    /// Model number of the XM430-W350.
    pub const MODEL_XM430_W350: u16 = 1020;
    /// Model number of the XL430-W250.
    pub const MODEL_XL430_W250: u16 = 1060;

    /// Servo angle (rad, 0 at the centre tick) to a position tick.
    pub fn rad_to_tick(rad: f32) -> i32 {
        let t = rad / RAD_PER_TICK;
        // Round half away from zero without libm.
        let r = if t >= 0.0 { t + 0.5 } else { t - 0.5 };
        CENTER_TICK.saturating_add(r as i32)
    }

    /// Position tick to servo angle (rad).
    pub fn tick_to_rad(tick: i32) -> f32 {
        (tick.saturating_sub(CENTER_TICK)) as f32 * RAD_PER_TICK
    }
}

/// Electrical and mechanical data of a servo model at its 12 V supply, output-shaft side.
///
/// A DC motor with gear: `τ = Kt·i`, `V = R·i + Ke·ω`, `Kt = Ke = V/ω₀`, `R = V·Kt/τ_stall`.
/// With the XM430-W350's 4.1 N·m stall torque and 46 rpm no-load speed this gives a torque
/// constant of 2.49 N·m/A, within 0.4 % of the 149.795 current units per N·m the LoCoBot driver
/// uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorSpec {
    /// Stall torque at the supply voltage, N·m.
    pub stall_torque: f32,
    /// No-load speed at the supply voltage, rad/s.
    pub no_load_speed: f32,
    /// Supply voltage, V.
    pub supply_voltage: f32,
    /// Whether the model has a current sensor and current control (goal current, mode 0).
    pub current_control: bool,
    /// Model number reported at address 0.
    pub model_number: u16,
}

impl MotorSpec {
    /// Torque (and back-EMF) constant, N·m/A = V·s/rad.
    pub fn kt(&self) -> f32 {
        self.supply_voltage / self.no_load_speed
    }
    /// Winding resistance, Ω.
    pub fn resistance(&self) -> f32 {
        self.supply_voltage * self.kt() / self.stall_torque
    }
    /// Effort (N·m) that a present-current/load register value (address 126) stands for.
    pub fn effort_from_register(&self, raw: i16) -> f32 {
        if self.current_control {
            raw as f32 * units::AMP_PER_CURRENT_UNIT * self.kt()
        } else {
            raw as f32 / units::LOAD_FULL_SCALE * self.stall_torque
        }
    }
    /// Register value (address 126 units) for an effort, N·m.
    pub fn register_from_effort(&self, effort: f32) -> i16 {
        let v = if self.current_control {
            effort / self.kt() / units::AMP_PER_CURRENT_UNIT
        } else {
            effort / self.stall_torque * units::LOAD_FULL_SCALE
        };
        clamp_i16(v)
    }
    /// Goal-PWM value that produces `effort` (N·m) at joint speed `speed` (rad/s):
    /// `V = R·τ/Kt + Ke·ω`, saturated at the supply.
    pub fn pwm_for_effort(&self, effort: f32, speed: f32) -> i16 {
        clamp_i16(self.pwm_fraction_for_effort(effort, speed) * units::PWM_MAX)
    }
    /// PWM fraction in [−1, 1] that produces `effort` (N·m) at joint speed `speed` (rad/s).
    pub fn pwm_fraction_for_effort(&self, effort: f32, speed: f32) -> f32 {
        let v = self.resistance() * effort / self.kt() + self.kt() * speed;
        let f = (v / self.supply_voltage).clamp(-1.0, 1.0);
        if f.is_nan() {
            0.0
        } else {
            f
        }
    }
    /// Effort (N·m) that a PWM fraction `pwm` in [−1, 1] produces at joint speed `speed`
    /// (rad/s): the inverse of [`MotorSpec::pwm_fraction_for_effort`] below saturation.
    pub fn effort_for_pwm_fraction(&self, pwm: f32, speed: f32) -> f32 {
        (pwm * self.supply_voltage - self.kt() * speed) * self.kt() / self.resistance()
    }
}

fn clamp_i16(v: f32) -> i16 {
    if v.is_nan() {
        0
    } else {
        v.clamp(i16::MIN as f32, i16::MAX as f32) as i16
    }
}

impl ServoModel {
    /// Factory-default control gains (ROBOTIS e-manual) and motion profile (none).
    pub fn factory_gains(&self) -> ServoGains {
        let (pos_p, pos_i, pos_d, vel_p, vel_i) = match self {
            ServoModel::Xm430W350 => (800, 0, 0, 100, 1920),
            _ => (640, 0, 4000, 100, 1000),
        };
        ServoGains {
            pos_p,
            pos_i,
            pos_d,
            vel_p,
            vel_i,
            profile_velocity: 0,
            profile_acceleration: 0,
        }
    }

    /// Published data of the model (ROBOTIS e-manual).
    pub fn spec(&self) -> MotorSpec {
        match self {
            ServoModel::Xm430W350 => MotorSpec {
                stall_torque: 4.1,
                no_load_speed: 46.0 * core::f32::consts::TAU / 60.0,
                supply_voltage: 12.0,
                current_control: true,
                model_number: units::MODEL_XM430_W350,
            },
            ServoModel::Xl430W250 => MotorSpec {
                stall_torque: 1.5,
                no_load_speed: 61.0 * core::f32::consts::TAU / 60.0,
                supply_voltage: 12.0,
                current_control: false,
                model_number: units::MODEL_XL430_W250,
            },
        }
    }
}

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

    #[test]
    fn motor_constants_match_locobot_driver() {
        // The LoCoBot driver converts torque to XM430 goal current as N·m × 149.795.
        let units_per_nm = 1.0 / ServoModel::Xm430W350.spec().kt() / units::AMP_PER_CURRENT_UNIT;
        assert!(
            (units_per_nm - 149.795).abs() / 149.795 < 0.01,
            "{units_per_nm}"
        );
    }
}
