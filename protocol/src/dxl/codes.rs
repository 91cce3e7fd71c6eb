//! The numbers of Protocol 2.0 and the X series: instruction codes, the status error byte,
//! Hardware Error Status bits, control-table addresses (with their sizes) and operating modes.

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

/// Line rates of the X series' Baud Rate register (address 8), by code, bit/s (ROBOTIS
/// e-manual, XM430-W350 control table).
pub const BAUD_RATES: [u32; 8] = [
    9600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000,
];

/// The Baud Rate register's code of `baud` bit/s, or `None` for a rate it cannot be set to.
pub fn baud_code(baud: u32) -> Option<u8> {
    BAUD_RATES.iter().position(|&b| b == baud).map(|i| i as u8)
}
