//! The gripper state machine, as the LoCoBot driver runs it: closing drives PWM −500 with a
//! short −700 kick when the load first exceeds 500; below 1800 ticks the gripper is fully
//! closed, a load that persists means an object is held; opening is position mode to 2800.

use ferrobot_protocol::{GripperCommand, GripperState};

use crate::bus::Present;
use crate::config::GripperConfig;
use crate::time::Instant;

/// What the gripper servo should do this tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GripperDrive {
    /// Leave the servo in its joint mode (no command yet).
    Idle,
    /// Position mode, goal in ticks.
    Position(i32),
    /// PWM mode, goal PWM.
    Pwm(i16),
}

/// Gripper state machine.
#[derive(Debug, Clone)]
pub struct Gripper {
    cfg: GripperConfig,
    /// Current state.
    pub state: GripperState,
    started: Instant,
    kick_until: Instant,
    load_since: Option<Instant>,
    kicked: bool,
}

impl Gripper {
    /// A gripper in the unknown state.
    pub fn new(cfg: GripperConfig) -> Self {
        Self {
            cfg,
            state: GripperState::Unknown,
            started: Instant::ZERO,
            kick_until: Instant::ZERO,
            load_since: None,
            kicked: false,
        }
    }

    /// Start a command.
    pub fn command(&mut self, now: Instant, cmd: GripperCommand) {
        self.started = now;
        self.kick_until = Instant::ZERO;
        self.load_since = None;
        self.kicked = false;
        self.state = match cmd {
            GripperCommand::Close => GripperState::Closing,
            _ => GripperState::Opening,
        };
    }

    /// Stop where it is (watchdog, emergency stop): a gripper opening, or closing on nothing
    /// yet, stops (its servo goes back to its joint's control, which holds it); one closing on
    /// an object it has felt keeps it, at the holding PWM. A closing gripper once kept closing
    /// at full PWM through a stop.
    pub fn halt(&mut self) {
        match self.state {
            GripperState::Opening => self.state = GripperState::Unknown,
            GripperState::Closing if self.load_since.is_some() => {
                self.state = GripperState::Holding;
            }
            GripperState::Closing => self.state = GripperState::Unknown,
            _ => {}
        }
    }

    /// One tick with the servo's present position and load.
    pub fn tick(&mut self, now: Instant, present: &Present) -> GripperDrive {
        let c = &self.cfg;
        let pos = present.position;
        let load = (present.current as i32).abs();
        match self.state {
            GripperState::Opening => {
                if pos.saturating_sub(c.open_tick).saturating_abs() <= c.open_tolerance {
                    self.state = GripperState::Open;
                }
                GripperDrive::Position(c.open_tick)
            }
            GripperState::Open => GripperDrive::Position(c.open_tick),
            GripperState::Closing => {
                if pos < c.closed_tick {
                    self.state = GripperState::Closed;
                    return GripperDrive::Pwm(c.hold_pwm);
                }
                let loaded = now - self.started >= c.grace_time && load > c.load_threshold as i32;
                if loaded {
                    if !self.kicked {
                        self.kicked = true;
                        self.kick_until = now + c.kick_time;
                    }
                    let since = *self.load_since.get_or_insert(now);
                    if now >= self.kick_until && now - since >= c.persist_time {
                        self.state = GripperState::Holding;
                        return GripperDrive::Pwm(c.hold_pwm);
                    }
                } else if now >= self.kick_until {
                    self.load_since = None;
                }
                GripperDrive::Pwm(if now < self.kick_until {
                    c.kick_pwm
                } else {
                    c.close_pwm
                })
            }
            GripperState::Holding => {
                if pos < c.closed_tick {
                    self.state = GripperState::Closed;
                }
                GripperDrive::Pwm(c.hold_pwm)
            }
            GripperState::Closed => GripperDrive::Pwm(c.hold_pwm),
            _ => GripperDrive::Idle,
        }
    }
}
