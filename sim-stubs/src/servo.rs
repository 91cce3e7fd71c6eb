//! One simulated X-series Dynamixel: its control table and its physics (output-shaft side, SI
//! units): DC motor and gear from [`MotorSpec`], the internal controllers at 4 kHz with the
//! e-manual's gain scaling, backlash, encoder quantisation, seeded reading noise, overload
//! protection ([`OVERLOAD_FRACTION`], [`OVERLOAD_TIME`]) and contacts (stops, an obstacle) as
//! stiff spring-dampers. Model details: `docs/design/sim-stubs.md`, "servo".

use ferrobot_protocol::dxl::{addr, hw_error, mode, status_error, units, MotorSpec};
use ferrobot_protocol::ServoModel;

use crate::rng::SimRng;

/// Physical parameters beyond the datasheet's motor figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoPhysics {
    /// Inertia seen at the output shaft (rotor reflected through the gear, plus the link), kg·m².
    pub inertia: f64,
    /// Viscous gear friction, N·m·s/rad.
    pub viscous: f64,
    /// Coulomb gear friction, N·m.
    pub coulomb: f64,
    /// Backlash (full play), rad.
    pub backlash: f64,
    /// Standard deviation of velocity-reading noise, velocity units.
    pub velocity_noise: f64,
    /// Standard deviation of current/load-reading noise, register units.
    pub current_noise: f64,
}

impl ServoPhysics {
    /// Defaults for a model: XM430-W350 (353.5:1) and XL430-W250 (258.5:1).
    pub fn for_model(model: ServoModel) -> Self {
        match model {
            ServoModel::Xm430W350 => ServoPhysics {
                inertia: 0.012,
                viscous: 0.02,
                coulomb: 0.04,
                backlash: 0.25_f64.to_radians(),
                velocity_noise: 0.4,
                current_noise: 1.5,
            },
            _ => ServoPhysics {
                inertia: 0.004,
                viscous: 0.01,
                coulomb: 0.02,
                backlash: 0.25_f64.to_radians(),
                velocity_noise: 0.4,
                current_noise: 3.0,
            },
        }
    }
}

/// Simulation substep, s.
pub const SUBSTEP: f64 = 250e-6;
/// Load fraction of stall torque beyond which the overload timer runs.
pub const OVERLOAD_FRACTION: f64 = 0.8;
/// How long the overload must last, s.
pub const OVERLOAD_TIME: f64 = 2.0;

/// A simulated servo.
#[derive(Debug, Clone)]
pub struct ServoSim {
    /// Dynamixel ID.
    pub id: u8,
    /// Model.
    pub model: ServoModel,
    spec: MotorSpec,
    /// Physical parameters.
    pub phys: ServoPhysics,
    table: [u8; addr::TABLE_SIZE],
    /// Motor-side angle, rad (0 at the centre tick).
    pub theta_m: f64,
    /// Output angle, rad (what the encoder sees).
    pub theta: f64,
    /// Angular speed, rad/s.
    pub omega: f64,
    /// Motor current, A.
    pub current: f64,
    /// Motor torque at the output, N·m.
    pub torque: f64,
    /// External torque on the output (gravity, contacts), N·m, set by the owner each step.
    pub external_torque: f64,
    /// A hand's torque on the output, N·m: held until the owner changes it (a person moving
    /// the arm in teach mode).
    pub hand_torque: f64,
    /// Mechanical stops (min, max), rad.
    pub stops: Option<(f64, f64)>,
    /// An obstacle: motion below (`true`) or above (`false`) this angle is blocked.
    pub obstacle: Option<(f64, bool)>,
    /// When true the servo ignores the bus (a broken cable, a dead servo).
    pub silent: bool,
    integ_pos: f64,
    integ_vel: f64,
    prof_pos: f64,
    prof_vel: f64,
    overload_timer: f64,
    rng: SimRng,
}

