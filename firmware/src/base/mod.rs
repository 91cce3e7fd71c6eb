//! Mobile-base driver: Kobuki serial protocol or Create 2 Open Interface behind one interface.
//!
//! It sends the commanded body velocity every feedback period (and at once when it changes),
//! parses feedback, integrates odometry from encoder ticks (wrap-around handled), reports
//! bumper, cliff and wheel-drop, and stops the base by itself when a safety sensor fires, a
//! command's duration runs out, or the base goes silent.

pub mod odometry;

use ferrobot_protocol::{base_flags, create2, kobuki, BaseKind, RejectReason, WheelData};
use heapless::{Deque, Vec};

use crate::config::BaseConfig;
use crate::time::{Duration, Instant};
use crate::txbuf::TxBuf;
use odometry::OdometryIntegrator;

/// Kobuki's feedback period (50 Hz), at which the driver also repeats its command.
const KOBUKI_PERIOD: Duration = Duration::from_millis(20);
/// How often a silent Create 2 is sent Start, Safe and the stream request again.
const CREATE2_RESTART: Duration = Duration::from_millis(500);

/// Events the firmware reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseEvent {
    /// Safety bits newly set ([`base_flags`]).
    Safety(u16),
    /// No feedback within the timeout.
    Lost,
    /// Feedback again.
    Recovered,
}

enum Proto {
    None,
    Kobuki(kobuki::Parser),
    Create2 {
        parser: create2::StreamParser,
        next_start: Instant,
    },
}

/// Base counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BaseStats {
    /// Feedback packets.
    pub packets: u32,
    /// Dropped packets.
    pub bad_packets: u32,
}

/// The base driver.
pub struct BaseDriver {
    /// Geometry.
    pub cfg: BaseConfig,
    proto: Proto,
    /// Odometry.
    pub odom: OdometryIntegrator,
    /// Wheel data.
    pub wheels: WheelData,
    /// Current [`base_flags`].
    pub flags: u16,
    cmd: (f32, f32),
    cmd_until: Instant,
    sent: Option<(f32, f32)>,
    next_send: Instant,
    last_enc: Option<(i32, i32)>,
    /// The previous gyro heading, rad (Kobuki).
    last_gyro: Option<f32>,
    last_rx: Option<Instant>,
    /// Whether feedback is missing.
    pub lost: bool,
    /// Odometry geometry: left and right wheel radius and wheel separation, m (the nominal
    /// ones until [`BaseDriver::set_geometry`]).
    pub odom_geometry: (f32, f32, f32),
    tx: TxBuf<128>,
    /// When the last wheel command will have left the line. A newer command waits for
    /// it (the newest one wins), so that a burst of commands cannot queue up on the line
    /// ahead of a stop: a stop reaches the base within two packet times.
    line_free_at: Instant,
    events: Deque<BaseEvent, 8>,
    /// Counters.
    pub stats: BaseStats,
}

impl BaseDriver {
    /// A driver for `cfg`.
    pub fn new(cfg: BaseConfig) -> Self {
        let proto = match cfg.kind {
            BaseKind::Kobuki => Proto::Kobuki(kobuki::Parser::new()),
            BaseKind::Create2 => Proto::Create2 {
                parser: create2::StreamParser::new(),
                next_start: Instant::ZERO,
            },
            _ => Proto::None,
        };
        Self {
            cfg,
            proto,
            odom: OdometryIntegrator::default(),
            wheels: WheelData::default(),
            flags: 0,
            cmd: (0.0, 0.0),
            cmd_until: Instant::ZERO,
            sent: None,
            next_send: Instant::ZERO,
            last_enc: None,
            last_gyro: None,
            last_rx: None,
            lost: false,
            odom_geometry: (cfg.wheel_radius, cfg.wheel_radius, cfg.track),
            tx: TxBuf::new(),
            line_free_at: Instant::ZERO,
            events: Deque::new(),
            stats: BaseStats::default(),
        }
    }

    /// Use calibrated odometry geometry: left and right wheel radius and wheel separation, m.
    /// Each must be finite and within 10 % of the nominal value.
    pub fn set_geometry(&mut self, left: f32, right: f32, track: f32) -> Result<(), RejectReason> {
        if !self.present() {
            return Err(RejectReason::NoBase);
        }
        let near = |x: f32, nominal: f32| x.is_finite() && (x - nominal).abs() <= 0.1 * nominal;
        let r = self.cfg.wheel_radius;
        if !(near(left, r) && near(right, r) && near(track, self.cfg.track)) {
            return Err(RejectReason::InvalidConfig);
        }
        self.odom_geometry = (left, right, track);
        Ok(())
    }

