//! The hardware check: before anything moves, the devices of a stock robot's `[direct]`
//! section are found, every servo the description names is pinged and read, the base is
//! heard, and each finding is a row of a table that says what is wrong and how to fix it.
//! The host-run backends refuse to start while a row is a fault ([`Report::passed`]).
//!
//! The check talks on the same [`Wires`] the firmware then runs on, so it works on real
//! devices and on emulated ones (a virtual clock) alike.

use std::path::{Path, PathBuf};
use std::time::Duration;

use ferrobot_description::{BaseModel, RobotConfig, ServoModel};
use ferrobot_protocol::dxl::{self, addr, units, PacketDecoder};

use super::clock::Clock;
use super::device::{Device, LatencyTimer, OpenError};
use super::wires::{Wires, SERVO};

pub use super::check_report::{Problem, Report, Row, Severity};

/// How long a servo has to answer one packet (its return delay, USB both ways).
pub const REPLY_WINDOW: Duration = Duration::from_millis(20);

/// Longest wall time one exchange may take, whatever the clock: a virtual clock whose
/// conductor stopped granting time ends the check with an error instead of a hang.
pub const STALLED_CLOCK: Duration = Duration::from_secs(10);

/// How long the base has to be heard.
pub const BASE_WINDOW: Duration = Duration::from_millis(300);

/// Servo input voltage outside which a row is a fault, V (the X series' 10-14.8 V, ROBOTIS
/// e-manual, XM430-W350 specifications).
pub const VOLTAGE_RANGE: (f64, f64) = (10.0, 14.8);

/// Servo temperature above which a row is a warning, °C (the X series' limit is 80).
pub const HOT: u8 = 70;

/// Where the devices are, when not where the description says.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Devices {
    /// The servo bus's device (default: `[direct].servo.port`).
    pub servo: Option<PathBuf>,
    /// The base's device (default: `[direct].base.port`).
    pub base: Option<PathBuf>,
}

/// Find and open the devices of `cfg` (a row per device found or not); `None` for a device
/// that cannot be opened.
pub fn open_devices(cfg: &RobotConfig, at: &Devices) -> (Vec<Row>, Option<Device>, Option<Device>) {
    let mut rows = Vec::new();
    let Some(direct) = cfg.direct.as_ref() else {
        rows.push(Row::fault(
            "robot",
            &cfg.name,
            Problem::NoDirectSection(cfg.name.clone()),
        ));
        return (rows, None, None);
    };
    let servo = open_one(&mut rows, "servo bus", &direct.servo, at.servo.as_deref());
    let base = direct
        .base
        .as_ref()
        .and_then(|b| open_one(&mut rows, "base", b, at.base.as_deref()));
    (rows, servo, base)
}

fn open_one(
    rows: &mut Vec<Row>,
    what: &'static str,
    spec: &ferrobot_description::DeviceSection,
    at: Option<&Path>,
) -> Option<Device> {
    let path = at
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from(&spec.port));
    match Device::open(&path, spec.baud) {
        Ok(d) => {
            let shown = path.display();
            rows.push(match d.latency {
                Some(LatencyTimer::Unwritable(ms)) => Row::warning(
                    what,
                    &format!("{shown}, FTDI latency timer {ms} ms"),
                    Problem::LatencyTimer {
                        path: path.clone(),
                        ms,
                    },
                ),
                Some(LatencyTimer::Set(ms)) => {
                    Row::ok(what, &format!("{shown}, FTDI latency timer {ms} ms"))
                }
                _ => Row::ok(what, &format!("{shown} (no FTDI latency timer)")),
            });
            Some(d)
        }
        Err(OpenError::Missing(p)) => {
            // The adapter may be there without its udev link.
            let found = spec.usb_ids().and_then(|(v, pid)| find_usb_serial(v, pid));
            let problem = match found {
                Some(dev) => Problem::UdevLinkMissing {
                    link: p,
                    device: dev,
                },
                None if what == "base" => Problem::NoBase(p),
                None => Problem::DeviceMissing { what, path: p },
            };
            rows.push(Row::fault(what, "missing", problem));
            None
        }
        Err(OpenError::Permission(p)) => {
            rows.push(Row::fault(what, "no access", Problem::Permission(p)));
            None
        }
        Err(OpenError::Other(p, why)) => {
            rows.push(Row::fault(what, &why, Problem::DeviceBusy(p, why.clone())));
            None
        }
    }
}