impl ServoSim {
    /// A servo with factory defaults at angle `theta` (rad), torque off.
    pub fn new(id: u8, model: ServoModel, theta: f64, rng: SimRng) -> Self {
        let spec = model.spec();
        let mut s = Self {
            id,
            model,
            spec,
            phys: ServoPhysics::for_model(model),
            table: [0; addr::TABLE_SIZE],
            theta_m: theta,
            theta,
            omega: 0.0,
            current: 0.0,
            torque: 0.0,
            external_torque: 0.0,
            hand_torque: 0.0,
            stops: None,
            obstacle: None,
            silent: false,
            integ_pos: 0.0,
            integ_vel: 0.0,
            prof_pos: theta,
            prof_vel: 0.0,
            overload_timer: 0.0,
            rng,
        };
        s.factory_reset();
        s
    }

    /// Set the Baud Rate register to `baud`'s code, as ROBOTIS' tools leave a servo of a bus
    /// at that rate (the factory's is 57600); a rate outside the table leaves it as it is.
    pub fn set_baud_register(&mut self, baud: u32) {
        if let Some(code) = ferrobot_protocol::dxl::baud_code(baud) {
            self.put(addr::BAUD_RATE, 1, u32::from(code));
        }
    }

    /// Write `len` bytes of `value` at `address` of the control table, as nothing on the bus
    /// can (fault injection: a servo of another model, a wrong setting).
    pub fn set_register(&mut self, address: u16, len: usize, value: u32) {
        self.put(address, len, value);
    }

    /// Restore the control table's defaults (ID kept).
    pub fn factory_reset(&mut self) {
        let id = self.id;
        let gains = self.model.factory_gains();
        self.table = [0; addr::TABLE_SIZE];
        self.put(addr::MODEL_NUMBER, 2, self.spec.model_number as u32);
        self.put(addr::FIRMWARE_VERSION, 1, 46);
        self.put(addr::ID, 1, id as u32);
        self.put(addr::BAUD_RATE, 1, 1);
        self.put(addr::RETURN_DELAY_TIME, 1, 250);
        self.put(addr::OPERATING_MODE, 1, mode::POSITION as u32);
        self.put(addr::PWM_LIMIT, 2, 885);
        self.put(addr::CURRENT_LIMIT, 2, 1193);
        self.put(
            addr::VELOCITY_LIMIT,
            4,
            if self.spec.current_control { 200 } else { 265 },
        );
        self.put(addr::MAX_POSITION_LIMIT, 4, 4095);
        self.put(addr::MIN_POSITION_LIMIT, 4, 0);
        self.put(addr::STATUS_RETURN_LEVEL, 1, 2);
        self.put(addr::VELOCITY_I_GAIN, 2, gains.vel_i as u32);
        self.put(addr::VELOCITY_P_GAIN, 2, gains.vel_p as u32);
        self.put(addr::POSITION_D_GAIN, 2, gains.pos_d as u32);
        self.put(addr::POSITION_I_GAIN, 2, gains.pos_i as u32);
        self.put(addr::POSITION_P_GAIN, 2, gains.pos_p as u32);
        self.put(addr::PRESENT_INPUT_VOLTAGE, 2, 120);
        self.put(addr::PRESENT_TEMPERATURE, 1, 35);
        let goal = units::rad_to_tick(self.theta as f32);
        self.put(addr::GOAL_POSITION, 4, goal as u32);
        self.update_present();
    }

    /// Reboot: torque off, hardware error cleared, RAM area back to defaults.
    pub fn reboot(&mut self) {
        self.put(addr::TORQUE_ENABLE, 1, 0);
        self.put(addr::HARDWARE_ERROR_STATUS, 1, 0);
        self.overload_timer = 0.0;
        self.integ_pos = 0.0;
        self.integ_vel = 0.0;
        let goal = units::rad_to_tick(self.theta as f32);
        self.put(addr::GOAL_POSITION, 4, goal as u32);
    }

    fn put(&mut self, a: u16, len: usize, v: u32) {
        let bytes = v.to_le_bytes();
        for (k, b) in bytes.iter().take(len).enumerate() {
            if let Some(slot) = self.table.get_mut(a as usize + k) {
                *slot = *b;
            }
        }
    }

    /// Read `len` bytes of the control table as a little-endian unsigned value.
    pub fn get(&self, a: u16, len: usize) -> u32 {
        let mut v = [0u8; 4];
        for (k, b) in v.iter_mut().take(len).enumerate() {
            *b = self.table.get(a as usize + k).copied().unwrap_or(0);
        }
        u32::from_le_bytes(v)
    }