    /// Whether there is a base.
    pub fn present(&self) -> bool {
        !matches!(self.proto, Proto::None)
    }

    /// The base's feedback period, at which the driver repeats its command.
    fn period(&self) -> Duration {
        match self.proto {
            Proto::Create2 { .. } => Duration::from_micros(create2::STREAM_PERIOD_US),
            _ => KOBUKI_PERIOD,
        }
    }

    /// Command a body velocity (`v` m/s, `w` rad/s) for `duration`. Refused (but a stop) while
    /// a safety sensor fires or the base's feedback is lost ([`RejectReason::BaseSafety`]).
    pub fn set_velocity(
        &mut self,
        now: Instant,
        v: f32,
        w: f32,
        duration: Duration,
    ) -> Result<(), RejectReason> {
        if !self.present() {
            return Err(RejectReason::NoBase);
        }
        if !v.is_finite() || !w.is_finite() {
            return Err(RejectReason::NotFinite);
        }
        if self.flags & (base_flags::ANY_CLIFF | base_flags::ANY_WHEEL_DROP) != 0
            && (v != 0.0 || w != 0.0)
        {
            return Err(RejectReason::BaseSafety);
        }
        if self.flags & base_flags::ANY_BUMPER != 0 && v > 0.0 {
            return Err(RejectReason::BaseSafety);
        }
        // A base gone silent has no safety sensors: it may only be stopped.
        if self.lost && (v != 0.0 || w != 0.0) {
            return Err(RejectReason::BaseSafety);
        }
        self.cmd = self.limit(v, w);
        self.cmd_until = now + duration;
        self.next_send = now.max(self.line_free_at); // as soon as the line is free
        Ok(())
    }

    /// Scale (v, w) so that neither wheel exceeds the base's top speed.
    fn limit(&self, v: f32, w: f32) -> (f32, f32) {
        let half = 0.5 * self.cfg.track;
        let peak = (v - w * half).abs().max((v + w * half).abs());
        if peak > self.cfg.max_wheel_speed && peak > 0.0 {
            let k = self.cfg.max_wheel_speed / peak;
            (v * k, w * k)
        } else {
            (v, w)
        }
    }

    /// Stop at once.
    pub fn stop(&mut self, now: Instant) {
        self.cmd = (0.0, 0.0);
        self.cmd_until = now;
        self.next_send = now.max(self.line_free_at);
    }

    /// The velocity currently commanded (v m/s, w rad/s).
    pub fn commanded(&self) -> (f32, f32) {
        self.cmd
    }

    /// Bytes waiting for the base.
    pub fn pending_tx(&self) -> &[u8] {
        self.tx.pending()
    }

    /// The shell sent the first `n` pending bytes.
    pub fn consume_tx(&mut self, n: usize) {
        self.tx.consume(n);
    }

    /// Take the next event.
    pub fn pop_event(&mut self) -> Option<BaseEvent> {
        self.events.pop_front()
    }

    /// When `poll` must run next.
    pub fn deadline(&self) -> Instant {
        let mut d = self.next_send;
        if self.cmd != (0.0, 0.0) {
            d = d.min(self.cmd_until);
        }
        if let Some(t) = self.last_rx {
            if !self.lost {
                d = d.min(t + self.cfg.feedback_timeout);
            }
        }
        if let Proto::Create2 { next_start, .. } = self.proto {
            if self.last_rx.is_none() || self.lost {
                d = d.min(next_start);
            }
        }
        d
    }

