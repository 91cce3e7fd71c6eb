//! Keys, what they do, and PyRobot's key map (`locobot_control/config/teleop.yaml` and its
//! `teleoperation.py`): keys, step sizes and base speeds as data.

/// A key as a shell reports it: a character (case kept), an arrow, Escape, or Ctrl-C.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Key {
    /// A printable character.
    Char(char),
    /// Arrow up.
    Up,
    /// Arrow down.
    Down,
    /// Arrow left.
    Left,
    /// Arrow right.
    Right,
    /// Escape.
    Esc,
    /// Ctrl-C (a key event in a raw terminal, not a signal).
    CtrlC,
}

impl std::fmt::Display for Key {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Key::Char(c) => write!(f, "{c}"),
            Key::Up => f.write_str("Up"),
            Key::Down => f.write_str("Down"),
            Key::Left => f.write_str("Left"),
            Key::Right => f.write_str("Right"),
            Key::Esc => f.write_str("Esc"),
            Key::CtrlC => f.write_str("Ctrl-C"),
        }
    }
}

/// What happened to a key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyKind {
    /// Pressed (or, from a terminal that reports no kinds, any key event).
    Press,
    /// An auto-repeat while held (only from a terminal that reports kinds).
    Repeat,
    /// Released (only from a terminal or device that reports releases).
    Release,
}

/// One key event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KeyEvent {
    /// Which key.
    pub key: Key,
    /// Press, repeat or release.
    pub kind: KeyKind,
}

impl KeyEvent {
    /// A press of `key`.
    pub fn press(key: Key) -> Self {
        KeyEvent {
            key,
            kind: KeyKind::Press,
        }
    }
    /// A release of `key`.
    pub fn release(key: Key) -> Self {
        KeyEvent {
            key,
            kind: KeyKind::Release,
        }
    }
    /// An auto-repeat of `key`.
    pub fn repeat(key: Key) -> Self {
        KeyEvent {
            key,
            kind: KeyKind::Repeat,
        }
    }
}

/// Open or close.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GripperAction {
    /// Open the gripper.
    Open,
    /// Close the gripper (until closed or holding an object).
    Close,
}

/// A discrete step: one per key event (and per auto-repeat).
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// Move the end effector by `[dx, dy, dz]` (m, the arm's base frame), keeping the
    /// gripper's orientation (pitch and roll on a 5-joint arm).
    Ee([f64; 3]),
    /// Turn one arm joint (by name) by `delta` rad.
    Joint {
        /// The joint's name in the robot description.
        joint: String,
        /// Step, rad.
        delta: f64,
    },
    /// Open or close the gripper.
    Gripper(GripperAction),
    /// Pan and tilt the camera head by `[dpan, dtilt]` rad.
    PanTilt([f64; 2]),
    /// The arm to its home pose.
    Reset,
}

/// What a key does.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// A step, once per key event.
    Step(Step),
    /// Drive the base at `v` m/s forward and `w` rad/s (counter-clockwise) while the key is
    /// held; several held base keys add up.
    Base {
        /// Forward speed, m/s.
        v: f64,
        /// Yaw rate, rad/s.
        w: f64,
    },
    /// Stop the base, hold the arm, leave.
    Quit,
}

impl Action {
    /// A base velocity: held while its key is.
    pub fn is_held(&self) -> bool {
        matches!(self, Action::Base { .. })
    }
}

/// One key's binding and its help text.
#[derive(Debug, Clone, PartialEq)]
pub struct Binding {
    /// The key.
    pub key: Key,
    /// What it does.
    pub action: Action,
    /// A short description for help screens (e.g. "end effector +x").
    pub label: String,
}

/// Keys and what they do: data, so a shell can show it and a user replace it.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyMap {
    /// The bindings; the first binding of a key wins.
    pub bindings: Vec<Binding>,
}

/// PyRobot's steps (`teleop.yaml`): end effector ±0.01 m in x and y, +0.015 / −0.01 m in z.
pub const EE_STEP: f64 = 0.01;
/// PyRobot's upward end-effector step, m.
pub const EE_STEP_UP: f64 = 0.015;
/// PyRobot's downward end-effector step, m.
pub const EE_STEP_DOWN: f64 = 0.01;
/// PyRobot's wrist-pitch step (`DELTA_ANGLE_4`), rad.
pub const JOINT_4_STEP: f64 = 0.1;
/// PyRobot's wrist-roll step (`DELTA_ANGLE_5`), rad.
pub const JOINT_5_STEP: f64 = 0.25;
/// PyRobot's pan and tilt step (`DELTA_ANGLE_CAMERA`), rad.
pub const CAMERA_STEP: f64 = 0.08;
/// PyRobot's base forward speed while an arrow is held, m/s.
pub const BASE_SPEED: f64 = 0.05;
/// PyRobot's base turn rate while an arrow is held, rad/s.
pub const BASE_TURN: f64 = 0.5;

