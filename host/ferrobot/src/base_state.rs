//! What the base remembers between calls: the commands its host-side laws sent, the wheel
//! log a calibration records, and the odometry geometry it set. Written by the hub as time
//! passes (the goals' commands, the telemetry's wheels), read by [`crate::Base`].

use ferrobot_protocol::Telemetry;

use crate::config::RobotConfig;
use crate::odometry_calibration::WheelGeometry;

/// What the base remembers between calls.
#[derive(Debug, Default)]
pub(crate) struct BaseState {
    /// Base commands sent by host-side laws: (time s, v m/s, ω rad/s).
    pub(crate) log: Vec<(f64, f64, f64)>,
    /// While recording: the wheel angles `[left, right]` (rad) of each telemetry frame the
    /// motions have seen, with the frame's firmware time (µs).
    pub(crate) wheel_log: Option<Vec<(u64, [f64; 2])>>,
    /// The geometry the firmware's odometry uses, when set (calibrated).
    pub(crate) odometry: Option<WheelGeometry>,
}

impl BaseState {
    /// The base state of a robot of `cfg`, before its odometry geometry is pushed.
    pub(crate) fn new(_cfg: &RobotConfig) -> Self {
        BaseState::default()
    }

    /// While a wheel log is kept, add the wheel angles of telemetry frame `t` unless it is the
    /// frame logged last.
    pub(crate) fn log_wheels(&mut self, t: &Telemetry) {
        if let Some(log) = &mut self.wheel_log {
            if log.last().map(|l| l.0) != Some(t.time_us) {
                log.push((t.time_us, [t.wheels.left as f64, t.wheels.right as f64]));
            }
        }
    }
}