    /// Control-table bytes.
    pub fn read(&self, a: u16, len: u16) -> Option<&[u8]> {
        self.table.get(a as usize..a as usize + len as usize)
    }

    /// Torque enabled.
    pub fn torque_enabled(&self) -> bool {
        self.get(addr::TORQUE_ENABLE, 1) != 0
    }

    /// Hardware Error Status.
    pub fn hardware_error(&self) -> u8 {
        self.get(addr::HARDWARE_ERROR_STATUS, 1) as u8
    }

    /// Error byte for a status packet: the alert bit while a hardware error is latched.
    pub fn status_error(&self) -> u8 {
        if self.hardware_error() != 0 {
            status_error::ALERT
        } else {
            0
        }
    }

    /// Apply a write; returns the status error number (0 when accepted).
    pub fn write(&mut self, a: u16, data: &[u8]) -> u8 {
        let end = a as usize + data.len();
        if end > addr::TABLE_SIZE || data.is_empty() {
            return status_error::ACCESS;
        }
        // Read-only items.
        let ro = |x: usize| {
            x < 7 || x == addr::HARDWARE_ERROR_STATUS as usize || x >= addr::MOVING as usize
        };
        if (a as usize..end).any(ro) {
            return status_error::ACCESS;
        }
        // EEPROM area is writable only with torque off.
        if (a as usize) < addr::TORQUE_ENABLE as usize && self.torque_enabled() {
            return status_error::ACCESS;
        }
        let was_on = self.torque_enabled();
        for (k, b) in data.iter().enumerate() {
            if let Some(slot) = self.table.get_mut(a as usize + k) {
                *slot = *b;
            }
        }
        if (a..end as u16).contains(&addr::TORQUE_ENABLE) {
            if self.hardware_error() != 0 {
                // A latched hardware error keeps the torque off.
                self.put(addr::TORQUE_ENABLE, 1, 0);
            } else if !was_on && self.torque_enabled() {
                self.integ_pos = 0.0;
                self.integ_vel = 0.0;
                self.prof_pos = self.theta;
                self.prof_vel = 0.0;
            }
        }
        0
    }

    fn mode(&self) -> u8 {
        self.get(addr::OPERATING_MODE, 1) as u8
    }

    fn goal_angle(&self) -> f64 {
        let g = self.get(addr::GOAL_POSITION, 4) as i32;
        let (lo, hi) = (
            self.get(addr::MIN_POSITION_LIMIT, 4) as i32,
            self.get(addr::MAX_POSITION_LIMIT, 4) as i32,
        );
        let g = if self.mode() == mode::POSITION {
            g.clamp(lo, hi.max(lo))
        } else {
            g
        };
        units::tick_to_rad(g) as f64
    }

    /// Advance the physics by one substep of [`SUBSTEP`] seconds.
    pub fn step(&mut self) {
        let dt = SUBSTEP;
        let on = self.torque_enabled();
        let pwm = self.control_pwm(on, dt);
        self.motor(on, pwm);
        let contact = self.contact_torque();
        let drive = self.torque + self.external_torque + self.hand_torque + contact
            - self.phys.viscous * self.omega;
        self.integrate(drive, dt);
        self.protect(on, dt);
    }

    /// The PWM (±885) the internal controller asks for in its operating mode, before the PWM
    /// limit; 0 with torque off.
    fn control_pwm(&mut self, on: bool, dt: f64) -> f64 {
        let ms = dt * 1e3;
        let vel_unit = units::RAD_S_PER_VELOCITY_UNIT as f64;
        let supply = self.spec.supply_voltage as f64;
        let kt = self.spec.kt() as f64;
        let r = self.spec.resistance() as f64;
        if !on {
            0.0
        } else {
            match self.mode() {
                mode::PWM => (self.get(addr::GOAL_PWM, 2) as u16 as i16) as f64,
                mode::VELOCITY => {
                    let goal = self.get(addr::GOAL_VELOCITY, 4) as i32 as f64;
                    let e = goal - self.omega / vel_unit;
                    self.integ_vel = (self.integ_vel + e * ms).clamp(-1e7, 1e7);
                    let kp = self.get(addr::VELOCITY_P_GAIN, 2) as f64 / 128.0;
                    let ki = self.get(addr::VELOCITY_I_GAIN, 2) as f64 / 65536.0;
                    kp * e + ki * self.integ_vel
                }
                mode::CURRENT if self.spec.current_control => {
                    let limit = self.get(addr::CURRENT_LIMIT, 2) as f64;
                    let goal = ((self.get(addr::GOAL_CURRENT, 2) as u16 as i16) as f64)
                        .clamp(-limit, limit);
                    let i_goal = goal * units::AMP_PER_CURRENT_UNIT as f64;
                    (r * i_goal + kt * self.omega) / supply * 885.0
                }
                _ => self.position_pwm(dt),
            }
        }
    }

