//! The hardware check's findings: a row per device, servo and base, each with what is wrong
//! and how to fix it, and the table `ferrobot hardware check` prints.

use std::fmt;
use std::path::PathBuf;

use serde::Serialize;

/// How bad a row is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Severity {
    /// As the description says.
    Ok,
    /// Runs, but worth fixing.
    Warning,
    /// Nothing moves until it is fixed.
    Fault,
}

/// What is wrong, with what the fix needs.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub enum Problem {
    /// The robot has no `[direct]` section: no stock cables to check.
    NoDirectSection(String),
    /// No device at the path, and no adapter with the section's USB IDs either.
    DeviceMissing {
        /// Which device.
        what: &'static str,
        /// Where it was looked for.
        path: PathBuf,
    },
    /// The adapter is plugged in, but its udev link is missing.
    UdevLinkMissing {
        /// The link the description names.
        link: PathBuf,
        /// Where the adapter is.
        device: PathBuf,
    },
    /// This user may not open the device.
    Permission(PathBuf),
    /// The device would not open for another reason (another program has it).
    DeviceBusy(PathBuf, String),
    /// No servo answers at any rate.
    BusSilent(PathBuf),
    /// The servos answer at another rate than the description's.
    WrongBaud {
        /// Where they answer, bit/s.
        found: u32,
        /// The description's, bit/s.
        expected: u32,
    },
    /// A servo the description names does not answer.
    ServoMissing(u8),
    /// A servo of another model than the description's.
    WrongModel {
        /// Its ID.
        id: u8,
        /// The model number it reports.
        found: u16,
        /// The description's.
        expected: u16,
    },
    /// A servo reports a hardware error (its alert bit).
    HardwareAlert(u8),
    /// A servo's input voltage is outside its range.
    Voltage {
        /// Its ID.
        id: u8,
        /// Its input voltage, V.
        volts: f64,
    },
    /// A servo runs hot.
    Hot {
        /// Its ID.
        id: u8,
        /// Its temperature, °C.
        celsius: u8,
    },
    /// The adapter's FTDI latency timer could not be lowered: every reply may wait that long.
    LatencyTimer {
        /// The device.
        path: PathBuf,
        /// The timer, ms.
        ms: u32,
    },
    /// A servo's Baud Rate register disagrees with the rate it answers at.
    BaudRegister {
        /// Its ID.
        id: u8,
        /// The register's code.
        code: u8,
        /// The bus's rate, bit/s.
        baud: u32,
    },
    /// No base at the path.
    NoBase(PathBuf),
    /// The base's device opens, but the base says nothing.
    BaseSilent(PathBuf),
    /// The base's battery is low, V.
    BatteryLow(f64),
}

impl fmt::Display for Problem {
    /// What is wrong and how to fix it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.device_fix() {
            Some(text) => f.write_str(&text),
            None => f.write_str(&self.servo_or_base_fix()),
        }
    }
}

impl Problem {
    /// The text of a device's problem.
    fn device_fix(&self) -> Option<String> {
        use Problem::*;
        Some(match self {
            NoDirectSection(r) => format!("{r} has no [direct] section: it runs on a board"),
            DeviceMissing { what, path } => format!(
                "no {what} at {}: plug its USB cable in, or name the device (--servo/--base)",
                path.display()
            ),
            UdevLinkMissing { link, device } => format!(
                "the adapter is at {} but {} is missing: install the udev rules \
                 (sudo cp scripts/udev/99-ferrobot.rules /etc/udev/rules.d/ && sudo udevadm \
                 control --reload && sudo udevadm trigger) or pass the device",
                device.display(),
                link.display()
            ),
            Permission(p) => format!(
                "no permission to open {}: sudo usermod -aG dialout $USER, then log in again \
                 (or install scripts/udev/99-ferrobot.rules)",
                p.display()
            ),
            DeviceBusy(p, why) => format!(
                "{} will not open ({why}): is another program (a ROS driver, a terminal) using it?",
                p.display()
            ),
            LatencyTimer { path, ms } => format!(
                "{}'s FTDI latency timer stays at {ms} ms (this user may not write it): every \
                 servo reply can wait {ms} ms and the loop overruns; install \
                 scripts/udev/99-ferrobot.rules, which sets it to 1 ms",
                path.display()
            ),
            _ => return None,
        })
    }

