//! A gamepad for teleoperation (gilrs; feature `gamepad`): its buttons and sticks become the
//! key events of PyRobot's key map, so the core does not know which device spoke. Buttons and
//! sticks report releases: the left stick drives the base while it is pushed (a repeat every
//! turn renews the hold), the right stick steps the camera head once per push.

use ferrobot_teleop::{Key, KeyEvent};
use gilrs::{Axis, Button, EventType, Gilrs};

/// Buttons and the keys they stand for (a standard gamepad, gilrs' names): the D-pad moves the
/// end effector in x and y, the bumpers down and up; A closes and B opens the gripper; X and
/// Y turn joint 4, the triggers joint 5; Select homes the arm, Start quits.
pub const BUTTONS: [(Button, Key); 14] = [
    (Button::DPadUp, Key::Char('w')),
    (Button::DPadDown, Key::Char('s')),
    (Button::DPadLeft, Key::Char('a')),
    (Button::DPadRight, Key::Char('d')),
    (Button::RightTrigger, Key::Char('z')),
    (Button::LeftTrigger, Key::Char('x')),
    (Button::South, Key::Char('m')),
    (Button::East, Key::Char('n')),
    (Button::West, Key::Char('h')),
    (Button::North, Key::Char('j')),
    (Button::RightTrigger2, Key::Char('k')),
    (Button::LeftTrigger2, Key::Char('l')),
    (Button::Select, Key::Char('r')),
    (Button::Start, Key::Char('q')),
];

/// A stick direction counts as pushed beyond this deflection (of 1) ...
pub const PUSH: f32 = 0.5;
/// ... and as let go below this one (hysteresis against a wobbling thumb).
pub const LET_GO: f32 = 0.3;

/// Stick axes, the key for each direction (negative, positive), and whether it is held (base)
/// or stepped once per push (head). gilrs' y axes point up.
const STICKS: [(Axis, [Key; 2], bool); 4] = [
    (Axis::LeftStickY, [Key::Down, Key::Up], true),
    (Axis::LeftStickX, [Key::Right, Key::Left], true),
    (Axis::RightStickX, [Key::Char('i'), Key::Char('u')], false),
    (Axis::RightStickY, [Key::Char('p'), Key::Char('o')], false),
];

/// The direction a stick axis at `value` points now: `Some(0)` negative, `Some(1)` positive,
/// given the one it pointed before (hysteresis between [`LET_GO`] and [`PUSH`]).
pub fn stick_direction(before: Option<usize>, value: f32) -> Option<usize> {
    let side = usize::from(value > 0.0);
    match before {
        Some(b) if b == side && value.abs() >= LET_GO => Some(b),
        _ if value.abs() >= PUSH => Some(side),
        _ => None,
    }
}

/// The gamepads, read through gilrs.
pub struct Gamepad {
    gilrs: Gilrs,
    /// Each stick axis's direction now.
    sticks: [Option<usize>; 4],
}

impl Gamepad {
    /// Gamepad input, or `None` (with the reason) when the system offers none.
    pub fn open() -> Result<Gamepad, String> {
        let gilrs = Gilrs::new().map_err(|e| e.to_string())?;
        Ok(Gamepad {
            gilrs,
            sticks: [None; 4],
        })
    }

    /// How many gamepads are connected.
    pub fn connected(&self) -> usize {
        self.gilrs.gamepads().count()
    }

    /// The key events since the last call, and a repeat of each held stick key.
    pub fn events(&mut self) -> Vec<KeyEvent> {
        let mut out = Vec::new();
        while let Some(e) = self.gilrs.next_event() {
            match e.event {
                EventType::ButtonPressed(b, _) => out.extend(key_of(b).map(KeyEvent::press)),
                EventType::ButtonReleased(b, _) => out.extend(key_of(b).map(KeyEvent::release)),
                EventType::AxisChanged(axis, value, _) => {
                    if let Some(k) = STICKS.iter().position(|s| s.0 == axis) {
                        let (_, keys, _) = STICKS[k];
                        let now = stick_direction(self.sticks[k], value);
                        if now != self.sticks[k] {
                            out.extend(self.sticks[k].map(|d| KeyEvent::release(keys[d])));
                            out.extend(now.map(|d| KeyEvent::press(keys[d])));
                            self.sticks[k] = now;
                        }
                    }
                }
                _ => {}
            }
        }
        for (k, (_, keys, held)) in STICKS.iter().enumerate() {
            if let (true, Some(d)) = (held, self.sticks[k]) {
                out.push(KeyEvent::repeat(keys[d]));
            }
        }
        out
    }
}

/// The key a button stands for.
fn key_of(b: Button) -> Option<Key> {
    BUTTONS
        .iter()
        .find(|(button, _)| *button == b)
        .map(|(_, k)| *k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stick_pushes_past_half_and_lets_go_below_three_tenths() {
        assert_eq!(stick_direction(None, 0.4), None);
        assert_eq!(stick_direction(None, 0.6), Some(1));
        assert_eq!(stick_direction(Some(1), 0.35), Some(1));
        assert_eq!(stick_direction(Some(1), 0.25), None);
        assert_eq!(stick_direction(None, -0.7), Some(0));
        // Straight across: the other side at once.
        assert_eq!(stick_direction(Some(0), 0.9), Some(1));
    }

    #[test]
    fn every_button_stands_for_a_key_of_pyrobots_map() {
        let map = ferrobot_teleop::KeyMap::pyrobot(["joint_4", "joint_5"]);
        for (_, key) in BUTTONS {
            assert!(map.action(key).is_some(), "{key}");
        }
        for (_, keys, _) in STICKS {
            for key in keys {
                assert!(map.action(key).is_some(), "{key}");
            }
        }
    }
}