impl KeyMap {
    /// PyRobot's LoCoBot key map: `w`/`s` ±x, `a`/`d` ±y, `z`/`x` ±z (end effector);
    /// `h`/`j` ±joint 4, `k`/`l` ±joint 5; `n` open, `m` close; `u`/`i` ±pan, `o`/`p` ±tilt;
    /// arrows drive the base (held); `r` resets the arm; and, ours, `q`, Esc and Ctrl-C quit
    /// (PyRobot: Ctrl-C only). `wrist` names the two wrist joints (PyRobot's `joint_4` and
    /// `joint_5`).
    pub fn pyrobot(wrist: [&str; 2]) -> KeyMap {
        let b = |key, action, label: &str| Binding {
            key,
            action,
            label: label.to_string(),
        };
        let joint = |name: &str, delta| {
            Action::Step(Step::Joint {
                joint: name.to_string(),
                delta,
            })
        };
        let ee = |d| Action::Step(Step::Ee(d));
        let head = |d| Action::Step(Step::PanTilt(d));
        let grip = |g| Action::Step(Step::Gripper(g));
        use Key::*;
        let [j4, j5] = wrist;
        KeyMap {
            bindings: vec![
                b(Char('w'), ee([EE_STEP, 0.0, 0.0]), "end effector +x"),
                b(Char('s'), ee([-EE_STEP, 0.0, 0.0]), "end effector -x"),
                b(Char('a'), ee([0.0, EE_STEP, 0.0]), "end effector +y"),
                b(Char('d'), ee([0.0, -EE_STEP, 0.0]), "end effector -y"),
                b(Char('z'), ee([0.0, 0.0, EE_STEP_UP]), "end effector +z"),
                b(Char('x'), ee([0.0, 0.0, -EE_STEP_DOWN]), "end effector -z"),
                b(Char('h'), joint(j4, JOINT_4_STEP), &format!("{j4} +")),
                b(Char('j'), joint(j4, -JOINT_4_STEP), &format!("{j4} -")),
                b(Char('k'), joint(j5, JOINT_5_STEP), &format!("{j5} +")),
                b(Char('l'), joint(j5, -JOINT_5_STEP), &format!("{j5} -")),
                b(Char('n'), grip(GripperAction::Open), "gripper open"),
                b(Char('m'), grip(GripperAction::Close), "gripper close"),
                b(Char('u'), head([CAMERA_STEP, 0.0]), "pan +"),
                b(Char('i'), head([-CAMERA_STEP, 0.0]), "pan -"),
                b(Char('o'), head([0.0, CAMERA_STEP]), "tilt +"),
                b(Char('p'), head([0.0, -CAMERA_STEP]), "tilt -"),
                b(
                    Up,
                    Action::Base {
                        v: BASE_SPEED,
                        w: 0.0,
                    },
                    "base forward (held)",
                ),
                b(
                    Down,
                    Action::Base {
                        v: -BASE_SPEED,
                        w: 0.0,
                    },
                    "base backward (held)",
                ),
                b(
                    Left,
                    Action::Base {
                        v: 0.0,
                        w: BASE_TURN,
                    },
                    "base turn left (held)",
                ),
                b(
                    Right,
                    Action::Base {
                        v: 0.0,
                        w: -BASE_TURN,
                    },
                    "base turn right (held)",
                ),
                b(Char('r'), Action::Step(Step::Reset), "arm home"),
                b(Char('q'), Action::Quit, "quit"),
                b(Esc, Action::Quit, "quit"),
                b(CtrlC, Action::Quit, "quit"),
            ],
        }
    }

    /// What `key` does, if anything.
    pub fn action(&self, key: Key) -> Option<&Action> {
        self.bindings
            .iter()
            .find(|b| b.key == key)
            .map(|b| &b.action)
    }

    /// The map without the bindings whose action `keep` refuses (e.g. the base's keys on a
    /// robot without a base).
    pub fn retain(mut self, keep: impl Fn(&Action) -> bool) -> KeyMap {
        self.bindings.retain(|b| keep(&b.action));
        self
    }
}
