//! The simulated Kobuki and Create 2: a [`DiffDrive`] behind each base's real serial protocol,
//! at its real feedback rate (Kobuki 50 Hz, Create 2 stream every 15 ms).

use ferrobot_protocol::{create2, kobuki};

use crate::diff_drive::{DiffDrive, DiffDriveParams, Surroundings};
use crate::rng::SimRng;

/// Physics substep of the bases, µs.
pub const BASE_STEP_US: u64 = 1000;

/// Injected safety-sensor states (besides bumper contacts with obstacles).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Injected {
    /// Bumpers pressed by hand: bit 0 left, 1 centre, 2 right.
    pub bumper: u8,
    /// Cliff sensors: bit 0 left, 1 centre, 2 right.
    pub cliff: u8,
    /// Wheel drops: bit 0 left, 1 right.
    pub wheel_drop: u8,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum OiMode {
    Off,
    Passive,
    Safe,
    Full,
}

enum Kind {
    Kobuki {
        parser: Box<kobuki::Parser>,
        gyro_bias: f64,
    },
    Create2 {
        mode: OiMode,
        streaming: bool,
        op: Vec<u8>,
        need: Option<usize>,
        bad: u32,
    },
}

/// A simulated base.
pub struct BasePlant {
    /// The physics and ground truth.
    pub drive: DiffDrive,
    /// Injected sensor states.
    pub injected: Injected,
    kind: Kind,
    time_us: u64,
    next_feedback: u64,
    period_us: u64,
    out: Vec<u8>,
    /// Command packets accepted.
    pub commands: u32,
    /// The base's replies are lost on their way (a broken receive wire, a base whose serial
    /// output died): it still obeys commands but says nothing (fault injection).
    pub mute: bool,
}

/// The Kobuki of the LoCoBot: nominal radius 0.035 m and track 0.230 m; the true wheels are
/// 0.8 % and 0.9 % larger (worn tyres and load; this makes the 2 m odometry gap about the
/// 15 mm PyRobot reports) and the track 0.5 % wider; wheel controller lag 40 ms, 1.5 m/s²
/// acceleration limit, 5 mm/s deadband, slip noise 0.2 %.
pub fn kobuki_params() -> DiffDriveParams {
    DiffDriveParams {
        left_radius: 0.035 * 1.008,
        right_radius: 0.035 * 1.009,
        track: 0.230 * 1.005,
        ticks_per_rev: kobuki::TICKS_PER_REV as f64,
        lag: 0.04,
        accel_limit: 1.5,
        max_speed: 0.7,
        deadband: 0.005,
        slip_std: 0.002,
        slip_per_accel: 0.002,
        body_radius: 0.177,
    }
}

/// The Create 2 of the LoCoBot-Lite: 72 mm wheels per the Open Interface specification,
/// true radii 0.5 % and 0.8 % larger, track 1 % wider; lag 60 ms, 1.0 m/s², 10 mm/s
/// deadband, slip noise 0.5 %.
pub fn create2_params() -> DiffDriveParams {
    DiffDriveParams {
        left_radius: 0.036 * 1.005,
        right_radius: 0.036 * 1.008,
        track: 0.235 * 1.01,
        ticks_per_rev: create2::TICKS_PER_REV as f64,
        lag: 0.06,
        accel_limit: 1.0,
        max_speed: 0.5,
        deadband: 0.01,
        slip_std: 0.005,
        slip_per_accel: 0.004,
        body_radius: 0.174,
    }
}

impl BasePlant {
    /// A Kobuki.
    pub fn kobuki(seed: u64) -> Self {
        let mut rng = SimRng::new(seed, 2);
        let gyro_bias = rng.normal(0.0002);
        Self::with(
            DiffDrive::new(kobuki_params(), SimRng::new(seed, 3)),
            Kind::Kobuki {
                parser: Box::new(kobuki::Parser::new()),
                gyro_bias,
            },
            20_000,
        )
    }

    /// A Create 2.
    pub fn create2(seed: u64) -> Self {
        Self::with(
            DiffDrive::new(create2_params(), SimRng::new(seed, 4)),
            Kind::Create2 {
                mode: OiMode::Off,
                streaming: false,
                op: Vec::new(),
                need: None,
                bad: 0,
            },
            create2::STREAM_PERIOD_US,
        )
    }

    fn with(drive: DiffDrive, kind: Kind, period_us: u64) -> Self {
        Self {
            drive,
            injected: Injected::default(),
            kind,
            time_us: 0,
            next_feedback: period_us,
            period_us,
            out: Vec::new(),
            commands: 0,
            mute: false,
        }
    }

    /// Packets dropped for checksum or framing errors.
    pub fn bad_packets(&self) -> u32 {
        match &self.kind {
            Kind::Kobuki { parser, .. } => parser.bad,
            Kind::Create2 { bad, .. } => *bad,
        }
    }