    /// Timers: command expiry, periodic send, loss of feedback.
    pub fn poll(&mut self, now: Instant) {
        if !self.present() {
            self.next_send = Instant::MAX;
            return;
        }
        if self.cmd != (0.0, 0.0) && now >= self.cmd_until {
            self.cmd = (0.0, 0.0);
            self.next_send = now;
        }
        if let Some(t) = self.last_rx {
            if !self.lost && now >= t + self.cfg.feedback_timeout {
                self.lost = true;
                let _ = self.events.push_back(BaseEvent::Lost);
                // Its bumper, cliff and wheel-drop sensors are no longer read: stop (the
                // command was once repeated until its duration ran out, up to a minute).
                if self.cmd != (0.0, 0.0) {
                    self.cmd = (0.0, 0.0);
                    self.next_send = now;
                }
            }
        }
        if let Proto::Create2 { next_start, .. } = &mut self.proto {
            if (self.last_rx.is_none() || self.lost) && now >= *next_start {
                *next_start = now + CREATE2_RESTART;
                let mut start: Vec<u8, 16> = Vec::new();
                let _ = start.extend_from_slice(&[
                    create2::OP_START,
                    create2::OP_SAFE,
                    create2::OP_STREAM,
                ]);
                let _ = start.push(create2::STREAM_IDS.len() as u8);
                let _ = start.extend_from_slice(&create2::STREAM_IDS);
                let _ = self.tx.push(&start);
            }
        }
        if now >= self.next_send {
            // A command that found no room is retried at the next poll.
            self.next_send = match self.send_command() {
                Some(n) => {
                    // 10 bits per byte on the line.
                    let baud = match self.proto {
                        Proto::Create2 { .. } => create2::BAUD,
                        _ => kobuki::BAUD,
                    };
                    let line = Duration::from_micros(
                        (n as u64)
                            .saturating_mul(10_000_000)
                            .checked_div(u64::from(baud))
                            .unwrap_or(0)
                            .saturating_add(1),
                    );
                    self.line_free_at = now.max(self.line_free_at) + line;
                    now + self.period()
                }
                None => now,
            };
        }
    }

    /// Queue the current command for the base; its length in bytes, or `None` when it does
    /// not fit (it is retried at the next poll).
    fn send_command(&mut self) -> Option<usize> {
        let (v, w) = self.cmd;
        let mut b = [0u8; 16];
        let n = match self.proto {
            Proto::Kobuki(_) => {
                let (speed, radius) = kobuki::speed_radius(v, w, self.cfg.track);
                kobuki::encode_base_control(speed, radius, &mut b).unwrap_or(0)
            }
            Proto::Create2 { .. } => {
                let half = 0.5 * self.cfg.track;
                let mm = |x: f32| (x * 1000.0).clamp(-500.0, 500.0) as i16;
                let cmd = create2::drive_direct(mm(v + w * half), mm(v - w * half));
                for (d, c) in b.iter_mut().zip(cmd) {
                    *d = c;
                }
                cmd.len()
            }
            Proto::None => 0,
        };
        if n == 0 {
            return Some(0);
        }
        if !self.tx.push(b.get(..n).unwrap_or(&[])) {
            return None;
        }
        self.sent = Some((v, w));
        Some(n)
    }

    /// Bytes from the base.
    pub fn on_bytes(&mut self, now: Instant, bytes: &[u8]) {
        for &b in bytes {
            let fb: Option<(i32, i32, u16, Option<f32>)> = match &mut self.proto {
                Proto::Kobuki(p) => match p.push(b) {
                    Some(Ok(payload)) => {
                        let mut out = None;
                        let mut gyro = None;
                        for (id, data) in kobuki::sub_payloads(payload) {
                            if id == kobuki::FB_BASIC_SENSOR_DATA {
                                if let Some(d) = kobuki::BasicSensorData::from_bytes(data) {
                                    out = Some((
                                        d.left_encoder as i32,
                                        d.right_encoder as i32,
                                        kobuki_flags(&d),
                                    ));
                                }
                            } else if id == kobuki::FB_INERTIA {
                                gyro = kobuki::inertial_angle(data);
                            }
                        }
                        out.map(|(l, r, f)| (l, r, f, gyro))
                    }
                    Some(Err(_)) => {
                        self.stats.bad_packets = self.stats.bad_packets.saturating_add(1);
                        None
                    }
                    None => None,
                },
                Proto::Create2 { parser, .. } => match parser.push(b) {
                    Some(Ok(s)) => Some((
                        s.left_encoder as u16 as i32,
                        s.right_encoder as u16 as i32,
                        create2_flags(&s),
                        None,
                    )),
                    Some(Err(_)) => {
                        self.stats.bad_packets = self.stats.bad_packets.saturating_add(1);
                        None
                    }
                    None => None,
                },
                Proto::None => None,
            };
            if let Some((l, r, flags, gyro)) = fb {
                self.on_feedback(now, l, r, flags, gyro);
            }
        }
    }

