//! What the host hears besides answers: a fault report as each fault happens (to an accepted
//! session only), the fixed-size telemetry frame every telemetry period (joint states in SI
//! units, the odometry pose in the odometry frame, fault flags, loop timing) and the link
//! and bus counters on request.

use ferrobot_protocol::{
    fault_flags, DeviceMsg, Diagnostics, Fault, FaultKind, GripperState, Telemetry,
};

use crate::base::BaseEvent;
use crate::bus::ServoStatus;
use crate::log::{self, log_warn};
use crate::session::Session;
use crate::time::{Duration, Instant};
use crate::Firmware;

impl Firmware {
    /// Report a fault: logged always, sent to the host in an accepted session.
    pub(crate) fn fault(
        &mut self,
        now: Instant,
        kind: FaultKind,
        joint: Option<u8>,
        servo_id: Option<u8>,
        code: u16,
    ) {
        log_warn!(
            "fault {=istr}: joint {=u8}, servo {=u8}, code {=u16}",
            log::fault_name(kind),
            joint.unwrap_or(u8::MAX),
            servo_id.unwrap_or(u8::MAX),
            code
        );
        if self.session == Session::Accepted {
            self.send(&DeviceMsg::Fault(Fault {
                kind,
                joint,
                servo_id,
                code,
                time_us: now.as_micros(),
            }));
        }
    }

    /// Report the base's safety sensors, and its feedback lost or back.
    pub(crate) fn drain_base_events(&mut self, now: Instant) {
        use ferrobot_protocol::base_flags as bf;
        while let Some(e) = self.base.pop_event() {
            match e {
                BaseEvent::Safety(bits) => {
                    let groups = [
                        (bits & bf::ANY_BUMPER, FaultKind::Bumper),
                        (bits & bf::ANY_CLIFF, FaultKind::Cliff),
                        (bits & bf::ANY_WHEEL_DROP, FaultKind::WheelDrop),
                    ];
                    for (b, kind) in groups {
                        if b != 0 {
                            self.fault(now, kind, None, None, b);
                        }
                    }
                }
                BaseEvent::Lost => self.fault(now, FaultKind::BaseLost, None, None, 0),
                BaseEvent::Recovered => self.fault(now, FaultKind::BaseRecovered, None, None, 0),
            }
        }
    }

    /// Send telemetry every `period` from `now` on (never when it is zero).
    pub(crate) fn set_telemetry(&mut self, now: Instant, period: Duration) {
        self.telemetry_period = period;
        self.next_telemetry = if period.is_zero() {
            Instant::MAX
        } else {
            now + period
        };
    }

    /// The [`fault_flags`] as of now.
    fn faults(&self) -> u16 {
        let mut f = 0;
        if self.estop {
            f |= fault_flags::ESTOP;
        }
        if self.watchdog_tripped {
            f |= fault_flags::WATCHDOG;
        }
        if self.lost_servos != 0 {
            f |= fault_flags::SERVO_LOST;
        }
        if self.bus.servos.iter().any(|s| s.hw_error != 0) {
            f |= fault_flags::SERVO_HARDWARE;
        }
        if self
            .bus
            .servos
            .iter()
            .any(|s| s.status == ServoStatus::Configuring)
        {
            f |= fault_flags::CONFIGURING;
        }
        if self.base.present() && self.base.lost {
            f |= fault_flags::BASE_LOST;
        }
        if self.base.flags != 0 {
            f |= fault_flags::BASE_SAFETY;
        }
        if self.overrun_since_telemetry {
            f |= fault_flags::OVERRUN;
        }
        if self.dynamics.trusted() {
            f |= fault_flags::ARM_MODEL;
        }
        f
    }

    /// The telemetry frame as of now.
    pub fn telemetry(&self, now: Instant) -> Telemetry {
        Telemetry {
            time_us: now.as_micros(),
            joints: self.joints.iter().map(|j| j.state).collect(),
            queued: self
                .joints
                .iter()
                .map(|j| j.queued())
                .sum::<usize>()
                .min(255) as u8,
            gripper: self
                .gripper
                .as_ref()
                .map(|(_, g)| g.state)
                .unwrap_or(GripperState::Absent),
            odometry: self.base.odom.pose,
            wheels: self.base.wheels,
            base_flags: self.base.flags,
            faults: self.faults(),
            loop_stats: self.loop_stats,
        }
    }

    /// Send the telemetry frame as of `now`.
    pub(crate) fn send_telemetry(&mut self, now: Instant) {
        let t = self.telemetry(now);
        self.overrun_since_telemetry = false;
        self.send(&DeviceMsg::Telemetry(t));
    }

    /// Link and bus counters.
    pub fn diagnostics(&self) -> Diagnostics {
        let f = self.decoder.stats();
        Diagnostics {
            host_frames: f.ok,
            host_bad_frames: f.dropped(),
            host_tx_dropped: self.host_tx_dropped,
            servo_packets: self.bus.stats.packets,
            servo_bad_packets: self.bus.stats.bad_packets,
            servo_timeouts: self.bus.stats.timeouts,
            servo_alerts: self.bus.stats.alerts,
            servo_stale: self.bus.stats.stale,
            base_packets: self.base.stats.packets,
            base_bad_packets: self.base.stats.bad_packets,
        }
    }
}