/// The tty device (`/dev/ttyUSB0`) of a USB serial adapter with these IDs, if one is plugged.
pub fn find_usb_serial(vendor: u16, product: u16) -> Option<PathBuf> {
    let dir = std::fs::read_dir("/sys/bus/usb-serial/devices").ok()?;
    for entry in dir.flatten() {
        // …/ttyUSB0 -> …/usb1/1-1/1-1:1.0/ttyUSB0: the USB device is two levels up.
        let Ok(real) = std::fs::canonicalize(entry.path()) else {
            continue;
        };
        let Some(usb) = real.parent().and_then(Path::parent) else {
            continue;
        };
        let id = |f: &str| {
            std::fs::read_to_string(usb.join(f))
                .ok()
                .and_then(|s| u16::from_str_radix(s.trim(), 16).ok())
        };
        if id("idVendor") == Some(vendor) && id("idProduct") == Some(product) {
            return Some(Path::new("/dev").join(entry.file_name()));
        }
    }
    None
}

/// Send `packet` on line `line` and gather the answer until `complete` says it is whole or
/// `window` (of the wires' clock) has passed.
pub fn exchange(
    wires: &mut Wires,
    line: usize,
    packet: &[u8],
    window: Duration,
    mut complete: impl FnMut(&[u8]) -> bool,
) -> Result<Vec<u8>, String> {
    let _ = wires.take(line);
    wires.send(line, packet);
    let deadline = wires.now_us() + window.as_micros() as u64;
    let started = std::time::Instant::now();
    let mut got = Vec::new();
    loop {
        got.extend(wires.take(line));
        // The other line's bytes are not this exchange's: taken and dropped, so that a virtual
        // clock sees every released byte consumed (a Kobuki talks unasked).
        let _ = wires.take(1 - line);
        let now = wires.now_us();
        if complete(&got) || now >= deadline {
            return Ok(got);
        }
        if started.elapsed() > STALLED_CLOCK {
            return Err(format!(
                "the clock stood still for {STALLED_CLOCK:?} at {now} us: are the emulated \
                 devices' plants running?"
            ));
        }
        wires.idle_until(deadline);
        let wait = match wires.clock {
            Clock::Wall(_) => Duration::from_micros(deadline - now),
            Clock::Virtual(_) => Duration::from_millis(10),
        };
        wires.wait(wait.min(Duration::from_millis(10)), &[])?;
    }
}

/// The status packet from servo `id` in `bytes`, if a whole one is there: its error byte and
/// parameters.
fn status_from(bytes: &[u8], id: u8) -> Option<(u8, Vec<u8>)> {
    let mut d = PacketDecoder::<256>::new();
    for &b in bytes {
        if let Some(Ok(p)) = d.push(b) {
            if p.is_status() && p.id == id {
                return Some((p.error(), p.data().to_vec()));
            }
        }
    }
    None
}

/// Ask servo `id` with the packet `build` makes; its status's error and data.
fn ask(
    wires: &mut Wires,
    id: u8,
    build: impl FnOnce(&mut [u8]) -> Result<usize, dxl::DxlError>,
) -> Result<Option<(u8, Vec<u8>)>, String> {
    let mut buf = [0u8; 64];
    let n = build(&mut buf).map_err(|e| format!("{e:?}"))?;
    let got = exchange(wires, SERVO, &buf[..n], REPLY_WINDOW, |b| {
        status_from(b, id).is_some()
    })?;
    Ok(status_from(&got, id))
}

/// Whether any of `ids` answers a ping at the device's current rate.
fn any_answers(wires: &mut Wires, ids: &[u8]) -> Result<bool, String> {
    for &id in ids {
        if ask(wires, id, |b| dxl::ping(b, id))?.is_some() {
            return Ok(true);
        }
    }
    Ok(false)
}

/// The rate the servos answer at, when it is not `expected`: every rate of the X series'
/// table ([`dxl::BAUD_RATES`]) tried, the device set back to `expected` after.
pub fn scan_baud(wires: &mut Wires, ids: &[u8], expected: u32) -> Result<Option<u32>, String> {
    let mut found = None;
    for baud in dxl::BAUD_RATES.into_iter().filter(|b| *b != expected) {
        if wires.servo.set_baud(baud) && any_answers(wires, ids)? {
            found = Some(baud);
            break;
        }
    }
    wires.servo.set_baud(expected);
    Ok(found)
}

/// The model number the description's `model` has.
pub fn model_number(model: ServoModel) -> u16 {
    match model {
        ServoModel::Xm430W350 => units::MODEL_XM430_W350,
        ServoModel::Xl430W250 => units::MODEL_XL430_W250,
    }
}