    /// The text of a servo's or the base's problem.
    fn servo_or_base_fix(&self) -> String {
        use Problem::*;
        match self {
            BusSilent(p) => format!(
                "no servo answers on {} at any rate: check the servos' power (12 V) and the \
                 cable from the U2D2",
                p.display()
            ),
            WrongBaud { found, expected } => format!(
                "the servos answer at {found} bit/s, the description says {expected}: set \
                 them to {expected} with ROBOTIS' Dynamixel Wizard, or set [direct].servo.baud"
            ),
            ServoMissing(id) => {
                format!("servo {id} does not answer: check its cable and ID (Dynamixel Wizard)")
            }
            WrongModel {
                id,
                found,
                expected,
            } => format!(
                "servo {id} is model {found}, the description says {expected}: fix the \
                 joint's servo.model or the wiring"
            ),
            HardwareAlert(id) => {
                format!("servo {id} reports a hardware error: power-cycle it, and look at its load")
            }
            Voltage { id, volts } => {
                format!("servo {id} sees {volts:.1} V (10-14.8 V): check the power supply")
            }
            Hot { id, celsius } => format!("servo {id} is at {celsius} °C: let it cool"),
            BaudRegister { id, code, baud } => {
                format!("servo {id}'s Baud Rate register is {code}, not the code of {baud} bit/s")
            }
            NoBase(p) => format!(
                "no base at {}: plug the base's USB cable in and switch the base on",
                p.display()
            ),
            BaseSilent(p) => format!(
                "the base's cable is at {} but the base says nothing: switch the base on",
                p.display()
            ),
            BatteryLow(v) => format!("the base's battery is at {v:.1} V: charge it"),
            other => format!("{other:?}"),
        }
    }
}

/// One finding.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    /// What was checked: a device, a servo, the base.
    pub subject: String,
    /// What was read.
    pub reading: String,
    /// How bad it is.
    pub severity: Severity,
    /// What is wrong, if anything.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub problem: Option<Problem>,
}

impl Row {
    /// A row as it should be.
    pub fn ok(subject: &str, reading: &str) -> Row {
        Self::new(subject, reading, Severity::Ok, None)
    }

    /// A row worth fixing.
    pub fn warning(subject: &str, reading: &str, p: Problem) -> Row {
        Self::new(subject, reading, Severity::Warning, Some(p))
    }

    /// A row that stops the robot from moving.
    pub fn fault(subject: &str, reading: &str, p: Problem) -> Row {
        Self::new(subject, reading, Severity::Fault, Some(p))
    }

    fn new(subject: &str, reading: &str, severity: Severity, problem: Option<Problem>) -> Row {
        Row {
            subject: subject.into(),
            reading: reading.into(),
            severity,
            problem,
        }
    }
}

/// The check of one robot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// The robot's name.
    pub robot: String,
    /// The findings, devices first.
    pub rows: Vec<Row>,
}

impl Report {
    /// The error that refuses the robot when the check failed: each fault with its subject and
    /// fix, and the table.
    pub fn error(&self) -> crate::Error {
        crate::Error::HardwareCheck {
            faults: self
                .rows
                .iter()
                .filter(|r| r.severity == Severity::Fault)
                .map(|r| match &r.problem {
                    Some(p) => format!("{}: {p}", r.subject),
                    None => r.subject.clone(),
                })
                .collect(),
            table: self.to_string(),
        }
    }

    /// Whether no row is a fault: the robot may move.
    pub fn passed(&self) -> bool {
        self.rows.iter().all(|r| r.severity != Severity::Fault)
    }
}

impl fmt::Display for Report {
    /// The table: subject, status, reading; then each problem with its fix.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let w = self.rows.iter().map(|r| r.subject.len()).max().unwrap_or(0);
        writeln!(f, "hardware check of {}", self.robot)?;
        for r in &self.rows {
            let status = match r.severity {
                Severity::Ok => "ok",
                Severity::Warning => "WARN",
                Severity::Fault => "FAULT",
            };
            writeln!(f, "  {:w$}  {status:5}  {}", r.subject, r.reading)?;
        }
        for r in self.rows.iter().filter(|r| r.problem.is_some()) {
            if let Some(p) = &r.problem {
                writeln!(f, "  - {}: {p}", r.subject)?;
            }
        }
        let verdict = if self.passed() {
            "passed: the robot may move"
        } else {
            "FAILED: nothing moves until the faults are fixed"
        };
        write!(f, "{verdict}")
    }
}