    /// Position control with optional trapezoidal profile: the profile advanced one step, and
    /// the PID's PWM towards it.
    fn position_pwm(&mut self, dt: f64) -> f64 {
        let ms = dt * 1e3;
        let ticks_per_rad = units::TICKS_PER_REV as f64 / std::f64::consts::TAU;
        let vel_unit = units::RAD_S_PER_VELOCITY_UNIT as f64;
        let goal = self.goal_angle();
        let pv = self.get(addr::PROFILE_VELOCITY, 4) as f64 * vel_unit;
        let pa = self.get(addr::PROFILE_ACCELERATION, 4) as f64 * 214.577 * std::f64::consts::TAU
            / 3600.0;
        if pv <= 0.0 {
            self.prof_pos = goal;
            self.prof_vel = 0.0;
        } else {
            let d = goal - self.prof_pos;
            let a = if pa > 0.0 { pa } else { 1e6 };
            let v_target = d.signum() * pv.min((2.0 * a * d.abs()).sqrt());
            let dv = (v_target - self.prof_vel).clamp(-a * dt, a * dt);
            self.prof_vel += dv;
            self.prof_pos += self.prof_vel * dt;
            if (goal - self.prof_pos).signum() != d.signum() {
                self.prof_pos = goal;
                self.prof_vel = 0.0;
            }
        }
        let e = (self.prof_pos - self.theta) * ticks_per_rad;
        let de_ms = (self.prof_vel - self.omega) * ticks_per_rad * 1e-3;
        let kp = self.get(addr::POSITION_P_GAIN, 2) as f64 / 128.0;
        let ki = self.get(addr::POSITION_I_GAIN, 2) as f64 / 65536.0;
        let kd = self.get(addr::POSITION_D_GAIN, 2) as f64 / 16.0;
        if ki > 0.0 {
            self.integ_pos = (self.integ_pos + e * ms).clamp(-885.0 / ki, 885.0 / ki);
        }
        kp * e + ki * self.integ_pos + kd * de_ms
    }

    /// The motor's current and torque from `pwm` (limited), its back-EMF and, in current
    /// mode, the current limit.
    fn motor(&mut self, on: bool, pwm: f64) {
        let supply = self.spec.supply_voltage as f64;
        let kt = self.spec.kt() as f64;
        let r = self.spec.resistance() as f64;
        let pwm_limit = (self.get(addr::PWM_LIMIT, 2) as f64).min(885.0);
        let pwm = pwm.clamp(-pwm_limit, pwm_limit);
        let volts = pwm / 885.0 * supply;
        self.current = if on {
            (volts - kt * self.omega) / r
        } else {
            0.0
        };
        if on && self.mode() == mode::CURRENT && self.spec.current_control {
            let limit =
                self.get(addr::CURRENT_LIMIT, 2) as f64 * units::AMP_PER_CURRENT_UNIT as f64;
            self.current = self.current.clamp(-limit, limit);
        }
        self.torque = kt * self.current;
    }

    /// Contacts: stiff, critically damped, pushing out and never pulling in (the stops and the
    /// obstacle), N·m.
    fn contact_torque(&self) -> f64 {
        let k = 60.0;
        let c = 2.0 * (k * self.phys.inertia).sqrt();
        let push_up = |pen: f64, omega: f64| (k * pen - c * omega).max(0.0);
        let push_down = |pen: f64, omega: f64| -(k * pen + c * omega).max(0.0);
        let mut contact = 0.0;
        if let Some((lo, hi)) = self.stops {
            if self.theta < lo {
                contact += push_up(lo - self.theta, self.omega);
            } else if self.theta > hi {
                contact += push_down(self.theta - hi, self.omega);
            }
        }
        if let Some((at, below)) = self.obstacle {
            if below && self.theta < at {
                contact += push_up(at - self.theta, self.omega);
            } else if !below && self.theta > at {
                contact += push_down(self.theta - at, self.omega);
            }
        }
        contact
    }