    /// The base's feedback cycle (Kobuki 20 ms, Create 2 15 ms), µs.
    pub fn period_us(&self) -> u64 {
        self.period_us
    }

    /// When the next feedback packet is due, µs.
    pub fn next_event(&self) -> u64 {
        self.next_feedback
    }

    /// Advance the physics to `t_us`, emitting feedback packets that fall due (taken with
    /// [`BasePlant::take_output`]).
    pub fn advance_to(&mut self, t_us: u64) {
        self.advance_among(t_us, None);
    }

    /// Start the base's clock at `t_us` (µs), before it ran: its first feedback a period
    /// later.
    pub fn start_at(&mut self, t_us: u64) {
        if t_us > self.time_us {
            self.time_us = t_us;
            self.next_feedback = t_us + self.period_us;
        }
    }

    /// [`BasePlant::advance_to`] with the body among `world`'s colliders (see
    /// [`DiffDrive::step_among`]).
    pub fn advance_among(&mut self, t_us: u64, world: Option<&dyn Surroundings>) {
        while self.time_us + BASE_STEP_US <= t_us {
            self.time_us += BASE_STEP_US;
            self.safety_reflexes();
            self.drive.step_among(BASE_STEP_US as f64 * 1e-6, world);
            if self.time_us >= self.next_feedback {
                self.next_feedback += self.period_us;
                self.emit_feedback();
            }
        }
    }

    /// Bytes the base has sent since the last call (none while [`BasePlant::mute`]).
    pub fn take_output(&mut self) -> Vec<u8> {
        let out = std::mem::take(&mut self.out);
        if self.mute {
            Vec::new()
        } else {
            out
        }
    }

    fn bumper_bits(&self) -> u8 {
        let c = self.drive.contact;
        self.injected.bumper | (c.left as u8) | ((c.center as u8) << 1) | ((c.right as u8) << 2)
    }

    fn safety_reflexes(&mut self) {
        // The Create 2 in safe mode stops and drops to passive on a cliff or wheel drop.
        let hazard = self.injected.cliff != 0 || self.injected.wheel_drop != 0;
        if let Kind::Create2 { mode, .. } = &mut self.kind {
            if *mode == OiMode::Safe && hazard {
                *mode = OiMode::Passive;
                self.drive.command(0.0, 0.0);
            }
        }
    }

    fn emit_feedback(&mut self) {
        let (l, r) = self.drive.encoder_counts();
        let b = self.bumper_bits();
        let inj = self.injected;
        match &mut self.kind {
            Kind::Kobuki { gyro_bias, .. } => {
                let gyro_bias = *gyro_bias;
                self.emit_kobuki(gyro_bias, (l, r), b, inj);
            }
            Kind::Create2 { streaming, .. } => {
                if !*streaming {
                    return;
                }
                self.emit_create2((l, r), b, inj);
            }
        }
    }

    /// A Kobuki's feedback: basic sensor data and inertia, from the encoders `(l, r)`, the
    /// bumper bits `b` (left, centre, right) and the injected faults.
    fn emit_kobuki(&mut self, gyro_bias: f64, (l, r): (u16, u16), b: u8, inj: Injected) {
        use kobuki::{bumper, cliff, wheel_drop};
        let mut bump = 0;
        if b & 1 != 0 {
            bump |= bumper::LEFT;
        }
        if b & 2 != 0 {
            bump |= bumper::CENTER;
        }
        if b & 4 != 0 {
            bump |= bumper::RIGHT;
        }
        let mut cl = 0;
        if inj.cliff & 1 != 0 {
            cl |= cliff::LEFT;
        }
        if inj.cliff & 2 != 0 {
            cl |= cliff::CENTER;
        }
        if inj.cliff & 4 != 0 {
            cl |= cliff::RIGHT;
        }
        let mut wd = 0;
        if inj.wheel_drop & 1 != 0 {
            wd |= wheel_drop::LEFT;
        }
        if inj.wheel_drop & 2 != 0 {
            wd |= wheel_drop::RIGHT;
        }
        let p = &self.drive.p;
        let pwm = |v: f64| (v / p.max_speed * 100.0).clamp(-100.0, 100.0) as i8;
        let d = kobuki::BasicSensorData {
            timestamp_ms: (self.time_us / 1000) as u16,
            bumper: bump,
            wheel_drop: wd,
            cliff: cl,
            left_encoder: l,
            right_encoder: r,
            left_pwm: pwm(self.drive.speed.0),
            right_pwm: pwm(self.drive.speed.1),
            buttons: 0,
            charger: 0,
            battery: 160,
            over_current: 0,
        };
        let heading = self.drive.truth[2] + gyro_bias * self.time_us as f64 * 1e-6;
        let angle = (heading.to_degrees() * 100.0).round() as i64 as i16;
        let rate_dps = (self.drive.speed.1 - self.drive.speed.0) / p.track;
        let rate = (rate_dps.to_degrees() * 100.0).round() as i16;
        let mut payload = vec![
            kobuki::FB_BASIC_SENSOR_DATA,
            kobuki::BasicSensorData::LEN as u8,
        ];
        payload.extend_from_slice(&d.to_bytes());
        let a = angle.to_le_bytes();
        let rr = rate.to_le_bytes();
        payload.extend_from_slice(&[kobuki::FB_INERTIA, 7, a[0], a[1], rr[0], rr[1], 0, 0, 0]);
        let mut buf = [0u8; 64];
        if let Some(n) = kobuki::encode_packet(&payload, &mut buf) {
            self.out.extend_from_slice(&buf[..n]);
        }
    }