/// Check the servos of `cfg` on `wires`: a row each, or one row for a bus where none answers.
pub fn check_servos(wires: &mut Wires, cfg: &RobotConfig) -> Result<Vec<Row>, String> {
    let servos: Vec<(u8, ServoModel, String)> = cfg
        .joints
        .iter()
        .flat_map(|j| {
            let twin = j
                .twin_id
                .map(|t| (t, j.model, format!("{} (twin)", j.name)));
            std::iter::once((j.servo_id, j.model, j.name.clone())).chain(twin)
        })
        .collect();
    let ids: Vec<u8> = servos.iter().map(|s| s.0).collect();
    let expected = wires.servo.baud;
    if !any_answers(wires, &ids)? {
        let problem = match scan_baud(wires, &ids, expected)? {
            Some(found) => Problem::WrongBaud { found, expected },
            None => Problem::BusSilent(wires.servo.path.clone()),
        };
        return Ok(vec![Row::fault("servo bus", "no servo answers", problem)]);
    }
    let mut rows = Vec::new();
    for (id, model, joint) in servos {
        rows.push(check_servo(wires, id, model, &joint, expected)?);
    }
    Ok(rows)
}

/// One servo's row: ping (model, firmware), then its settings and its state.
fn check_servo(
    wires: &mut Wires,
    id: u8,
    model: ServoModel,
    joint: &str,
    baud: u32,
) -> Result<Row, String> {
    let subject = format!("servo {id} ({joint})");
    let Some((_, ping)) = ask(wires, id, |b| dxl::ping(b, id))? else {
        return Ok(Row::fault(&subject, "no answer", Problem::ServoMissing(id)));
    };
    let found = dxl::le_u16(&ping, 0);
    let firmware = ping.get(2).copied().unwrap_or(0);
    let settings = ask(wires, id, |b| dxl::read(b, id, addr::BAUD_RATE, 4))?;
    let state = ask(wires, id, |b| {
        dxl::read(b, id, addr::PRESENT_INPUT_VOLTAGE, 3)
    })?;
    let (Some((_, settings)), Some((hw, state))) = (settings, state) else {
        return Ok(Row::fault(
            &subject,
            "pings, but does not read",
            Problem::ServoMissing(id),
        ));
    };
    let code = settings.first().copied().unwrap_or(u8::MAX);
    let mode = settings.get(3).copied().unwrap_or(u8::MAX);
    let volts = f64::from(dxl::le_u16(&state, 0)) * 0.1;
    let celsius = state.get(2).copied().unwrap_or(0);
    let reading = format!(
        "model {found}, firmware {firmware}, baud code {code}, mode {mode}, {volts:.1} V, \
         {celsius} °C"
    );
    let expected = model_number(model);
    let problem = if found != expected {
        Some(Problem::WrongModel {
            id,
            found,
            expected,
        })
    } else if hw & dxl::status_error::ALERT != 0 {
        Some(Problem::HardwareAlert(id))
    } else if !(VOLTAGE_RANGE.0..=VOLTAGE_RANGE.1).contains(&volts) {
        Some(Problem::Voltage { id, volts })
    } else {
        None
    };
    Ok(match problem {
        Some(p) => Row::fault(&subject, &reading, p),
        None if celsius >= HOT => Row::warning(&subject, &reading, Problem::Hot { id, celsius }),
        None if dxl::baud_code(baud) != Some(code) => {
            Row::warning(&subject, &reading, Problem::BaudRegister { id, code, baud })
        }
        None => Row::ok(&subject, &reading),
    })
}

/// Hear the base: a Kobuki streams its feedback unasked; a Create 2 is started, asked for a
/// stream of its sensors, and stopped again.
pub fn check_base(wires: &mut Wires, model: BaseModel) -> Result<Row, String> {
    match model {
        BaseModel::Kobuki => super::check_base::kobuki(wires),
        BaseModel::Create2 => super::check_base::create2(wires),
    }
}

/// The whole check of `cfg` on `wires` (devices already opened: `rows` are their rows).
pub fn run(wires: &mut Wires, cfg: &RobotConfig, mut rows: Vec<Row>) -> Result<Report, String> {
    rows.extend(check_servos(wires, cfg)?);
    if let (Some(b), true) = (cfg.base.as_ref(), wires.base.is_some()) {
        rows.push(check_base(wires, b.kind)?);
    }
    Ok(Report {
        robot: cfg.name.clone(),
        rows,
    })
}