    /// Move the motor under torque `drive` (N·m) for `dt` s with Coulomb friction and
    /// stiction, and the output after it through the backlash.
    fn integrate(&mut self, drive: f64, dt: f64) {
        // Coulomb friction with stiction.
        let fc = self.phys.coulomb;
        let acc = if self.omega.abs() < 1e-4 && drive.abs() <= fc {
            self.omega = 0.0;
            0.0
        } else {
            (drive - fc * self.omega.signum()) / self.phys.inertia
        };
        let omega_next = self.omega + acc * dt;
        // Friction cannot reverse the motion within a step.
        self.omega =
            if self.omega != 0.0 && omega_next.signum() != self.omega.signum() && drive.abs() <= fc
            {
                0.0
            } else {
                omega_next
            };
        self.theta_m += self.omega * dt;
        // Backlash: the output follows the motor through a play of `backlash`.
        let half = 0.5 * self.phys.backlash;
        if self.theta_m - self.theta > half {
            self.theta = self.theta_m - half;
        } else if self.theta_m - self.theta < -half {
            self.theta = self.theta_m + half;
        }
    }

    /// Overload protection: torque above [`OVERLOAD_FRACTION`] of stall for
    /// [`OVERLOAD_TIME`] sets the overload error and turns torque off.
    fn protect(&mut self, on: bool, dt: f64) {
        if on && self.torque.abs() > OVERLOAD_FRACTION * self.spec.stall_torque as f64 {
            self.overload_timer += dt;
            if self.overload_timer >= OVERLOAD_TIME {
                let e = self.hardware_error() | hw_error::OVERLOAD;
                self.put(addr::HARDWARE_ERROR_STATUS, 1, e as u32);
                self.put(addr::TORQUE_ENABLE, 1, 0);
            }
        } else {
            self.overload_timer = 0.0;
        }
    }

    /// The output's speed now, rad/s: the motor's, while the gear is engaged (the output
    /// rests against one side of the backlash and is carried along); zero while the motor
    /// turns inside the play.
    pub fn output_speed(&self) -> f64 {
        let half = 0.5 * self.phys.backlash;
        let lead = self.theta_m - self.theta;
        let engaged = (self.omega > 0.0 && lead >= half - 1e-12)
            || (self.omega < 0.0 && lead <= -half + 1e-12);
        if engaged {
            self.omega
        } else {
            0.0
        }
    }

    /// Refresh the present-value registers from the physical state (with quantisation and noise).
    pub fn update_present(&mut self) {
        let pos = units::rad_to_tick(self.theta as f32);
        let vel_units = self.omega / units::RAD_S_PER_VELOCITY_UNIT as f64
            + self.rng.normal(self.phys.velocity_noise);
        let vel = vel_units.round() as i32;
        let cur = if self.spec.current_control {
            self.current / units::AMP_PER_CURRENT_UNIT as f64
        } else {
            self.torque / self.spec.stall_torque as f64 * units::LOAD_FULL_SCALE as f64
        } + if self.torque_enabled() {
            self.rng.normal(self.phys.current_noise)
        } else {
            0.0
        };
        let cur = cur.round().clamp(i16::MIN as f64, i16::MAX as f64) as i16;
        let pwm = (self.current * self.spec.resistance() as f64 / self.spec.supply_voltage as f64
            * 885.0) as i16;
        self.put(addr::PRESENT_PWM, 2, pwm as u16 as u32);
        self.put(addr::PRESENT_CURRENT, 2, cur as u16 as u32);
        self.put(addr::PRESENT_VELOCITY, 4, vel as u32);
        self.put(addr::PRESENT_POSITION, 4, pos as u32);
        let moving = (vel.unsigned_abs() > 2) as u32;
        self.put(addr::MOVING, 1, moving);
    }
}