    /// One feedback sample: encoder counts, safety flags, and the gyro heading (rad) when the
    /// base has one. With a gyro, the heading change comes from it (gyro-aided odometry):
    /// wheel-radius and track errors and wheel slip then no longer turn the estimate.
    fn on_feedback(&mut self, now: Instant, left: i32, right: i32, flags: u16, gyro: Option<f32>) {
        self.stats.packets = self.stats.packets.saturating_add(1);
        let dt = self.last_rx.map(|t| (now - t).as_secs_f32()).unwrap_or(0.0);
        self.last_rx = Some(now);
        if self.lost {
            self.lost = false;
            let _ = self.events.push_back(BaseEvent::Recovered);
        }
        if let Some((l0, r0)) = self.last_enc {
            // 16-bit counters: the wrapped difference is the travel.
            let dl_ticks = (left.wrapping_sub(l0) as u16) as i16 as f32;
            let dr_ticks = (right.wrapping_sub(r0) as u16) as i16 as f32;
            let k = self.cfg.rad_per_tick();
            let (al, ar) = (dl_ticks * k, dr_ticks * k);
            self.wheels.left += al;
            self.wheels.right += ar;
            if dt > 0.0 {
                self.wheels.left_rate = al / dt;
                self.wheels.right_rate = ar / dt;
            }
            let (rl, rr, track) = self.odom_geometry;
            match (gyro, self.last_gyro) {
                (Some(g), Some(g0)) => {
                    let dth = ferrobot_protocol::geometry::wrap(g - g0);
                    self.odom.update_with_heading(al * rl, ar * rr, dth, dt)
                }
                _ => self.odom.update(al * rl, ar * rr, track, dt),
            }
        }
        self.last_enc = Some((left, right));
        self.last_gyro = gyro;
        let rising = flags & !self.flags;
        self.flags = flags;
        if rising != 0 {
            let _ = self.events.push_back(BaseEvent::Safety(rising));
            // Stop unless the command only backs away from a bumper.
            let backing = rising & !base_flags::ANY_BUMPER == 0 && self.cmd.0 < 0.0;
            if !backing {
                self.stop(now);
            }
        }
    }
}

fn kobuki_flags(d: &kobuki::BasicSensorData) -> u16 {
    use ferrobot_protocol::kobuki::{bumper, cliff, wheel_drop};
    let mut f = 0;
    let map = [
        (d.bumper & bumper::LEFT, base_flags::BUMPER_LEFT),
        (d.bumper & bumper::CENTER, base_flags::BUMPER_CENTER),
        (d.bumper & bumper::RIGHT, base_flags::BUMPER_RIGHT),
        (d.cliff & cliff::LEFT, base_flags::CLIFF_LEFT),
        (d.cliff & cliff::CENTER, base_flags::CLIFF_CENTER),
        (d.cliff & cliff::RIGHT, base_flags::CLIFF_RIGHT),
        (d.wheel_drop & wheel_drop::LEFT, base_flags::WHEEL_DROP_LEFT),
        (
            d.wheel_drop & wheel_drop::RIGHT,
            base_flags::WHEEL_DROP_RIGHT,
        ),
    ];
    for (bit, flag) in map {
        if bit != 0 {
            f |= flag;
        }
    }
    f
}

fn create2_flags(s: &create2::Sensors) -> u16 {
    use ferrobot_protocol::create2::bumps;
    let mut f = 0;
    if s.bumps_drops & bumps::BUMP_LEFT != 0 {
        f |= base_flags::BUMPER_LEFT;
    }
    if s.bumps_drops & bumps::BUMP_RIGHT != 0 {
        f |= base_flags::BUMPER_RIGHT;
    }
    if s.bumps_drops & bumps::DROP_LEFT != 0 {
        f |= base_flags::WHEEL_DROP_LEFT;
    }
    if s.bumps_drops & bumps::DROP_RIGHT != 0 {
        f |= base_flags::WHEEL_DROP_RIGHT;
    }
    let [l, fl, fr, r] = s.cliffs;
    if l != 0 {
        f |= base_flags::CLIFF_LEFT;
    }
    if fl != 0 || fr != 0 {
        f |= base_flags::CLIFF_CENTER;
    }
    if r != 0 {
        f |= base_flags::CLIFF_RIGHT;
    }
    f
}