    /// A Create 2's sensor stream (while streaming), from the encoders `(l, r)`, the bumper
    /// bits `b` (left, centre, right) and the injected faults.
    fn emit_create2(&mut self, (l, r): (u16, u16), b: u8, inj: Injected) {
        use create2::bumps;
        let mut bd = 0;
        if b & 1 != 0 {
            bd |= bumps::BUMP_LEFT;
        }
        if b & 4 != 0 {
            bd |= bumps::BUMP_RIGHT;
        }
        if b & 2 != 0 {
            bd |= bumps::BUMP_LEFT | bumps::BUMP_RIGHT;
        }
        if inj.wheel_drop & 1 != 0 {
            bd |= bumps::DROP_LEFT;
        }
        if inj.wheel_drop & 2 != 0 {
            bd |= bumps::DROP_RIGHT;
        }
        let s = create2::Sensors {
            bumps_drops: bd,
            cliffs: [
                (inj.cliff & 1 != 0) as u8,
                (inj.cliff & 2 != 0) as u8,
                (inj.cliff & 2 != 0) as u8,
                (inj.cliff & 4 != 0) as u8,
            ],
            left_encoder: l as i16,
            right_encoder: r as i16,
        };
        let mut buf = [0u8; 64];
        if let Some(n) = create2::encode_stream(&s, &mut buf) {
            self.out.extend_from_slice(&buf[..n]);
        }
    }

    /// Bytes from the firmware at `t_us`.
    pub fn on_bytes(&mut self, t_us: u64, bytes: &[u8]) {
        self.advance_to(t_us);
        for &b in bytes {
            match &mut self.kind {
                Kind::Kobuki { parser, .. } => {
                    if let Some(Ok(payload)) = parser.push(b) {
                        let mut cmd = None;
                        for (id, d) in kobuki::sub_payloads(payload) {
                            if id == kobuki::CMD_BASE_CONTROL && d.len() == 4 {
                                let speed = i16::from_le_bytes([d[0], d[1]]);
                                let radius = i16::from_le_bytes([d[2], d[3]]);
                                // The Kobuki's controller uses its nominal wheel separation.
                                cmd = Some(kobuki::wheel_speeds(speed, radius, 0.230));
                            }
                        }
                        if let Some((l, r)) = cmd {
                            self.commands += 1;
                            self.drive.command(l as f64, r as f64);
                        }
                    }
                }
                Kind::Create2 {
                    mode,
                    streaming,
                    op,
                    need,
                    bad,
                } => {
                    op.push(b);
                    if op.len() == 1 {
                        match create2::command_len(b) {
                            Some(n) => *need = Some(n),
                            None => {
                                *bad += 1;
                                op.clear();
                                continue;
                            }
                        }
                    } else if op.len() == 2 && op[0] == create2::OP_STREAM {
                        *need = Some(1 + b as usize);
                    }
                    if need.is_some_and(|n| op.len() == n + 1) {
                        let cmd = std::mem::take(op);
                        *need = None;
                        match cmd[0] {
                            create2::OP_START => *mode = OiMode::Passive,
                            create2::OP_SAFE if *mode != OiMode::Off => *mode = OiMode::Safe,
                            create2::OP_FULL if *mode != OiMode::Off => *mode = OiMode::Full,
                            create2::OP_STOP => {
                                *mode = OiMode::Off;
                                *streaming = false;
                                self.drive.command(0.0, 0.0);
                            }
                            create2::OP_STREAM if *mode != OiMode::Off => *streaming = true,
                            create2::OP_PAUSE_RESUME => *streaming = cmd.get(1) == Some(&1),
                            create2::OP_DRIVE_DIRECT
                                if matches!(*mode, OiMode::Safe | OiMode::Full) =>
                            {
                                let r = i16::from_be_bytes([cmd[1], cmd[2]]).clamp(-500, 500);
                                let l = i16::from_be_bytes([cmd[3], cmd[4]]).clamp(-500, 500);
                                self.commands += 1;
                                self.drive.command(l as f64 / 1000.0, r as f64 / 1000.0);
                            }
                            _ => {}
                        }
                    }
                }
            }
        }
    }
}
