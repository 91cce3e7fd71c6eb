//! `[direct]`: a stock robot's own USB cables, for the host-run firmware (`Backend::Direct`).
//! A stock LoCoBot has no controller board: its computer drives the Dynamixel bus through a
//! U2D2 and the base through the base's own cable, so the firmware core runs on the host and
//! its servo bus and base lines are serial devices. This section says where they are and how
//! fast they run; `[bus]` stays the controller board's.

use serde::Deserialize;

use crate::sections::BusSection;

/// `[direct]` as written.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectSection {
    /// The servo bus's adapter (a U2D2).
    pub servo: DeviceSection,
    /// The base's cable, if the robot has a base.
    pub base: Option<DeviceSection>,
    /// Servo-loop period on the host, µs: a USB round trip costs about 1 ms each way, so the
    /// loop runs slower than a board's.
    pub loop_period_us: u32,
    /// Slack added to every servo reply's timeout for the USB round trip, µs (the FTDI latency
    /// timer at 1 ms, one USB frame each way, the servo's return delay).
    pub reply_margin_us: u32,
}

/// One serial device of `[direct]`: how to find it and its line rate.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceSection {
    /// The path a udev rule gives it (`/dev/ttyUSB_dyna`), or any device path.
    pub port: String,
    /// The adapter's USB vendor and product IDs, `"vvvv:pppp"` in hex (`"0403:6014"`): how the
    /// hardware check finds the device when the udev link is missing.
    pub usb: Option<String>,
    /// Line rate, bit/s.
    pub baud: u32,
}

impl DeviceSection {
    /// The USB vendor and product IDs, if given and well formed.
    pub fn usb_ids(&self) -> Option<(u16, u16)> {
        let (v, p) = self.usb.as_deref()?.split_once(':')?;
        Some((
            u16::from_str_radix(v, 16).ok()?,
            u16::from_str_radix(p, 16).ok()?,
        ))
    }
}

impl DirectSection {
    /// The servo bus as the host-run firmware runs it: the adapter's rate and the host's loop.
    pub fn bus(&self) -> BusSection {
        BusSection {
            baud: self.servo.baud,
            loop_period_us: self.loop_period_us,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ConfigSource, RobotConfig};

    /// The LoCoBot with `key` set to `value`: the error's text, if refused.
    fn refused(key: &str, value: toml::Value) -> Option<String> {
        let source = ConfigSource::Bundled("locobot".into());
        RobotConfig::load(&source, &[(key.to_string(), value)])
            .err()
            .map(|e| e.to_string())
    }

    #[test]
    fn a_direct_section_out_of_its_ranges_is_refused_naming_the_key() {
        use toml::Value::{Integer, String as S};
        for (key, value) in [
            ("direct.servo.baud", Integer(0)),
            ("direct.servo.baud", Integer(-1)),
            ("direct.servo.baud", Integer(100_000_000)),
            ("direct.base.baud", Integer(12)),
            ("direct.servo.usb", S("zz:6014".into())),
            ("direct.base.usb", S("0403".into())),
            ("direct.reply_margin_us", Integer(1_000_000)),
            ("direct.servo.port", Integer(3)),
            ("direct.servo.colour", S("red".into())),
        ] {
            let why = refused(key, value.clone()).unwrap_or_else(|| panic!("{key} = {value}"));
            let field = key.rsplit('.').next().unwrap_or(key);
            assert!(why.contains(field), "{key} = {value}: {why}");
        }
        let lite = ConfigSource::Bundled("locobot_lite".into());
        let no_base = [(
            "direct.base".to_string(),
            toml::Value::Table(Default::default()),
        )];
        assert!(RobotConfig::load(&lite, &no_base).is_err());
    }

    #[test]
    fn the_bundled_locobots_run_their_bus_at_1_mbit_on_their_own_cables() {
        for robot in ["locobot", "locobot_lite"] {
            let cfg = RobotConfig::bundled(robot).expect("bundled");
            let direct = cfg.direct_config().expect("a [direct] section");
            assert_eq!(direct.bus.baud, 1_000_000);
            assert_eq!(cfg.bus.baud, 4_000_000, "a board's bus stays as [bus] says");
        }
        assert!(RobotConfig::bundled("sawyer")
            .expect("sawyer")
            .direct
            .is_none());
    }

    #[test]
    fn usb_ids_are_read_in_hex_and_refused_when_malformed() {
        let mut d = DeviceSection {
            port: "/dev/ttyUSB_dyna".into(),
            usb: Some("0403:6014".into()),
            baud: 1_000_000,
        };
        assert_eq!(d.usb_ids(), Some((0x0403, 0x6014)));
        for bad in ["0403", "0403:", "xyz:6014", "0403:60144"] {
            d.usb = Some(bad.into());
            assert_eq!(d.usb_ids(), None, "{bad}");
        }
    }
}
