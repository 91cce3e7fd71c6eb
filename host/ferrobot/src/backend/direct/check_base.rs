//! The hardware check of a base: a Kobuki streams its feedback unasked (basic sensor data at
//! 50 Hz: bumpers, wheel drops, cliffs, battery); a Create 2 is started, asked to stream its
//! sensors, and its Open Interface stopped again (Stop, 173) so the check leaves it as found.

use ferrobot_protocol::create2::{self, StreamParser};
use ferrobot_protocol::kobuki::{self, BasicSensorData, Parser};

use super::check::{exchange, BASE_WINDOW};
use super::check_report::{Problem, Row};
use super::wires::{Wires, BASE};

/// Kobuki battery voltage below which the check warns, V (Kobuki's "low" level; the driver
/// reports 0.1 V units).
pub const KOBUKI_LOW_BATTERY: f64 = 13.2;

/// The base's device path, as the rows name it.
fn base_path(wires: &Wires) -> std::path::PathBuf {
    wires
        .base
        .as_ref()
        .map(|d| d.path.clone())
        .unwrap_or_default()
}

/// The first basic sensor data in `bytes`.
fn kobuki_sensors(bytes: &[u8]) -> Option<BasicSensorData> {
    let mut p = Parser::new();
    for &b in bytes {
        if let Some(Ok(payload)) = p.push(b) {
            for (id, d) in kobuki::sub_payloads(payload) {
                if id == kobuki::FB_BASIC_SENSOR_DATA {
                    if let Some(s) = BasicSensorData::from_bytes(d) {
                        return Some(s);
                    }
                }
            }
        }
    }
    None
}

/// A Kobuki: heard within [`BASE_WINDOW`], its battery and bumpers read.
pub fn kobuki(wires: &mut Wires) -> Result<Row, String> {
    let got = exchange(wires, BASE, &[], BASE_WINDOW, |b| {
        kobuki_sensors(b).is_some()
    })?;
    let Some(s) = kobuki_sensors(&got) else {
        return Ok(Row::fault(
            "base (Kobuki)",
            "silent",
            Problem::BaseSilent(base_path(wires)),
        ));
    };
    let volts = f64::from(s.battery) * 0.1;
    let reading = format!(
        "battery {volts:.1} V, bumper {:#04x}, wheel drop {:#04x}, cliff {:#04x}",
        s.bumper, s.wheel_drop, s.cliff
    );
    Ok(if volts < KOBUKI_LOW_BATTERY {
        Row::warning("base (Kobuki)", &reading, Problem::BatteryLow(volts))
    } else {
        Row::ok("base (Kobuki)", &reading)
    })
}

/// A Create 2: Start (passive mode), a stream of the firmware's sensor packets, then the
/// stream paused and the Open Interface stopped.
pub fn create2(wires: &mut Wires) -> Result<Row, String> {
    let mut ask = vec![
        create2::OP_START,
        create2::OP_STREAM,
        create2::STREAM_IDS.len() as u8,
    ];
    ask.extend_from_slice(&create2::STREAM_IDS);
    let heard = |bytes: &[u8]| {
        let mut p = StreamParser::new();
        bytes.iter().find_map(|&b| p.push(b).and_then(Result::ok))
    };
    let got = exchange(wires, BASE, &ask, BASE_WINDOW, |b| heard(b).is_some())?;
    wires.send(BASE, &[create2::OP_PAUSE_RESUME, 0, create2::OP_STOP]);
    Ok(match heard(&got) {
        Some(s) => Row::ok(
            "base (Create 2)",
            &format!(
                "bumps and wheel drops {:#04x}, cliffs {:?}, encoders {} {}",
                s.bumps_drops, s.cliffs, s.left_encoder, s.right_encoder
            ),
        ),
        None => Row::fault(
            "base (Create 2)",
            "silent",
            Problem::BaseSilent(base_path(wires)),
        ),
    })
}
