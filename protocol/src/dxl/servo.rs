//! The X-series servo models as both ends see them: unit conversions of their registers, and
//! their motors' electrical and mechanical data (torque constant, resistance, effort to
//! current or PWM and back) at the 12 V supply, output-shaft side; factory gains.

use crate::messages::{ServoGains, ServoModel};

/// Unit conversions of the X series.
pub mod units {
    use core::f32::consts::PI;
    /// Position ticks per revolution.
    pub const TICKS_PER_REV: f32 = 4096.0;
    /// Tick that corresponds to 0 rad.
    pub const CENTER_TICK: i32 = 2048;
    /// rad per position tick.
    pub const RAD_PER_TICK: f32 = 2.0 * PI / TICKS_PER_REV;
    /// rad/s per velocity unit (0.229 rpm).
    pub const RAD_S_PER_VELOCITY_UNIT: f32 = 0.229 * 2.0 * PI / 60.0;
    /// A per current unit (XM430: 2.69 mA).
    pub const AMP_PER_CURRENT_UNIT: f32 = 0.00269;
    /// Goal-PWM units at 100 % duty.
    pub const PWM_MAX: f32 = 885.0;
    /// Present-load units (XL430) at 100 % of stall torque (0.1 % units).
    pub const LOAD_FULL_SCALE: f32 = 1000.0;
    /// Model number of the XM430-W350.
    pub const MODEL_XM430_W350: u16 = 1020;
    /// Model number of the XL430-W250.
    pub const MODEL_XL430_W250: u16 = 1060;

    /// Servo angle (rad, 0 at the centre tick) to a position tick.
    pub fn rad_to_tick(rad: f32) -> i32 {
        let t = rad / RAD_PER_TICK;
        // Round half away from zero without libm.
        let r = if t >= 0.0 { t + 0.5 } else { t - 0.5 };
        CENTER_TICK.saturating_add(r as i32)
    }

    /// Position tick to servo angle (rad).
    pub fn tick_to_rad(tick: i32) -> f32 {
        (tick.saturating_sub(CENTER_TICK)) as f32 * RAD_PER_TICK
    }
}

/// Electrical and mechanical data of a servo model at its 12 V supply, output-shaft side.
///
/// A DC motor with gear: `τ = Kt·i`, `V = R·i + Ke·ω`, `Kt = Ke = V/ω₀`, `R = V·Kt/τ_stall`.
/// With the XM430-W350's 4.1 N·m stall torque and 46 rpm no-load speed this gives a torque
/// constant of 2.49 N·m/A, within 0.4 % of the 149.795 current units per N·m the LoCoBot driver
/// uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorSpec {
    /// Stall torque at the supply voltage, N·m.
    pub stall_torque: f32,
    /// No-load speed at the supply voltage, rad/s.
    pub no_load_speed: f32,
    /// Supply voltage, V.
    pub supply_voltage: f32,
    /// Whether the model has a current sensor and current control (goal current, mode 0).
    pub current_control: bool,
    /// Model number reported at address 0.
    pub model_number: u16,
}

impl MotorSpec {
    /// Torque (and back-EMF) constant, N·m/A = V·s/rad.
    pub fn kt(&self) -> f32 {
        self.supply_voltage / self.no_load_speed
    }
    /// Winding resistance, Ω.
    pub fn resistance(&self) -> f32 {
        self.supply_voltage * self.kt() / self.stall_torque
    }
    /// Effort (N·m) that a present-current/load register value (address 126) stands for.
    pub fn effort_from_register(&self, raw: i16) -> f32 {
        if self.current_control {
            raw as f32 * units::AMP_PER_CURRENT_UNIT * self.kt()
        } else {
            raw as f32 / units::LOAD_FULL_SCALE * self.stall_torque
        }
    }
    /// Register value (address 126 units) for an effort, N·m.
    pub fn register_from_effort(&self, effort: f32) -> i16 {
        let v = if self.current_control {
            effort / self.kt() / units::AMP_PER_CURRENT_UNIT
        } else {
            effort / self.stall_torque * units::LOAD_FULL_SCALE
        };
        clamp_i16(v)
    }
    /// Goal-PWM value that produces `effort` (N·m) at joint speed `speed` (rad/s):
    /// `V = R·τ/Kt + Ke·ω`, saturated at the supply.
    pub fn pwm_for_effort(&self, effort: f32, speed: f32) -> i16 {
        clamp_i16(self.pwm_fraction_for_effort(effort, speed) * units::PWM_MAX)
    }
    /// PWM fraction in [−1, 1] that produces `effort` (N·m) at joint speed `speed` (rad/s).
    pub fn pwm_fraction_for_effort(&self, effort: f32, speed: f32) -> f32 {
        let v = self.resistance() * effort / self.kt() + self.kt() * speed;
        let f = (v / self.supply_voltage).clamp(-1.0, 1.0);
        if f.is_nan() {
            0.0
        } else {
            f
        }
    }
    /// Effort (N·m) that a PWM fraction `pwm` in [−1, 1] produces at joint speed `speed`
    /// (rad/s): the inverse of [`MotorSpec::pwm_fraction_for_effort`] below saturation.
    pub fn effort_for_pwm_fraction(&self, pwm: f32, speed: f32) -> f32 {
        (pwm * self.supply_voltage - self.kt() * speed) * self.kt() / self.resistance()
    }
}

fn clamp_i16(v: f32) -> i16 {
    if v.is_nan() {
        0
    } else {
        v.clamp(i16::MIN as f32, i16::MAX as f32) as i16
    }
}

impl ServoModel {
    /// Factory-default control gains (ROBOTIS e-manual) and motion profile (none).
    pub fn factory_gains(&self) -> ServoGains {
        let (pos_p, pos_i, pos_d, vel_p, vel_i) = match self {
            ServoModel::Xm430W350 => (800, 0, 0, 100, 1920),
            _ => (640, 0, 4000, 100, 1000),
        };
        ServoGains {
            pos_p,
            pos_i,
            pos_d,
            vel_p,
            vel_i,
            profile_velocity: 0,
            profile_acceleration: 0,
        }
    }

    /// Published data of the model (ROBOTIS e-manual).
    pub fn spec(&self) -> MotorSpec {
        match self {
            ServoModel::Xm430W350 => MotorSpec {
                stall_torque: 4.1,
                no_load_speed: 46.0 * core::f32::consts::TAU / 60.0,
                supply_voltage: 12.0,
                current_control: true,
                model_number: units::MODEL_XM430_W350,
            },
            ServoModel::Xl430W250 => MotorSpec {
                stall_torque: 1.5,
                no_load_speed: 61.0 * core::f32::consts::TAU / 60.0,
                supply_voltage: 12.0,
                current_control: false,
                model_number: units::MODEL_XL430_W250,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motor_constants_match_locobot_driver() {
        // The LoCoBot driver converts torque to XM430 goal current as N·m × 149.795.
        let units_per_nm = 1.0 / ServoModel::Xm430W350.spec().kt() / units::AMP_PER_CURRENT_UNIT;
        assert!(
            (units_per_nm - 149.795).abs() / 149.795 < 0.01,
            "{units_per_nm}"
        );
    }
}
